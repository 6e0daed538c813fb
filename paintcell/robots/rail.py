"""A paint arm on a linear rail: a 7th, prismatic axis in the MuJoCo and the Pinocchio model.

`load_rail_robot(arm, T_world_rail, rail)` generates one MJCF — a fixed `rail_base` (the rail's
frame: the carriage slides along its +y, across the arm's forward +x, as on booth rails), a
`rail_carriage` body with the slide joint `rail`, its own limits, damping, armature and force
motor, and the arm's MJCF attached on the carriage — and loads it as a `paintcell.robots.Robot` with
7 joints (`rail` [m], joint1..joint6). Both engines read that one file, as for the fixed arms.

IK redundancy (`solve_rail_paths`): the rail stays still during a paint pass and moves between
passes (during the turn-arounds). Per pass, its position is the minimum of a smooth 1-D cost —
the mean squared distance of the arm's main axes (J1-J3, scaled by their ranges) from a preferred
configuration along the pass, on the best closed-form branch — over the rail positions where the
whole pass is feasible (inside the limits, off the wrist singularity, with a comfort margin):
a coarse scan of the rail, then a bounded scalar minimization (Brent) around the best scan
point (an optional penalty — e.g. the arm's clearance to the parts around it,
`paintcell.booth.booth_clearance` — is added where the plain cost could still lose to it).
The arm's 6-axis IK (`paintcell.robots.ik.solve_path`: closed form + DLS refinement) then
runs at that rail position, and the 7-axis result is re-measured on the 7-axis model.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from paintcell.core.transforms import half_turned
from paintcell.robots.arms import load_arm
from paintcell.robots.errors import RobotError
from paintcell.robots.robot import Robot, write_generated_mjcf

#: worst-case margin [rad] to joint limits / wrist singularity below which a rail position costs
#: more (a pass at the edge of the arm's range leaves the moves between passes no room).
COMFORT_MARGIN_RAD = 0.5
#: an extra cost of a rail position: penalty(s_m, Q (M, 6) arm joints [rad]) -> float.
RailPenalty = Callable[[float, np.ndarray], float]
#: names in the generated MJCF.
RAIL_JOINT = "rail"
RAIL_BASE_BODY = "rail_base"
#: poses of a pass a carriage search scores (`search_poses`); its picks are confirmed on all.
SEARCH_POSES = 40


@dataclass(frozen=True)
class RailSpec:
    """A linear rail under the arm (SI units). The carriage slides along the rail frame's +y; the
    arm's zero (forward, +x) faces across the rail.

    lower_m, upper_m: travel limits of the carriage [m] (the arm base's x in the rail frame).
    v_max_m_s, a_max_m_s2: carriage speed and acceleration limits. 1.5 m/s and 4 m/s² are
        typical of paint-robot rails (estimate: rack-and-pinion rails carrying a 600 kg arm).
    mass_kg: carriage mass (estimate: 300 kg, steel carriage with the arm's riser).
    force_max_n: carriage drive force limit [N] (estimate: accelerates carriage + arm ≈ 1000 kg
        at 4 m/s² with 2x headroom).
    damping_n_s_m, armature_kg: viscous friction and reflected motor inertia of the drive
        (estimate).
    home_m: carriage position of the `home` keyframe [m].
    """

    lower_m: float = -2.0
    upper_m: float = 2.0
    v_max_m_s: float = 1.5
    a_max_m_s2: float = 4.0
    mass_kg: float = 300.0
    force_max_n: float = 8000.0
    damping_n_s_m: float = 200.0
    armature_kg: float = 50.0
    home_m: float = 0.0

    def __post_init__(self) -> None:
        vals = [self.lower_m, self.upper_m, self.v_max_m_s, self.a_max_m_s2, self.mass_kg,
                self.force_max_n, self.damping_n_s_m, self.armature_kg, self.home_m]
        if not all(np.isfinite(v) for v in vals):
            raise RobotError("RailSpec values must be finite numbers")
        if not self.lower_m < self.upper_m:
            raise RobotError(f"rail lower_m {self.lower_m} must be below upper_m {self.upper_m}")
        if not self.lower_m <= self.home_m <= self.upper_m:
            raise RobotError(f"rail home_m {self.home_m} must lie in [{self.lower_m}, "
                             f"{self.upper_m}] m")
        if min(self.v_max_m_s, self.a_max_m_s2, self.mass_kg, self.force_max_n) <= 0 \
                or min(self.damping_n_s_m, self.armature_kg) < 0:
            raise RobotError("RailSpec speeds, accelerations, mass and force must be > 0")


@dataclass(frozen=True, eq=False)
class RailAxis:
    """What the IK needs to know of a rail robot: the rail, and the arm alone (a 6-axis `Robot`
    at an identity base; `arm_at(s)` places it where the carriage is at s [m])."""

    spec: RailSpec
    arm: Robot
    T_world_rail: np.ndarray

    def arm_at(self, s_m: float) -> Robot:
        """The 6-axis arm with its base on the carriage at rail position s_m [m]."""
        T = self.T_world_rail.copy()
        T[:3, 3] += s_m * self.T_world_rail[:3, 1]
        return self.arm.placed(T)


def rail_mjcf(arm_mjcf: str | Path, rail: RailSpec, arm_home: npt.ArrayLike, stem: str) -> Path:
    """Generate the MJCF of `arm_mjcf` on a rail; returns its path (content-addressed temp file).

    The arm's root body is wrapped, unchanged, in `rail_base` (fixed) > `rail_carriage` (slide
    joint `rail` along +y); a force motor `rail_motor` is added first among the actuators and the
    `home` keyframe gets the rail's home in front of the arm's.
    """
    arm_mjcf = Path(arm_mjcf)
    root = ET.parse(arm_mjcf).getroot()
    world = root.find("worldbody")
    arm_bodies = [] if world is None else world.findall("body")
    if world is None or len(arm_bodies) != 1:
        raise RobotError(f"{arm_mjcf}: a rail needs an arm MJCF with exactly one root body")
    arm_body = arm_bodies[0]
    for inc in root.iter():   # mesh/texture files stay where the arm's MJCF is
        if inc.tag == "compiler":
            inc.set("meshdir", str(arm_mjcf.parent / inc.get("meshdir", ".")))
    length = rail.upper_m - rail.lower_m
    mid = 0.5 * (rail.upper_m + rail.lower_m)
    base = ET.Element("body", name=RAIL_BASE_BODY)
    # The beam lies below the carriage top (z < 0): the arm's base plate sits at z = 0.
    ET.SubElement(base, "geom", name="rail_beam", type="box", group="2", contype="0",
                  conaffinity="0", density="0", rgba="0.3 0.3 0.32 1",
                  size=f"0.25 {0.5 * length + 0.45} 0.05", pos=f"0 {mid} -0.15")
    carriage = ET.SubElement(base, "body", name="rail_carriage")
    # Steel carriage plate 0.9 x 0.9 x 0.1 m.
    ixx = rail.mass_kg * (0.81 + 0.01) / 12
    ET.SubElement(carriage, "inertial", pos="0 0 -0.05", mass=repr(rail.mass_kg),
                  diaginertia=f"{ixx} {ixx} {rail.mass_kg * 1.62 / 12}")
    ET.SubElement(carriage, "joint", name=RAIL_JOINT, type="slide", axis="0 1 0",
                  limited="true", range=f"{rail.lower_m} {rail.upper_m}",
                  damping=repr(rail.damping_n_s_m), armature=repr(rail.armature_kg),
                  actuatorfrcrange=f"{-rail.force_max_n} {rail.force_max_n}")
    ET.SubElement(carriage, "geom", name="rail_carriage", type="box", group="2", contype="0",
                  conaffinity="0", density="0", rgba="0.25 0.25 0.25 1", size="0.45 0.45 0.05",
                  pos="0 0 -0.05")
    idx = list(world).index(arm_body)
    world.remove(arm_body)
    carriage.append(arm_body)
    world.insert(idx, base)
    act = root.find("actuator")
    if act is None:
        raise RobotError(f"{arm_mjcf}: the arm MJCF has no <actuator> section")
    act.insert(0, ET.Element("motor", name="rail_motor", joint=RAIL_JOINT, ctrllimited="true",
                             ctrlrange=f"{-rail.force_max_n} {rail.force_max_n}"))
    home = np.concatenate([[rail.home_m], np.asarray(arm_home, float)])
    for kf in root.iter("keyframe"):
        root.remove(kf)
    kf = ET.SubElement(root, "keyframe")
    ET.SubElement(kf, "key", name="home", qpos=" ".join(repr(float(v)) for v in home),
                  ctrl=" ".join(["0"] * len(home)))
    xml = ET.tostring(root, encoding="unicode")
    mujoco.MjModel.from_xml_string(xml)   # compiles, or raises with MuJoCo's message
    return write_generated_mjcf(xml, stem)


def load_rail_robot(arm_name: str, T_world_rail: npt.ArrayLike | None = None,
                    rail: RailSpec | None = None, tcp_offset: npt.ArrayLike | None = None
                    ) -> Robot:
    """The arm `arm_name` (`paintcell.robots.arms.load_arm` names with closed-form IK) on a linear
    rail.

    T_world_rail: (4, 4) rail frame in the world (carriage along its +y; the arm's base plate at
    its origin when the carriage is at 0). Returns a 7-joint `Robot` (`rail` first, [m]) whose
    `rail` attribute is a `RailAxis`; `paintcell.robots.paths.solve_paths` resolves its redundancy.
    """
    rail = rail or RailSpec()
    arm = load_arm(arm_name, tcp_offset=tcp_offset)
    if arm.opw is None:
        raise RobotError(f"{arm_name} has no closed-form IK; a rail needs an ortho-parallel arm "
                         "(abb_paint or irb5500)")
    path = rail_mjcf(arm.mjcf_path, rail, arm.q_home, f"{arm_name}_rail")
    robot = Robot.from_mjcf(f"{arm_name}_rail", path,
                            v_max=np.concatenate([[rail.v_max_m_s], arm.v_max]),
                            a_max=np.concatenate([[rail.a_max_m_s2], arm.a_max]),
                            T_world_base=T_world_rail, base_body_name=RAIL_BASE_BODY)
    if robot.joint_names[0] != RAIL_JOINT or robot.nq != arm.nq + 1:
        raise RobotError(f"generated rail model has joints {robot.joint_names}; expected "
                         f"{RAIL_JOINT!r} then the arm's")
    robot.wrist_joint_index = None if arm.wrist_joint_index is None else arm.wrist_joint_index + 1
    robot.rail = RailAxis(spec=rail, arm=arm, T_world_rail=robot.T_world_base.copy())
    return robot


def placed_rail(robot: Robot) -> RailAxis:
    """The robot's RailAxis at the robot's current base pose (after `Robot.placed`)."""
    ax: RailAxis = robot.rail
    if not np.allclose(ax.T_world_rail, robot.T_world_base):
        ax = RailAxis(spec=ax.spec, arm=ax.arm, T_world_rail=robot.T_world_base.copy())
    return ax


def travel_m(robot: Robot) -> tuple[float, float]:
    """The carriage travel [m] a rail robot plans within: its RailSpec's limits less the robot's
    joint-limit margin (`paintcell.robots.robot.LIMIT_MARGIN_M`)."""
    return float(robot.q_lower[0]), float(robot.q_upper[0])


def rail_cost(robot: Robot, T_world_tcp: np.ndarray, s_m: float, q_pref: np.ndarray,
              settings: Any, jump_scale: float = 1.0) -> tuple[float, bool]:
    """(cost, feasible) of `rail_branch` (its docstring), without the branch."""
    cost, ok, _ = rail_branch(robot, T_world_tcp, s_m, q_pref, settings, jump_scale)
    return cost, ok


def rail_branch(robot: Robot, T_world_tcp: np.ndarray, s_m: float, q_pref: np.ndarray,
                settings: Any, jump_scale: float = 1.0
                ) -> tuple[float, bool, np.ndarray | None]:
    """(cost, feasible) of holding the carriage at s_m [m] for the pass T_world_tcp (M, 4, 4).

    cost: mean over the pass of Σ_{J1..J3} ((q − q_pref) / range)², plus ((m0 − margin)/m0)² when
    the pass's worst-case margin (joint limits, wrist singularity) is under m0 =
    COMFORT_MARGIN_RAD, on the best closed-form branch (feasible branches with the IK settings'
    comfort margin first, then feasible ones); infeasible rail
    positions cost 1e3 + the number of poses outside the limits. jump_scale: the pass was
    subsampled by this factor (the joint-jump threshold grows by it). The third value is that
    branch's arm joints (M, 6) [rad] along the pass (None where no branch is feasible).
    """
    from paintcell.robots.ik import opw_branches

    ax = placed_rail(robot)
    if ax.arm.opw is not None:          # the closed form at the carriage's base, no arm copy
        return rail_branches(robot, T_world_tcp, np.array([s_m]), q_pref, settings,
                             jump_scale)[0]
    arm = ax.arm_at(s_m)
    Q, _, within = opw_branches(arm, T_world_tcp, q_pref)
    return _branch_cost(arm, Q, within, q_pref, settings, jump_scale, len(T_world_tcp))


def rail_branches(robot: Robot, T_world_tcp: np.ndarray, s_grid: np.ndarray,
                  q_pref: np.ndarray, settings: Any, jump_scale: float = 1.0
                  ) -> list[tuple[float, bool, np.ndarray | None]]:
    """`rail_branch` at every carriage position of `s_grid` [m], the same numbers: the
    closed-form IK of the pass at all of them in one call (the arm is not re-placed per
    position), then each position's branches and cost."""
    from paintcell.robots.ik import continuous_branches
    from paintcell.robots.opw import inverse

    ax = placed_rail(robot)
    arm = ax.arm
    if arm.opw is None or not len(s_grid):  # rail_branch says what is missing
        return [rail_branch(robot, T_world_tcp, float(s), q_pref, settings, jump_scale)
                for s in s_grid]
    T = np.asarray(T_world_tcp, float)
    tool = np.linalg.inv(arm.T_flange_tcp)
    flange = []
    for s_m in s_grid:                      # Robot.flange_poses at RailAxis.arm_at(s_m)'s base
        base = ax.T_world_rail.copy()
        base[:3, 3] += s_m * ax.T_world_rail[:3, 1]
        flange.append(np.linalg.inv(base) @ T @ tool)
    Q_all, reach_all = inverse(arm.opw, np.concatenate(flange))
    m = len(T)
    out = []
    for g in range(len(s_grid)):
        Q, _, within = continuous_branches(arm, Q_all[g * m:(g + 1) * m],
                                           reach_all[g * m:(g + 1) * m], q_pref)
        out.append(_branch_cost(arm, Q, within, q_pref, settings, jump_scale, m))
    return out


def _branch_cost(arm: Robot, Q: np.ndarray, within: np.ndarray, q_pref: np.ndarray,
                 settings: Any, jump_scale: float, m: int
                 ) -> tuple[float, bool, np.ndarray | None]:
    """`rail_branch`'s result from the arm's closed-form branches Q (8, M, 6), within (8, M)."""
    from paintcell.robots.ik import branch_feasibility

    st = branch_feasibility(arm, Q, within, settings, jump_scale=jump_scale)
    span = (arm.q_upper - arm.q_lower)[:3]
    d2 = np.sum(((np.where(within[:, :, None], Q, 0.0)[:, :, :3] - q_pref[:3]) / span) ** 2, axis=2)
    dev = np.sum(np.where(within, d2, 0.0), axis=1) / np.maximum(within.sum(axis=1), 1)
    # Margins (joint limits, wrist singularity) under COMFORT_MARGIN_RAD cost quadratically.
    short = np.maximum(0.0, COMFORT_MARGIN_RAD - st.margin) / COMFORT_MARGIN_RAD
    cost = dev + short ** 2
    comfy = st.feasible & (st.margin >= settings.comfort_margin_rad)
    ok = comfy if comfy.any() else st.feasible
    if ok.any():
        b = int(np.argmin(np.where(ok, cost, np.inf)))
        return float(cost[b]), True, Q[b]
    return 1e3 + float(m - st.n_ok.max()), False, None


def search_poses(T_world_tcp: np.ndarray, n_sub: int = SEARCH_POSES
                 ) -> tuple[np.ndarray, float]:
    """The poses (K, 4, 4) of a pass (M, 4, 4) that a search scores, at most n_sub of them
    evenly along it, and the factor by which they are farther apart than the pass's own (the
    joint-jump threshold of `rail_branch`'s jump_scale): the widest gap between two kept poses,
    in the pass's steps, so a pass whose every step is under the threshold is never screened
    out."""
    keep = np.unique(np.linspace(0, len(T_world_tcp) - 1, n_sub).astype(int))
    return T_world_tcp[keep], float(max(1, np.diff(keep).max(initial=1)))


def feasible_positions(robot: Robot, T_world_tcp: np.ndarray, s_grid: np.ndarray,
                       q_pref: np.ndarray, settings: Any, need: str = "all") -> np.ndarray:
    """(S,) bool: whether the pass T_world_tcp (M, 4, 4) is feasible (`rail_branch`) with the
    carriage at each of s_grid [m], confirmed on every pose. `search_poses` screens the grid (its
    jump threshold scaled by the subsample's widest gap); the positions it passes are confirmed
    on the whole pass (a subsample can hide a step larger than the threshold between two poses
    it skipped).

    need: "all" confirms every screened position; "any" stops at the first confirmed one (True
    there only); "ends" confirms from each end of the grid inward and stops at the first on each
    side (True at the least and the most feasible position only)."""
    s_grid = np.asarray(s_grid, float)
    sub, js = search_poses(T_world_tcp)
    ok = np.zeros(len(s_grid), bool)
    if need == "any":                       # one position at a time, the first confirmed
        for i, s_m in enumerate(s_grid):
            if rail_branch(robot, sub, float(s_m), q_pref, settings, js)[1] \
                    and rail_branch(robot, T_world_tcp, float(s_m), q_pref, settings)[1]:
                ok[i] = True
                break
        return ok
    screened = np.flatnonzero([f for _, f, _ in rail_branches(robot, sub, s_grid, q_pref,
                                                              settings, js)])
    if need == "all":
        if len(screened):
            ok[screened] = [f for _, f, _ in rail_branches(robot, T_world_tcp, s_grid[screened],
                                                           q_pref, settings)]
        return ok
    for order in (screened, screened[::-1]):    # a few positions each, usually the first
        for i in order:
            if ok[i] or rail_branch(robot, T_world_tcp, float(s_grid[i]), q_pref, settings)[1]:
                ok[i] = True
                break
    return ok


def _lazy_min(costs: Sequence[float], total: Callable[[int], float]) -> np.ndarray:
    """Totals (inf where not evaluated) of items with plain costs `costs`, total(i) ≥ costs[i]
    evaluated in order of the plain cost until no unevaluated item can win: the same minimum
    as evaluating every total, usually in one or two calls."""
    totals = np.full(len(costs), np.inf)
    for i in np.argsort(costs, kind="stable"):
        if costs[i] >= totals.min():
            break
        totals[i] = total(int(i))
    return totals


def best_rail_position(robot: Robot, T_world_tcp: np.ndarray, q_pref: np.ndarray,
                       settings: Any, n_scan: int = 41, n_sub: int = SEARCH_POSES,
                       penalty: RailPenalty | None = None) -> tuple[float, bool]:
    """Rail position [m] for one pass (see the module doc) and whether the pass is feasible
    there on every pose. The search scores the pass subsampled to `n_sub` poses; its result is
    confirmed on the whole pass, and where a step between two skipped poses is a joint jump,
    the scan's positions are confirmed the same way and the best confirmed one is taken.
    penalty(s_m, Q): an extra cost of the feasible branch Q (M, 6) [rad] at carriage position
    s_m [m] (e.g. how close the arm comes to things around it:
    `paintcell.booth.booth_clearance`)."""
    lower_m, upper_m = travel_m(robot)
    sub, js = search_poses(T_world_tcp, n_sub)

    def base(s: float) -> tuple[float, bool, np.ndarray | None]:
        return rail_branch(robot, sub, s, q_pref, settings, jump_scale=js)

    def total(s: float, c: float, ok: bool, Q: np.ndarray | None) -> float:
        return c + float(penalty(float(s), Q)) if ok and penalty is not None \
            and Q is not None else c

    grid = np.linspace(lower_m, upper_m, n_scan)
    scan = rail_branches(robot, sub, grid, q_pref, settings, jump_scale=js)
    totals = _lazy_min([c for c, _, _ in scan], lambda i: total(float(grid[i]), *scan[i]))
    k = int(np.argmin(totals))
    h = grid[1] - grid[0]
    lo, hi = max(lower_m, grid[k] - h), min(upper_m, grid[k] + h)
    res = minimize_scalar(lambda s: base(s)[0], bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-4})
    # the refinement of the plain cost, kept where its total is no worse than the grid's
    s = float(res.x)
    if not total(s, *base(s)) <= totals[k]:
        s = float(grid[k])
    feasible = base(s)[1]
    if not feasible or rail_branch(robot, T_world_tcp, s, q_pref, settings)[1]:
        return s, feasible
    # A joint jump between poses the search skipped: the scan's feasible positions on every pose.
    idx = np.flatnonzero([f for _, f, _ in scan])
    full = [(int(i), r) for i, r in zip(idx, rail_branches(robot, T_world_tcp, grid[idx],
                                                           q_pref, settings), strict=True)
            if r[1]]
    if not full:
        return s, False
    totals = _lazy_min([r[0] for _, r in full], lambda j: total(float(grid[full[j][0]]),
                                                                *full[j][1]))
    return float(grid[full[int(np.argmin(totals))][0]]), True


