"""Robot models, kinematics, IK along paint paths and reachability (never imports sim/)."""

from paintcell.robots.catalog import ROBOT_NAMES, load_robot
from paintcell.robots.errors import RobotError, UnreachableError
from paintcell.robots.robot import Robot, bell_tool_offset

__all__ = ["ROBOT_NAMES", "Robot", "RobotError", "UnreachableError", "bell_tool_offset",
           "load_robot"]
