"""/diagnostics keeps coming while the planner plans (the executor is single-threaded)."""

from __future__ import annotations

import time

from std_msgs.msg import Float64

from flexmotion_ros.nodes import messages, planner_moves, planner_node

from .conftest import wait_for


def test_status_is_published_during_a_long_plan(ros, monkeypatch):
    real = planner_moves.plan_move

    def slow_plan_move(*args, **kwargs):  # a plan that takes 2 s, like a limited move at 1 kHz
        time.sleep(2.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(planner_moves, "plan_move", slow_plan_move)
    planner = ros.planner(diagnostics_period_s=0.1, **{"state.source": "assumed"})  # no plant: the assumed state
    ros.connected(planner, subscribers=1)
    wait_for(lambda: ros.probe.planner_status() is not None, 5.0, "a first status")
    ros.probe.goal_pub.publish(Float64(data=0.5))

    def planning_statuses() -> int:
        with ros.probe.lock:
            diags = list(ros.probe.diagnostics)
        sts = [
            messages.diagnostic_values(d, planner_node.DIAGNOSTIC_NAME, planner.get_fully_qualified_name())
            for d in diags
        ]
        return sum(1 for st in sts if st is not None and st[2].get("planning") == "~/goal")

    # every 0.1 s during the 2 s plan: the old executor timer sent none (it waited for the plan)
    wait_for(lambda: planning_statuses() >= 5, 4.0, "periodic statuses saying it plans")
    # then moving (or done), not planning any more (a periodic status may catch "moving" a moment
    # before the planning mark is cleared: the status sent at the end of the request has it cleared)
    wait_for(lambda: (ros.probe.planner_status() or (0, "", {}))[1] in ("moving", "idle"), 5.0, "moving after the plan")
    wait_for(lambda: ros.probe.planner_status()[2]["planning"] == "", 2.0, "the planning mark cleared")


class _FakeNode:
    """What StatusReporter asks of its node before it starts: a publisher."""

    def create_publisher(self, *args, **kwargs):
        return None


def test_first_command_sent_before_the_move_is_reported_is_kept():
    # the stream (its own process) may send the first command -- and the follower report it -- before the
    # planning thread reports the installed move: the delay was lost (bench/ros_streaming.py KeyError)
    from flexmotion_ros.nodes.planner_status import StatusReporter

    status = StatusReporter(_FakeNode(), 1.0, 0.0, dict)
    first, second = object(), object()
    status.first_command(0.004, move=first)
    status.moving(0.5, {"samples": 10}, move=first)
    assert status.status()[2]["last_plan.goal_to_first_command_s"] == 0.004
    # the other order too; an older move's delay never labels a newer one
    status.moving(0.0, {"samples": 11}, move=second)
    assert "last_plan.goal_to_first_command_s" not in status.status()[2]
    status.first_command(0.005, move=second)
    assert status.status()[2]["last_plan.goal_to_first_command_s"] == 0.005
