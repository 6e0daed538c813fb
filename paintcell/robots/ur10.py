"""UR10 from example-robot-data, with a bell atomizer, through the same `Robot` interface.

example-robot-data 6.0 installs data only: `<prefix>/share/example-robot-data/robots/`. Its URDF
uses `package://` mesh paths and `.dae` visuals MuJoCo cannot read; MuJoCo's URDF importer is run
with `discardvisual` and the STL collision meshes (found through `meshdir`, `strippath`), then the
model is completed with MjSpec: the ROS helper frames (ee_link, tool0, base) are replaced by one
`flange` body holding the bell (mass, geoms, `flange_site`, `tcp`), joint armature and damping,
torque motors and a `home` keyframe. The generated MJCF (in the private robot-model cache,
`paintcell.robots.robot.cache_dir`) is what MuJoCo and Pinocchio both load. The UR10 is not
ortho-parallel: IK is DLS only.
"""

from __future__ import annotations

import os
import sys
import sysconfig
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.robots.errors import RobotError
from paintcell.robots.robot import Robot, bell_tool_offset, write_generated_mjcf

ERD_ENV = "EXAMPLE_ROBOT_DATA_DIR"
# URDF <limit velocity> of the UR10 [rad/s] (UR datasheet: 120, 120, 180, 180, 180, 180 °/s).
UR10_V_MAX = np.array([2.16, 2.16, 3.15, 3.2, 3.2, 3.2])
# Estimate: UR's default joint acceleration is 80 °/s² in the teach pendant, max ~ 4x that.
UR10_A_MAX = np.array([4.0, 4.0, 6.0, 8.0, 8.0, 8.0])
# Estimates for a harmonic drive (ratio 101) with a ~1e-4 kg·m² rotor: armature ≈ 1 kg·m² on the
# big joints, 0.1 on the wrist; damping ≈ 5 % of the torque limit per rad/s.
UR10_ARMATURE = np.array([1.0, 1.0, 0.5, 0.1, 0.1, 0.1])
UR10_DAMPING = np.array([15.0, 15.0, 7.5, 2.5, 2.5, 2.5])
# Home: elbow up, wrist bent (|sin q5| = 1), away from every singularity and limit.
UR10_HOME = np.array([0.0, -1.9, 1.9, -1.2, -1.5708, 0.0])
# Lighter bell for a 10 kg-payload arm [kg].
UR10_BELL_MASS = 3.0


def example_robot_data_dir() -> Path:
    """`share/example-robot-data/robots` of the installed example-robot-data package.

    Looks at $EXAMPLE_ROBOT_DATA_DIR, the cmeel prefix in site-packages, then sys.prefix.
    """
    candidates = []
    if os.environ.get(ERD_ENV):
        candidates.append(Path(os.environ[ERD_ENV]))
    for key in ("purelib", "platlib"):
        candidates.append(Path(sysconfig.get_paths()[key]) / "cmeel.prefix" / "share"
                          / "example-robot-data" / "robots")
    candidates.append(Path(sys.prefix) / "share" / "example-robot-data" / "robots")
    for c in candidates:
        if (c / "ur_description").is_dir():
            return c
    raise RobotError(f"example-robot-data not found (looked in {[str(c) for c in candidates]}); "
                     f"pip install example-robot-data or set ${ERD_ENV}")


def ur10_mjcf(tcp_offset: npt.ArrayLike | None = None) -> Path:
    """Generate (once, cached by content) the UR10 + bell MJCF and return its path."""
    root = example_robot_data_dir() / "ur_description"
    urdf = (root / "urdf" / "ur10_robot.urdf").read_text()
    mesh_dir = root / "meshes" / "ur10" / "collision"
    head = urdf.index(">", urdf.index("<robot")) + 1
    urdf = (urdf[:head] + f'<mujoco><compiler meshdir="{mesh_dir}/" discardvisual="true" '
            f'strippath="true" fusestatic="false"/></mujoco>' + urdf[head:])
    spec = mujoco.MjSpec.from_string(urdf)
    for name in ("ee_link", "tool0", "base"):
        spec.delete(spec.body(name))
    spec.compiler.degree = False
    spec.compiler.discardvisual = False  # (it would also drop the visual copies added below)
    spec.option.timestep = 0.001
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    joints = [j for j in spec.joints]
    for j, arm, damp in zip(joints, UR10_ARMATURE, UR10_DAMPING, strict=True):
        j.armature = float(arm)
        j.damping = [float(damp), 0.0, 0.0]  # MuJoCo 4.0: damping is a 3-vector
        tau = float(j.actfrcrange[1])
        act = spec.add_actuator(name=f"motor_{j.name}", target=j.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.ctrlrange = [-tau, tau]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.gainprm[0] = 1.0
    # The URDF collision meshes serve twice: collision (group 3) and a massless visual copy
    # (group 2, no contact), like the menagerie's separate visual/collision classes.
    for g in list(spec.geoms):
        g.group = 3
        body = g.parent
        v = body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=g.meshname, pos=g.pos,
                          quat=g.quat, group=2, contype=0, conaffinity=0, density=0.0,
                          rgba=[0.7, 0.72, 0.75, 1.0])
        v.name = ""
    # ROS tool0: 0.0922 m along wrist_3 y, z out of the flange (Rx(-pi/2)).
    flange = spec.body("wrist_3_link").add_body(name="flange", pos=[0.0, 0.0922, 0.0],
                                                quat=[np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0])
    flange.mass = UR10_BELL_MASS
    flange.ipos = [0.0, 0.0, 0.12]
    flange.inertia = [0.02, 0.02, 0.008]
    flange.explicitinertial = True
    T = bell_tool_offset() if tcp_offset is None else np.asarray(tcp_offset, float)
    flange.add_site(name="flange_site", size=[0.01, 0.01, 0.01])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).reshape(9))
    flange.add_site(name="tcp", pos=T[:3, 3], quat=quat, size=[0.012, 0.012, 0.012])
    flange.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.05, 0, 0],
                    fromto=[0, 0, 0.02, 0, 0, 0.16], group=3)
    flange.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.04, 0, 0],
                    fromto=[0, 0, 0.16, *(T[:3, 3] * [1, 1, 1] - 0.02 * T[:3, 2])], group=3)
    spec.add_key(name="home", qpos=UR10_HOME, ctrl=np.zeros(6))
    spec.compile()
    return write_generated_mjcf(spec.to_xml(), "ur10")


def load_ur10(T_world_base: npt.ArrayLike | None = None,
              tcp_offset: npt.ArrayLike | None = None) -> Robot:
    """The UR10 with a bell atomizer (default tool offset: `bell_tool_offset()`)."""
    from paintcell.robots.ur_ik import ur_closed_form

    robot = Robot.from_mjcf("ur10", ur10_mjcf(tcp_offset), v_max=UR10_V_MAX, a_max=UR10_A_MAX,
                            T_world_base=T_world_base, opw=None)
    robot.closed_form = ur_closed_form(robot)        # all eight solutions (Hawkins 2013)
    return robot
