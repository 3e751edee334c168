"""The stream process's Fast DDS settings: no lock shared with a reader's process in its write path (issue 14).

With the shared-memory transport, Fast DDS pushes each sample into every
reader's port under a mutex in memory shared with the reader's process; a
preempted reader of normal priority then held up the 1 kHz stream's writer
(and with it the next ``publish``) for a time slice.  Under
``stream_priority`` the stream process's participant sends over UDP only.
"""

from __future__ import annotations

import pytest

from flexmotion_ros.nodes.stream_child import (
    PUBLICATION_MODE_ENV,
    TRANSPORTS_ENV,
    USER_TRANSPORT_ENV,
    builtin_transports,
    stream_environment,
)


def test_a_prioritised_stream_sends_over_udp_only_and_asynchronously():
    assert stream_environment(50, {}) == {
        "RMW_FASTRTPS_PUBLICATION_MODE": "ASYNCHRONOUS",
        "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
    }


def test_without_priority_fast_dds_keeps_its_defaults():
    assert stream_environment(0, {}) == {}


@pytest.mark.parametrize("name", USER_TRANSPORT_ENV)
def test_a_users_transport_configuration_is_left_alone(name):
    assert builtin_transports(50, {name: "/some/profile.xml"}) is None
    assert "FASTDDS_BUILTIN_TRANSPORTS" not in stream_environment(50, {name: "x"})


def test_the_benchmarks_switches_choose_otherwise():
    env = {TRANSPORTS_ENV: "DEFAULT", PUBLICATION_MODE_ENV: "SYNCHRONOUS"}
    assert stream_environment(50, env) == {
        "RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS",
        "FASTDDS_BUILTIN_TRANSPORTS": "DEFAULT",
    }
    assert builtin_transports(0, {TRANSPORTS_ENV: "UDPv4"}) == "UDPv4"
