"""The arms paintcell ships, loaded by name (no rail: `paintcell.robots.catalog.load_robot` adds
those)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
import numpy.typing as npt

from paintcell.robots.errors import RobotError
from paintcell.robots.opw import (
    IRB4600_60_205,
    IRB5500_CLASS,
    OPWParameters,
    configuration_signs,
)
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
from paintcell.robots.ur_kinematics import ur_configuration_signs

__all__ = ["ARM_NAMES", "arm_configuration_signs", "arm_opw", "load_arm"]

#: The ABB-style arms built from a shipped MJCF: name → (MJCF, joint speed limits [rad/s],
#: joint acceleration limits [rad/s²], closed-form IK parameters).
_MJCF_ARMS = {
    "abb_paint": (ABB_PAINT_MJCF, ABB_PAINT_V_MAX, ABB_PAINT_A_MAX, IRB4600_60_205),
    "irb5500": (IRB5500_MJCF, IRB5500_V_MAX, IRB5500_A_MAX, IRB5500_CLASS),
}
#: Arms with a base of their own (each may also stand on a rail: `paintcell.robots.catalog`).
ARM_NAMES = (*_MJCF_ARMS, "ur10")


def arm_opw(name: str) -> OPWParameters | None:
    """Closed-form (OPW) parameters of the arm of robot `name` ("<arm>" or "<arm>_rail"); None
    for an arm without them (the UR10) or an unknown name."""
    arm = name[:-5] if name.endswith("_rail") else name
    return _MJCF_ARMS[arm][3] if arm in _MJCF_ARMS else None


def arm_configuration_signs(name: str) -> Callable[[np.ndarray], np.ndarray] | None:
    """The configuration-sign function of the arm of robot `name` ("<arm>" or "<arm>_rail"):
    Q (K, 6) [rad] -> (K, 3) shoulder, elbow, wrist signs (`paintcell.robots.opw.
    configuration_signs` for the ortho-parallel ABB arms, `paintcell.robots.ur_kinematics.
    ur_configuration_signs` for the UR10); None for an unknown name."""
    opw = arm_opw(name)
    if opw is not None:
        return partial(configuration_signs, opw)
    return ur_configuration_signs if name == "ur10" else None


def load_arm(name: str, T_world_base: npt.ArrayLike | None = None,
             tcp_offset: npt.ArrayLike | None = None) -> Robot:
    """Load an arm ("abb_paint", "irb5500", "ur10") placed at `T_world_base` (4,4) (default:
    identity).

    tcp_offset: optional (4,4) T_flange_tcp [m] replacing the MJCF's tool offset (the TCP site
    moves; a generated MJCF in the private robot-model cache becomes `mjcf_path`).
    """
    if name in _MJCF_ARMS:
        path, v_max, a_max, opw = _MJCF_ARMS[name]
        if tcp_offset is not None:
            path = with_tcp_offset(path, "tcp", tcp_offset, name)
        return Robot.from_mjcf(name, path, v_max=v_max, a_max=a_max, T_world_base=T_world_base,
                               opw=opw)
    if name == "ur10":
        return load_ur10(T_world_base=T_world_base, tcp_offset=tcp_offset)
    raise RobotError(f"unknown arm {name!r}; choose one of {ARM_NAMES}")
