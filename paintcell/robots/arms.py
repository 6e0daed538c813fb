"""The arms paintcell ships, loaded by name (no rail: `paintcell.robots.catalog.load_robot` adds
those)."""

from __future__ import annotations

import numpy.typing as npt

from paintcell.robots.errors import RobotError
from paintcell.robots.opw import IRB4600_60_205, IRB5500_CLASS
from paintcell.robots.robot import (
    ABB_PAINT_A_MAX,
    ABB_PAINT_MJCF,
    ABB_PAINT_V_MAX,
    IRB5500_A_MAX,
    IRB5500_MJCF,
    IRB5500_V_MAX,
    Robot,
    with_tcp_offset,
)
from paintcell.robots.ur10 import load_ur10

__all__ = ["ARM_NAMES", "load_arm"]

#: Arms with a base of their own (each may also stand on a rail: `paintcell.robots.catalog`).
ARM_NAMES = ("abb_paint", "irb5500", "ur10")


def load_arm(name: str, T_world_base: npt.ArrayLike | None = None,
             tcp_offset: npt.ArrayLike | None = None) -> Robot:
    """Load an arm ("abb_paint", "irb5500", "ur10") placed at `T_world_base` (4,4) (default:
    identity).

    tcp_offset: optional (4,4) T_flange_tcp [m] replacing the MJCF's tool offset (the TCP site
    moves; a generated MJCF in the temp dir becomes `mjcf_path`).
    """
    if name == "abb_paint":
        path = ABB_PAINT_MJCF
        if tcp_offset is not None:
            path = with_tcp_offset(path, "tcp", tcp_offset, "abb_paint")
        return Robot.from_mjcf("abb_paint", path, v_max=ABB_PAINT_V_MAX, a_max=ABB_PAINT_A_MAX,
                               T_world_base=T_world_base, opw=IRB4600_60_205)
    if name == "irb5500":
        path = IRB5500_MJCF
        if tcp_offset is not None:
            path = with_tcp_offset(path, "tcp", tcp_offset, "irb5500")
        return Robot.from_mjcf("irb5500", path, v_max=IRB5500_V_MAX, a_max=IRB5500_A_MAX,
                               T_world_base=T_world_base, opw=IRB5500_CLASS)
    if name == "ur10":
        return load_ur10(T_world_base=T_world_base, tcp_offset=tcp_offset)
    raise RobotError(f"unknown arm {name!r}; choose one of {ARM_NAMES}")
