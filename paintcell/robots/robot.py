"""`Robot`: one arm + tool, loaded from one MJCF that both MuJoCo and Pinocchio read.

The MJCF (with the TCP site) is the single source of truth: limits, armature and damping are read
from MuJoCo's compiled model; kinematics and dynamics come from `pin.buildModelFromMJCF` of the
same file. The Pinocchio model includes the base pose `T_world_base` (the arm placed in the cell),
so `fk`, `jacobian` and RNEA work in world coordinates.
"""

from __future__ import annotations

import hashlib
import os
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from paintcell.core.atomic_io import atomic_write_text
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import read_regular_bytes
from paintcell.core.transforms import check_pose, quat_wxyz_from_matrix
from paintcell.robots.errors import RobotError
from paintcell.robots.opw import OPWParameters

ROBOTS_DIR = Path(__file__).resolve().parent
#: how far inside each MJCF joint range paintcell plans: 0.001 rad (0.06°) on a hinge, 1 mm on a
#: slide (a rail), at most a tenth of the range. A path planned onto a limit is executed against
#: it (the servo presses the joint on its limit and MuJoCo's soft limit gives a few µrad or µm),
#: and a robot controller stops there; the margin keeps every planned pose clear of it while
#: taking next to nothing from the arm's reach.
LIMIT_MARGIN_RAD = 0.001
LIMIT_MARGIN_M = 0.001


def _as_pose(T: npt.ArrayLike | None, what: str) -> np.ndarray:
    """(4,4) float64 rigid transform, checked (`paintcell.core.transforms.check_pose`); identity
    when
    None."""
    if T is None:
        return np.eye(4)
    return check_pose(T, what, error=RobotError).copy()


