"""The stream process's own Fast DDS settings, chosen in its environment before its ``rclpy.init`` (issue 14).

Under ``stream_priority`` the publisher is asynchronous; the transports stay
Fast DDS's own choice unless the benchmarks' switch names them (UDP only was
measured against shared memory in the 1 kHz storm: no fewer blocked publishes).
"""

from __future__ import annotations

from flexmotion_ros.nodes.stream_child import PUBLICATION_MODE_ENV, TRANSPORTS_ENV, stream_environment


def test_a_prioritised_stream_publishes_asynchronously_over_fast_dds_own_transports():
    assert stream_environment(50, {}) == {"RMW_FASTRTPS_PUBLICATION_MODE": "ASYNCHRONOUS"}


def test_without_priority_fast_dds_keeps_its_defaults_and_a_users_mode_is_left_alone():
    assert stream_environment(0, {}) == {}
    assert stream_environment(50, {"RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS"}) == {}


def test_the_benchmarks_switches_choose_the_mode_and_the_transports():
    env = {TRANSPORTS_ENV: "UDPv4", PUBLICATION_MODE_ENV: "SYNCHRONOUS"}
    assert stream_environment(50, env) == {
        "RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS",
        "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
    }
    assert stream_environment(0, {TRANSPORTS_ENV: "UDPv4"}) == {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
