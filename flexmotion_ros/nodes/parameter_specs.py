"""Parameter declarations both nodes make: the model, the command interface, the trajectory topic, the measurements.

One parameter file serves the planner and the plant, so these names are
declared by both with the same descriptors (:mod:`.planner_parameters`,
:mod:`.plant_parameters`).
"""

from __future__ import annotations

from rclpy.parameter import Parameter

from ..core.config import DEFAULTS
from .parameters import Spec


def model_specs(read_only: bool) -> list[Spec]:
    tail = " Fixed at start-up (the simulated machine)." if read_only else " A change applies to the next goal."
    return [
        Spec(
            "model.b0",
            DEFAULTS["model.b0"],
            "rigid-body input gain b0 (acceleration per unit input, e.g. 1/kg); non-zero. Several inputs: a double "
            "array, k x m row-major." + tail,
            read_only,
            dynamic=True,
        ),
        Spec(
            "model.c",
            DEFAULTS["model.c"],
            "rigid-body viscous term c (1/s), <= 0. Several inputs: one per rigid body." + tail,
            read_only,
            fp_range=(-1e12, 0.0),
            dynamic=True,
        ),
        Spec(
            "model.omega",
            Parameter.Type.DOUBLE_ARRAY,
            "undamped modal frequencies omega_i (rad/s), each > 0, no two equal; empty: rigid body only." + tail,
            read_only,
        ),
        Spec(
            "model.zeta",
            Parameter.Type.DOUBLE_ARRAY,
            "modal damping ratios zeta_i, each in [0, 1), one per mode." + tail,
            read_only,
        ),
        Spec(
            "model.b",
            Parameter.Type.DOUBLE_ARRAY,
            "modal input gains b_i, each non-zero, one per mode. Several inputs: N x m, row-major." + tail,
            read_only,
        ),
        *_multi_model_specs(read_only, tail),
    ]


def _multi_model_specs(read_only: bool, tail: str) -> list[Spec]:
    """The multi-input model's names (issue 12): set ``model.inputs`` and the model has several inputs."""
    return [
        Spec(
            "model.inputs",
            Parameter.Type.STRING_ARRAY,
            "names of the m actuated joints (inputs); set: a multi-input model (b0, b, u_max per input); "
            "empty: one input." + tail,
            read_only,
        ),
        Spec(
            "model.rigid_bodies",
            Parameter.Type.STRING_ARRAY,
            "multi-input: names of the k rigid-body coordinates (default [rigid_body]); the measured and simulated "
            "joint_states name them." + tail,
            read_only,
        ),
        Spec(
            "model.mode_names",
            Parameter.Type.STRING_ARRAY,
            "multi-input: names of the N modes (default mode_1 ... mode_N); the joint_states name them." + tail,
            read_only,
        ),
    ]


def command_interface_spec() -> Spec:
    """``command_interface``, declared by both nodes (one file serves the planner and the plant)."""
    return Spec(
        "command_interface",
        "effort",
        "what the actuated joint is commanded in: 'effort' (the force, u_max in N), 'velocity' or 'position' "
        "(a servo tracks the reference the planner sends, integrated exactly from the plan; the model's input "
        "is then the joint's acceleration, u_max in m/s^2, model.c = 0.0: build it with "
        "'flexmotion model crane --input acceleration'). Fixed at start-up.",
        read_only=True,
    )


def trajectory_topic_spec() -> Spec:
    """``trajectory.topic``, declared by both nodes."""
    return Spec(
        "trajectory.topic",
        "joint_trajectory",
        "trajectory_msgs/JointTrajectory topic: the planner publishes on it with output: trajectory (e.g. "
        "/<controller>/joint_trajectory of a joint_trajectory_controller), the plant reads it with plant.input: "
        "trajectory. Fixed at start-up.",
        read_only=True,
    )


def measurement_specs() -> list[Spec]:
    """``measurement.*``: the machine's measured channels (:mod:`flexmotion_ros.core.model.measurement`)."""
    tail = " Fixed at start-up."
    return [
        Spec(
            "measurement.names",
            Parameter.Type.STRING_ARRAY,
            "physical coordinate names of the channels on 'measurements' (sensor_msgs/JointState), unique; empty: "
            "the rigid-body position only." + tail,
            read_only=True,
        ),
        Spec(
            "measurement.map",
            Parameter.Type.DOUBLE_ARRAY,
            "row-major len(measurement.names) x (1 + modes): y = map @ [p, q_1, ..., q_N] (velocity and "
            "acceleration channels: the same row on the derivatives)." + tail,
            read_only=True,
        ),
        Spec(
            "measurement.kinds",
            Parameter.Type.STRING_ARRAY,
            "one per name: position (m), velocity (m/s) or acceleration (m/s^2, feeds the command through); "
            "empty: all position." + tail,
            read_only=True,
        ),
    ]
