"""Command interfaces of the actuated joint: effort, velocity, position (references and servos)."""

from .command import CommandInterface, check_acceleration_model, command_interface, velocity_limit_option
from .reference import JointReference, hold_setpoint, joint_reference, reference_for, setpoints
from .servo import (
    Servo,
    ServoRun,
    ServoState,
    servo_advance,
    servo_matrices,
    servo_setpoint,
    servo_start,
    simulate_servo,
)

__all__ = [
    "CommandInterface",
    "JointReference",
    "Servo",
    "ServoRun",
    "ServoState",
    "check_acceleration_model",
    "command_interface",
    "hold_setpoint",
    "joint_reference",
    "reference_for",
    "servo_advance",
    "servo_matrices",
    "servo_setpoint",
    "servo_start",
    "setpoints",
    "simulate_servo",
    "velocity_limit_option",
]
