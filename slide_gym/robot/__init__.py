"""The Barrett WAM arm with a Yale T42 hand: model data and the PyBullet robot."""

from slide_gym.robot.model import (
    ARM_JOINTS,
    ARM_LOWER,
    ARM_TORQUE_LIMITS,
    ARM_UPPER,
    ARM_VELOCITY_LIMITS,
    BASE_TO_SHOULDER,
    DH,
    FINGER_JOINTS,
    FINGER_LOWER,
    FINGER_UPPER,
    READY_ARM_Q,
    ArmGains,
    HandParams,
    flange_pose_dh,
)
from slide_gym.robot.wam_t42 import WamT42

__all__ = [
    "ARM_JOINTS",
    "ARM_LOWER",
    "ARM_TORQUE_LIMITS",
    "ARM_UPPER",
    "ARM_VELOCITY_LIMITS",
    "BASE_TO_SHOULDER",
    "DH",
    "FINGER_JOINTS",
    "FINGER_LOWER",
    "FINGER_UPPER",
    "READY_ARM_Q",
    "ArmGains",
    "HandParams",
    "WamT42",
    "flange_pose_dh",
]