def _mj_pose(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    T[:3, :3] = R.reshape(3, 3)
    T[:3, 3] = pos
    return T


def cache_dir() -> Path:
    """The per-user private folder of generated robot models (mode 0700, owned by this user):
    `$XDG_CACHE_HOME/paintcell/robots`, else `~/.cache/paintcell/robots`; where neither can be
    made, a fresh private temp folder of this process."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    root = Path(base) if os.path.isabs(base) else Path.home() / ".cache"
    d = root / "paintcell" / "robots"
    try:
        d.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = os.lstat(d)
        if stat.S_ISDIR(st.st_mode) and st.st_uid == os.geteuid():
            if stat.S_IMODE(st.st_mode) & 0o077:
                os.chmod(d, 0o700)
            return d
    except OSError:
        pass
    global _PRIVATE_FALLBACK
    if _PRIVATE_FALLBACK is None:  # mkdtemp: 0700, created by this process, never shared
        _PRIVATE_FALLBACK = Path(tempfile.mkdtemp(prefix="paintcell-robots-"))
    return _PRIVATE_FALLBACK


_PRIVATE_FALLBACK: Path | None = None


def write_generated_mjcf(xml: str, stem: str) -> Path:
    """Write generated MJCF text to a content-addressed file in `cache_dir()`; return its path.

    The file is named by the SHA-256 of the text, and a file found under that name is used only
    when its content has that digest: a cache file edited by anyone (joint ranges, masses) is
    rewritten from `xml`, never loaded. Atomic (write + rename), so parallel processes may
    generate the same model at once.
    """
    data = xml.encode()
    digest = hashlib.sha256(data).hexdigest()
    path = cache_dir() / f"{stem}_{digest[:16]}.xml"
    try:
        ok = hashlib.sha256(read_regular_bytes(path)).hexdigest() == digest
    except (OSError, PaintcellError):
        ok = False
    if not ok:
        if path.is_symlink() or (path.exists() and not path.is_file()):
            path.unlink()  # a link or special file in our private cache: replace it
        atomic_write_text(path, xml)
    return path


def with_tcp_offset(mjcf_path: Path, tcp_site_name: str, T_flange_tcp: npt.ArrayLike,
                    stem: str) -> Path:
    """A copy of the MJCF with the TCP site moved to `T_flange_tcp` (4,4) [m] in its body frame."""
    T = _as_pose(T_flange_tcp, "tcp_offset")
    spec = mujoco.MjSpec.from_file(str(mjcf_path))
    site = spec.site(tcp_site_name)
    if site is None:
        raise RobotError(f"site {tcp_site_name!r} not in {mjcf_path}; name the TCP site there")
    site.pos = T[:3, 3]
    site.quat = quat_wxyz_from_matrix(T[:3, :3])
    spec.compile()
    return write_generated_mjcf(spec.to_xml(), stem)


@dataclass(eq=False)
class Robot:
    """An arm with its tool, placed in the world. SI units; joint arrays are (nq,).

    Build with `paintcell.robots.load_robot(name, ...)` or `Robot.from_mjcf(...)`; treat as
    immutable (`placed(T_world_base)` gives a copy at another base pose).
    """

    name: str
    mjcf_path: Path
    joint_names: tuple[str, ...]
    q_lower: np.ndarray          # (nq,) [rad] the range planned within: the MJCF's less the
    q_upper: np.ndarray          # (nq,) [rad] `LIMIT_MARGIN_RAD` (`_M` on slides) at each end
    v_max: np.ndarray            # (nq,) [rad/s]
    a_max: np.ndarray            # (nq,) [rad/s²]
    tau_max: np.ndarray          # (nq,) [N·m]
    q_home: np.ndarray           # (nq,) [rad], the MJCF `home` keyframe
    armature: np.ndarray         # (nq,) reflected rotor inertia [kg·m²]
    damping: np.ndarray          # (nq,) viscous joint damping [N·m·s/rad]
    tcp_site_name: str
    base_body_name: str
    flange_site_name: str
    T_world_base: np.ndarray     # (4,4)
    T_flange_tcp: np.ndarray     # (4,4) tool offset, from the MJCF
    pin_model: Any
    pin_data: Any
    tcp_frame_id: int
    opw: OPWParameters | None = None   # closed-form IK parameters when the arm is ortho-parallel
    # closed-form IK of another geometry (the UR arms: `paintcell.robots.ur_ik`): T_base_flange
    # (M, 4, 4) -> (Q (M, 8, n) [rad], reach (M, 8)), as `paintcell.robots.opw.inverse` gives
    closed_form: Any = field(default=None, repr=False)
    wrist_joint_index: int | None = 4  # joint whose sin is 0 at the wrist singularity (J5)
    # `paintcell.robots.rail.RailAxis` when joint 0 is a linear rail carrying the arm
    rail: Any = None
    # (nq, 2) the MJCF's own range [rad; m on slides]: the hard limits q_lower/q_upper keep clear of
    q_range_mjcf: np.ndarray | None = field(default=None, repr=False)
    _base_joint_placement: Any = field(default=None, repr=False)
    _base_frame_placement: Any = field(default=None, repr=False)

    # --- construction -----------------------------------------------------------------------
    @classmethod
    def from_mjcf(cls, name: str, mjcf_path: str | os.PathLike[str], *,
                  v_max: npt.ArrayLike, a_max: npt.ArrayLike,
                  T_world_base: npt.ArrayLike | None = None, tcp_site_name: str = "tcp",
                  flange_site_name: str = "flange_site", base_body_name: str = "base_link",
                  opw: OPWParameters | None = None) -> Robot:
        """Load `mjcf_path` (arm + tool; hinge joints, and slide joints for rails) into MuJoCo and
        Pinocchio."""
        path = Path(mjcf_path)
        if not path.is_file():
            raise RobotError(f"MJCF {path} not found; check the path or reinstall paintcell")
        mj = mujoco.MjModel.from_xml_path(str(path))
        if np.any((mj.jnt_type != mujoco.mjtJoint.mjJNT_HINGE)
                  & (mj.jnt_type != mujoco.mjtJoint.mjJNT_SLIDE)):
            raise RobotError(f"{path}: only hinge and slide joints are supported; remove free/ball "
                             "joints")
        nq = mj.nq
        for site in (tcp_site_name, flange_site_name):
            if mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_SITE, site) < 0:
                raise RobotError(f"{path}: no site named {site!r}; add it to the tool body")
        if mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, base_body_name) < 0:
            raise RobotError(f"{path}: no body named {base_body_name!r}; name the arm's root body")
        joint_names = tuple(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(nq))
        q_lower = mj.jnt_range[:, 0].copy()
        q_upper = mj.jnt_range[:, 1].copy()
        if np.any(q_upper <= q_lower):
            raise RobotError(f"{path}: every joint needs a range (lower < upper); add range=")
        margin = np.minimum(np.where(mj.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE, LIMIT_MARGIN_M,
                                     LIMIT_MARGIN_RAD), 0.1 * (q_upper - q_lower))
        hard = np.column_stack([q_lower, q_upper])
        q_lower, q_upper = q_lower + margin, q_upper - margin
        tau = np.full(nq, np.inf)
        for act in range(mj.nu):
            j = mj.actuator_trnid[act, 0]
            tau[j] = min(abs(mj.actuator_ctrlrange[act, 0]), abs(mj.actuator_ctrlrange[act, 1]))
        key = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_KEY, "home")
        q_home = mj.key_qpos[key].copy() if key >= 0 else np.clip(np.zeros(nq), q_lower, q_upper)

        # Tool offset from MuJoCo's compiled values (independent of Pinocchio's site import).
        data = mujoco.MjData(mj)
        mujoco.mj_kinematics(mj, data)
        T_w_fl = _mj_pose(data.site(flange_site_name).xpos, np.zeros(4))
        T_w_fl[:3, :3] = data.site(flange_site_name).xmat.reshape(3, 3)
        T_w_tcp = np.eye(4)
        T_w_tcp[:3, :3] = data.site(tcp_site_name).xmat.reshape(3, 3)
        T_w_tcp[:3, 3] = data.site(tcp_site_name).xpos
        T_flange_tcp = np.linalg.inv(T_w_fl) @ T_w_tcp

        pm = pin.buildModelFromMJCF(str(path))
        if pm.nq != nq or tuple(pm.names[1:]) != joint_names:
            raise RobotError(f"{path}: Pinocchio and MuJoCo see different joints "
                             f"({list(pm.names[1:])} vs {list(joint_names)}); use hinge joints")
        tcp_id = cls._tcp_frame(pm, mj, tcp_site_name)
        v = np.broadcast_to(np.asarray(v_max, float), (nq,)).copy()
        a = np.broadcast_to(np.asarray(a_max, float), (nq,)).copy()
        robot = cls(name=name, mjcf_path=path, joint_names=joint_names, q_lower=q_lower,
                    q_upper=q_upper, v_max=v, a_max=a, tau_max=tau, q_home=q_home,
                    armature=mj.dof_armature.copy(), damping=mj.dof_damping.copy(),
                    tcp_site_name=tcp_site_name, base_body_name=base_body_name,
                    flange_site_name=flange_site_name, T_world_base=np.eye(4),
                    T_flange_tcp=T_flange_tcp, pin_model=pm, pin_data=pm.createData(),
                    tcp_frame_id=tcp_id, opw=opw, q_range_mjcf=hard,
                    _base_joint_placement=[pin.SE3(pm.jointPlacements[j])
                                           for j in range(pm.njoints)],
                    _base_frame_placement=[pin.SE3(f.placement) for f in pm.frames])
        robot._set_base(_as_pose(T_world_base, "T_world_base"))
        robot.q_home = robot.planned_home(q_home)
        return robot

    @staticmethod
    def _tcp_frame(pm: Any, mj: Any, site: str) -> int:
        """Pinocchio frame id of the TCP, with its placement set from MuJoCo's compiled values.

        Pinocchio imports MJCF sites as frames but (4.1) misplaces sites inside nested fixed bodies;
        the placement relative to the parent joint is recomputed here from MuJoCo's model.
        """
        sid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_SITE, site)
        body = mj.site_bodyid[sid]
        T = _mj_pose(mj.site_pos[sid], mj.site_quat[sid])
        while mj.body_jntnum[body] == 0 and body != 0:   # climb the fixed bodies
            T = _mj_pose(mj.body_pos[body], mj.body_quat[body]) @ T
            body = mj.body_parentid[body]
        if body == 0:
            raise RobotError(f"TCP site {site!r} is not on a moving body; attach it to the tool")
        joint_name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, mj.body_jntadr[body])
        jid = pm.getJointId(joint_name)
        # MJCF: a joint sits at its body origin (pos 0 here); the body frame is the joint frame.
        if np.abs(mj.jnt_pos[mj.body_jntadr[body]]).max() > 0:
            raise RobotError(f"joint {joint_name!r} has a nonzero pos=; put joints at body origins")
        placement = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
        if pm.existFrame(site):
            fid = pm.getFrameId(site)
            pm.frames[fid].placement = placement
            pm.frames[fid].parentJoint = jid
        else:
            fid = pm.addFrame(pin.Frame(site, jid, placement, pin.FrameType.OP_FRAME))
        return int(fid)

    def _set_base(self, T_world_base: np.ndarray) -> None:
        M = pin.SE3(T_world_base[:3, :3].copy(), T_world_base[:3, 3].copy())
        pm = self.pin_model
        for j in range(1, pm.njoints):
            if pm.parents[j] == 0:
                pm.jointPlacements[j] = M * self._base_joint_placement[j]
        for i, f in enumerate(pm.frames):
            if f.parentJoint == 0 and i > 0:
                f.placement = M * self._base_frame_placement[i]
        self.pin_data = pm.createData()
        self.T_world_base = T_world_base.copy()

    def placed(self, T_world_base: npt.ArrayLike) -> Robot:
        """A copy of this robot at another base pose `T_world_base` (4,4)."""
        T = _as_pose(T_world_base, "T_world_base")
        pm = self.pin_model.copy()
        r = Robot(**{**self.__dict__, "pin_model": pm, "pin_data": pm.createData()})
        r._set_base(T)
        return r

    # --- kinematics ---------------------------------------------------------------------------
    @property
    def has_closed_form(self) -> bool:
        """All eight IK solutions of a pose in closed form (`closed_form_inverse`)."""
        return self.opw is not None or self.closed_form is not None

    def closed_form_inverse(self, T_base_flange: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(Q (M, 8, n) [rad], reach (M, 8)) of flange poses T_base_flange (M, 4, 4) in the base
        frame: `paintcell.robots.opw.inverse` for an ortho-parallel arm, else `closed_form`."""
        T = np.asarray(T_base_flange, float)
        if self.opw is not None:
            from paintcell.robots.opw import inverse

            return inverse(self.opw, T)
        if self.closed_form is None:
            raise RobotError(f"{self.name} has no closed-form IK; use DLS (solve_path does)")
        return self.closed_form(T)

    @property
    def nq(self) -> int:
        """Number of joints."""
        return int(self.pin_model.nq)

    def check_q(self, q: npt.ArrayLike) -> np.ndarray:
        """(nq,) float64 joint vector, or RobotError naming the expected shape."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.nq,) or not np.all(np.isfinite(q)):
            raise RobotError(f"{self.name}: q must be a finite ({self.nq},) joint vector [rad], "
                             f"got shape {q.shape}")
        return q

    def fk(self, q: npt.ArrayLike) -> np.ndarray:
        """T_world_tcp (4,4) at joint angles q (nq,) [rad]."""
        q = self.check_q(q)
        pin.forwardKinematics(self.pin_model, self.pin_data, q)
        return np.array(pin.updateFramePlacement(self.pin_model, self.pin_data,
                                                 self.tcp_frame_id).homogeneous)

    def fk_many(self, Q: npt.ArrayLike) -> np.ndarray:
        """T_world_tcp (K,4,4) for joint angles Q (K, nq) [rad]."""
        Q = np.asarray(Q, dtype=float)
        if Q.ndim != 2 or Q.shape[1] != self.nq:
            raise RobotError(f"{self.name}: Q must be (K, {self.nq}) [rad], got {Q.shape}")
        out = np.empty((len(Q), 4, 4))
        m, d, fid = self.pin_model, self.pin_data, self.tcp_frame_id
        for k, q in enumerate(Q):
            pin.forwardKinematics(m, d, q)
            out[k] = pin.updateFramePlacement(m, d, fid).homogeneous
        return out

    def jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """(6, nq) TCP Jacobian [v; ω] in world-aligned axes at the TCP origin (m/rad, rad/rad)."""
        q = self.check_q(q)
        return np.array(pin.computeFrameJacobian(self.pin_model, self.pin_data, q,
                                                 self.tcp_frame_id,
                                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))

    def flange_poses(self, T_world_tcp: npt.ArrayLike) -> np.ndarray:
        """T_base_flange (M,4,4) for TCP targets T_world_tcp (M,4,4): strips base and tool."""
        T = np.asarray(T_world_tcp, float)
        return np.linalg.inv(self.T_world_base) @ T @ np.linalg.inv(self.T_flange_tcp)

    def planned_home(self, q: npt.ArrayLike) -> np.ndarray:
        """q (nq,) [rad; m on slides] with every joint that lies on or inside its MJCF limit but
        outside the planned range (within the margin of a limit: a carriage parked at its rail's
        end, an arm joint homed on its stop) moved onto that range, where programs start and end;
        a joint outside the MJCF range is left as it is, for the checks that refuse it."""
        q = np.array(q, dtype=float)
        if self.q_range_mjcf is None:
            return q
        lo, hi = self.q_range_mjcf[:, 0], self.q_range_mjcf[:, 1]
        return np.where((q >= lo) & (q <= hi), np.clip(q, self.q_lower, self.q_upper), q)

    def limit_margin(self, Q: npt.ArrayLike) -> np.ndarray:
        """(K,) smallest distance [rad] of each row of Q (K, nq) to the range planned within
        (`q_lower`, `q_upper`; <0: outside)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        return np.minimum(Q - self.q_lower, self.q_upper - Q).min(axis=1)


# --- the ABB-style paint robot -------------------------------------------------------------------
ABB_PAINT_MJCF = ROBOTS_DIR / "abb_paint" / "abb_paint.xml"
# IRB 4600 datasheet maximum axis speeds 175, 175, 175, 250, 250, 360 °/s.
ABB_PAINT_V_MAX = np.deg2rad([175.0, 175.0, 175.0, 250.0, 250.0, 360.0])
# Estimate (no public figure): full speed in ~0.5 s on the main axes (≈12 m/s² at the TCP at full
# reach), wrist axes ~4x faster; far below the torque limits for this model's inertias
# (README step 7).
ABB_PAINT_A_MAX = np.array([6.0, 6.0, 8.0, 20.0, 20.0, 30.0])


# --- the IRB 5500-class paint robot (paintcell/robots/abb_irb5500/README.md)
# ------------------------------
IRB5500_MJCF = ROBOTS_DIR / "abb_irb5500" / "abb_irb5500.xml"
# Axis speeds 100, 130, 130, 460, 460, 600 °/s (README step 3: IRB 5500 product specification).
IRB5500_V_MAX = np.deg2rad([100.0, 130.0, 130.0, 460.0, 460.0, 600.0])
# Estimate (README step 7): main axes to full speed in ~0.4 s, wrist ~5x faster.
IRB5500_A_MAX = np.array([4.5, 5.5, 6.5, 25.0, 25.0, 35.0])


def bell_tool_offset(straight_m: float = 0.16, head_m: float = 0.12,
                     bend_rad: float = np.pi / 4) -> np.ndarray:
    """T_flange_tcp (4,4) of a bell atomizer: `straight_m` [m] along the flange axis, then a head of
    `head_m` [m] bent by `bend_rad` about the flange y axis (toward flange +x). The default is the
    MJCF's tool (0.16 m, 0.12 m, 45°)."""
    c, s = np.cos(bend_rad), np.sin(bend_rad)
    T = np.eye(4)
    T[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    T[:3, 3] = [head_m * s, 0.0, straight_m + head_m * c]
    return T
