"""Command interfaces of the actuated joint: effort, velocity, position (references and servos)."""

from .command import CommandInterface, check_acceleration_model, command_interface, velocity_limit_option
from .reference import JointReference, hold_setpoint, joint_reference, reference_for, setpoints
from .servo import Servo, ServoRun, servo_matrices, simulate_servo

__all__ = [
    "CommandInterface",
    "JointReference",
    "Servo",
    "ServoRun",
    "check_acceleration_model",
    "command_interface",
    "hold_setpoint",
    "joint_reference",
    "reference_for",
    "servo_matrices",
    "setpoints",
    "simulate_servo",
    "velocity_limit_option",
]
