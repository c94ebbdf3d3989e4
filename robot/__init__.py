"""The adapter contract every robot speaks: data types, frames, units and limits.

Import from here: ``from homing.robot import Pose2, Scan, RobotAdapter``.
"""

from homing.robot.adapter import Clock, RobotAdapter
from homing.robot.turtlebot import RobotLimits
from homing.robot.types import (
    IR,
    BaseSwitches,
    BatteryState,
    Bumpers,
    CameraImage,
    CameraInfo,
    ChargingSource,
    ChargingState,
    DockIR,
    Observation,
    Odometry,
    Pose2,
    Scan,
    Twist2,
)

__all__ = [
    "IR",
    "BaseSwitches",
    "BatteryState",
    "Bumpers",
    "CameraImage",
    "CameraInfo",
    "ChargingSource",
    "ChargingState",
    "Clock",
    "DockIR",
    "Observation",
    "Odometry",
    "Pose2",
    "RobotAdapter",
    "RobotLimits",
    "Scan",
    "Twist2",
]
