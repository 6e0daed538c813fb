"""Robot models, kinematics, IK along paint paths and reachability (never imports sim/)."""

from robots.errors import RobotError, UnreachableError
from robots.robot import ROBOT_NAMES, Robot, bell_tool_offset, load_robot

__all__ = ["ROBOT_NAMES", "Robot", "RobotError", "UnreachableError", "bell_tool_offset",
           "load_robot"]
