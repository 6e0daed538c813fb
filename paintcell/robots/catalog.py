"""Every robot paintcell ships, by name: an arm (`paintcell.robots.arms`) or an arm on a rail
(`paintcell.robots.rail`).
"""

from __future__ import annotations

import numpy.typing as npt

from paintcell.robots.arms import load_arm
from paintcell.robots.errors import RobotError
from paintcell.robots.rail import load_rail_robot
from paintcell.robots.robot import Robot

__all__ = ["ROBOT_NAMES", "load_robot"]

# "<arm>_rail": the arm on a default linear rail (`paintcell.robots.rail`; T_world_base is the rail
# frame).
ROBOT_NAMES = ("abb_paint", "irb5500", "ur10", "abb_paint_rail", "irb5500_rail")


def load_robot(name: str, T_world_base: npt.ArrayLike | None = None,
               tcp_offset: npt.ArrayLike | None = None) -> Robot:
    """Load a robot (one of `ROBOT_NAMES`) placed at `T_world_base` (4,4) (default: identity);
    for "<arm>_rail" names `T_world_base` is the rail frame.

    tcp_offset: optional (4,4) T_flange_tcp [m] replacing the MJCF's tool offset (the TCP site
    moves; a generated MJCF in the private robot-model cache becomes `mjcf_path`).
    """
    if name.endswith("_rail") and name[:-5] in ("abb_paint", "irb5500"):
        return load_rail_robot(name[:-5], T_world_rail=T_world_base, tcp_offset=tcp_offset)
    if name in ("abb_paint", "irb5500", "ur10"):
        return load_arm(name, T_world_base=T_world_base, tcp_offset=tcp_offset)
    raise RobotError(f"unknown robot {name!r}; choose one of {ROBOT_NAMES}")
