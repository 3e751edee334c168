"""/diagnostics keeps coming while the planner plans (the executor is single-threaded)."""

from __future__ import annotations

import time

from std_msgs.msg import Float64

from flexmotion_ros.nodes import planner_node

from .conftest import wait_for


def test_status_is_published_during_a_long_plan(ros, monkeypatch):
    real = planner_node.plan_move

    def slow_plan_move(*args, **kwargs):  # a plan that takes 1.5 s, like a limited move at 1 kHz
        time.sleep(1.5)
        return real(*args, **kwargs)

    monkeypatch.setattr(planner_node, "plan_move", slow_plan_move)
    planner = ros.planner(diagnostics_period_s=0.1)
    ros.connected(planner, subscribers=1)
    wait_for(lambda: ros.probe.planner_status() is not None, 5.0, "a first status")
    ros.probe.goal_pub.publish(Float64(data=0.5))
    wait_for(lambda: (ros.probe.planner_status() or (0, "", {}))[2].get("planning") == "~/goal", 1.2, "a status saying it plans")
    t_seen = time.monotonic()
    n0 = len(ros.probe.diagnostics)
    time.sleep(0.8)  # still planning: the periodic status keeps coming
    assert len(ros.probe.diagnostics) - n0 >= 4, len(ros.probe.diagnostics) - n0
    assert time.monotonic() - t_seen < 1.5
    wait_for(lambda: (ros.probe.planner_status() or (0, "", {}))[1] == "moving", 5.0, "moving after the plan")
    assert ros.probe.planner_status()[2]["planning"] == ""