def solve_rail_paths(robot: Robot, paths: Sequence[npt.ArrayLike],
                     q_seed: npt.ArrayLike | None = None, free_spin: bool = False,
                     settings: Any = None, q_pref: npt.ArrayLike | None = None,
                     penalty: RailPenalty | None = None) -> list[Any]:
    """`paintcell.robots.paths.solve_paths` for a rail robot: per pass, the rail position of
    `best_rail_position` (with its `penalty`, if any), then the arm's IK there (seeded with the
    previous pass's end).

    q_seed: (7,) [m, rad...]; q_pref: (6,) preferred arm configuration [rad] (default: the
    arm's home). Returns `IKPathResult`s with q (M, 7) re-measured on the 7-axis model.
    """
    from paintcell.robots.ik import IKPathResult, IKSettings, solve_path
    from paintcell.robots.reachability import ReachabilityReport

    s = settings or IKSettings()
    ax = placed_rail(robot)
    pref = np.asarray(ax.arm.q_home if q_pref is None else q_pref, float)
    seed = None if q_seed is None else np.asarray(q_seed, float)[1:]
    out = []
    for T in paths:
        T = np.asarray(T, float)
        s_m, ok = best_rail_position(robot, T, pref, s, penalty=penalty)
        if not ok and not free_spin:    # the bell half-turned: the same film (paths module doc)
            T_half = half_turned(T)
            s_half, ok = best_rail_position(robot, T_half, pref, s, penalty=penalty)
            if ok:
                T, s_m = T_half, s_half
        res = solve_path(ax.arm_at(s_m), T, q_seed=seed, free_spin=free_spin, settings=s)
        q = np.column_stack([np.full(len(T), s_m), res.q])
        report = ReachabilityReport.measure(robot, q, T, free_spin=free_spin,
                                            thresholds=s.thresholds())
        out.append(IKPathResult(q=q, reachability=report, branch=res.branch,
                                method=f"rail+{res.method}"))
        seed = res.q[-1]
    return out
