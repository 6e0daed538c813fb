"""Inverse kinematics along paint paths.

Ortho-parallel arms (`robot.opw` set): the closed-form solver (`paintcell.robots.opw`) gives all 8
branches
for every pose of a pass at once; one branch is chosen for the whole pass (inside the joint limits,
away from the wrist singularity, no joint jump, closest to `q_seed`), J4/J6 are unwrapped along the
pass and shifted into their ±400° range near the seed; then every sample is refined with Pinocchio
damped least squares (DLS) from the closed-form solution, or, where that one is missing or outside
the limits, warm-started from the previous sample. Other arms (UR10) use DLS alone: a cold start
with seeded random restarts for the first sample, warm starts after that.

With `free_spin=True` only the spray axis (TCP z) is constrained: a 5-D task; warm-started DLS then
keeps the rotation about the axis that needs the least joint motion from the previous sample.
Every result carries a `ReachabilityReport`, re-measured from the joint solution.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from paintcell.core.transforms import check_poses
from paintcell.robots.errors import RobotError
from paintcell.robots.reachability import ReachabilityReport, ReachabilityThresholds
from paintcell.robots.robot import Robot

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class IKSettings:
    """Solver settings.

    pos_tol_m: position tolerance of a converged sample [m].
    rot_tol_rad: orientation tolerance [rad] (spray-axis angle with free spin).
    damping: DLS damping λ (units of the task error, m ~ rad); small: converged solutions are
        exact, the damping only tames steps near singularities.
    max_step_rad: largest joint step of one DLS iteration [rad].
    warm_iters: DLS iterations per warm-started sample.
    cold_iters: DLS iterations per cold-start attempt.
    cold_restarts: random restarts for a cold start (seeded, uniform inside the limits).
    wrist_sin_min: branch selection keeps |sin q5| above this along the pass.
    max_joint_jump_rad: branch selection rejects branches with a larger jump between samples.
    comfort_margin_rad: branches keeping this margin to limits and wrist singularity [rad] are
        preferred over closer-to-the-seed branches that do not.
    seed: RNG seed of the restarts.
    """

    pos_tol_m: float = 1e-6
    rot_tol_rad: float = 1e-5
    damping: float = 1e-4
    max_step_rad: float = 0.3
    warm_iters: int = 30
    cold_iters: int = 150
    cold_restarts: int = 40
    wrist_sin_min: float = 0.05
    max_joint_jump_rad: float = 0.2
    comfort_margin_rad: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            (self.pos_tol_m > 0, "pos_tol_m must be > 0 [m]"),
            (self.rot_tol_rad > 0, "rot_tol_rad must be > 0 [rad]"),
            (self.damping >= 0, "damping must be >= 0"),
            (self.max_step_rad > 0, "max_step_rad must be > 0 [rad]"),
            (_is_int(self.warm_iters) and self.warm_iters >= 1, "warm_iters must be an int >= 1"),
            (_is_int(self.cold_iters) and self.cold_iters >= 1, "cold_iters must be an int >= 1"),
            (_is_int(self.cold_restarts) and self.cold_restarts >= 0,
             "cold_restarts must be an int >= 0"),
            (0 <= self.wrist_sin_min < 1, "wrist_sin_min must be in [0, 1)"),
            (self.max_joint_jump_rad > 0, "max_joint_jump_rad must be > 0 [rad]"),
            (self.comfort_margin_rad >= 0, "comfort_margin_rad must be >= 0 [rad]"),
            (_is_int(self.seed), "seed must be an int"),
        ]
        for ok, msg in checks:
            # `not ok` is also true for NaN: every comparison with NaN is False.
            if not ok:
                raise RobotError(f"invalid IKSettings: {msg}; the defaults are "
                                 "IKSettings() (see its docstring)")

    def thresholds(self) -> ReachabilityThresholds:
        """The report's thresholds, consistent with these settings."""
        return ReachabilityThresholds(self.pos_tol_m, self.rot_tol_rad, self.wrist_sin_min,
                                      self.max_joint_jump_rad)


def _is_int(x: object) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool)


@dataclass(frozen=True, eq=False)
class IKPathResult:
    """Joint path of one pass.

    q: (M, n) joint angles [rad] (best effort at unreachable poses, never NaN).
    reachability: per-pose report (pass index 0).
    branch: OPW branch used for the pass (0..7), -1 for DLS-only robots.
    method: "opw+dls" or "dls".
    """

    q: np.ndarray
    reachability: ReachabilityReport
    branch: int
    method: str


# --- damped least squares --------------------------------------------------------------------
def _task_error(robot: Robot, T_target: np.ndarray, q: np.ndarray,
                free_spin: bool) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(error e, Jacobian J, position residual [m], rotation residual [rad]) at q."""
    m, d, f = robot.pin_model, robot.pin_data, robot.tcp_frame_id
    J = pin.computeFrameJacobian(m, d, q, f, _LWA)     # also updates d.oMf[f]
    M = d.oMf[f]
    e_p = T_target[:3, 3] - M.translation
    R = M.rotation
    if free_spin:
        z, zt = R[:, 2], T_target[:3, 2]
        c = np.cross(z, zt)
        s = np.linalg.norm(c)
        ang = float(np.arctan2(s, z @ zt))
        w = c * (ang / s) if s > 1e-15 else np.zeros(3)
        # Basis of the plane normal to z: the spin about z is free (5-D task).
        B = np.linalg.svd(np.eye(3) - np.outer(z, z))[0][:, :2]
        e = np.r_[e_p, B.T @ w]
        Jt = np.vstack([J[:3], B.T @ J[3:]])
        return e, Jt, float(np.linalg.norm(e_p)), ang
    w = pin.log3(T_target[:3, :3] @ R.T)
    return np.r_[e_p, w], J, float(np.linalg.norm(e_p)), float(np.linalg.norm(w))


def dls(robot: Robot, T_world_tcp: npt.ArrayLike, q0: npt.ArrayLike, *, free_spin: bool = False,
        max_iters: int = 30, settings: IKSettings | None = None) -> tuple[np.ndarray, bool]:
    """Damped-least-squares IK for one pose T_world_tcp (4,4) from q0 (n,) [rad], joints clamped
    to the limits. Returns (q (n,) [rad], converged to the settings' tolerances)."""
    s = settings or IKSettings()
    T = np.asarray(T_world_tcp, float)
    q = np.clip(np.asarray(q0, float).copy(), robot.q_lower, robot.q_upper)
    lam2 = s.damping ** 2
    for _ in range(max_iters + 1):
        e, J, rp, rr = _task_error(robot, T, q, free_spin)
        if rp <= s.pos_tol_m and rr <= s.rot_tol_rad:
            return q, True
        dq = J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(len(e)), e)
        big = np.abs(dq).max()
        if big > s.max_step_rad:
            dq *= s.max_step_rad / big
        q = np.clip(q + dq, robot.q_lower, robot.q_upper)
    return q, False


def cold_start(robot: Robot, T_world_tcp: npt.ArrayLike, q_seed: npt.ArrayLike | None = None, *,
               free_spin: bool = False, settings: IKSettings | None = None
               ) -> tuple[np.ndarray, bool]:
    """DLS from q_seed, q_home, then seeded random restarts; the first converged solution with
    |sin q5| above the threshold wins (else the first converged, else the last attempt)."""
    s = settings or IKSettings()
    rng = np.random.default_rng(s.seed)
    starts = [np.asarray(q, float) for q in (q_seed, robot.q_home) if q is not None]
    starts += list(rng.uniform(robot.q_lower, robot.q_upper, (s.cold_restarts, robot.nq)))
    fallback: tuple[np.ndarray, bool] | None = None
    q = starts[0]
    for q0 in starts:
        q, ok = dls(robot, T_world_tcp, q0, free_spin=free_spin, max_iters=s.cold_iters,
                    settings=s)
        if ok:
            wi = robot.wrist_joint_index
            if wi is None or abs(np.sin(q[wi])) >= s.wrist_sin_min:
                return q, True
            fallback = fallback or (q, True)
    return fallback or (q, False)


# --- closed-form branch selection -------------------------------------------------------------
def opw_branches(robot: Robot, T_world_tcp: npt.ArrayLike, q_ref: npt.ArrayLike
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All 8 closed-form branches of a pass, continuous along it.

    T_world_tcp: (M, 4, 4). q_ref: (n,) reference [rad] for the 2π shifts (J1, J4, J6).
    Returns Q (8, M, 6) [rad] (unwrapped along the pass, shifted into the limits near q_ref where
    possible), reach (8, M) (closed form exists) and within (8, M) (reach and inside the limits).
    """
    if not robot.has_closed_form:
        raise RobotError(f"{robot.name} has no closed-form IK; use DLS (solve_path does)")
    return opw_branches_flange(robot, robot.flange_poses(T_world_tcp), q_ref)


def opw_branches_flange(robot: Robot, T_base_flange: np.ndarray, q_ref: npt.ArrayLike
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`opw_branches` for flange poses in the base frame, T_base_flange (M, 4, 4)."""
    Q, reach = robot.closed_form_inverse(T_base_flange)
    return continuous_branches(robot, Q, reach, q_ref)


def continuous_branches(robot: Robot, Q: np.ndarray, reach: np.ndarray, q_ref: npt.ArrayLike
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-form solutions Q (M, 8, 6), reach (M, 8) of one pass → (Q (8, M, 6) unwrapped along
    the pass and shifted into the limits near q_ref, reach (8, M), within (8, M))."""
    Q = np.swapaxes(Q, 0, 1).copy()                     # (8, M, 6)
    reach = reach.T.copy()
    lo, hi = robot.q_lower, robot.q_upper
    two_pi_k = 2 * np.pi * np.arange(-3, 4)
    # Unreachable samples take the nearest earlier (else the first) reachable row, so that the
    # unwrap along the pass is not broken by them.
    idx = np.maximum.accumulate(np.where(reach, np.arange(reach.shape[1]), -1), axis=1)
    idx = np.where(idx < 0, np.argmax(reach, axis=1)[:, None], idx)
    Q = np.unwrap(np.take_along_axis(Q, idx[:, :, None], axis=1), axis=1)
    # Shift each joint path by 2πk: inside the limits if possible, start near q_ref.
    cand = Q[:, None] + two_pi_k[None, :, None, None]                 # (8, 7, M, 6)
    inside = (cand >= lo - 1e-12) & (cand <= hi + 1e-12)
    n_in = (inside & reach[:, None, :, None]).sum(axis=2)               # (8, 7, 6)
    dist = np.abs(cand[:, :, 0, :] - np.asarray(q_ref, float))
    k = np.argmax(n_in * 1e3 - np.minimum(dist, 999.0), axis=1)         # (8, 6)
    Q = Q + two_pi_k[k][:, None, :]
    within = reach & np.all((Q >= lo - 1e-12) & (Q <= hi + 1e-12), axis=2)
    Q[~reach] = np.nan
    return Q, reach, within


class BranchStats(NamedTuple):
    """Per closed-form branch of one pass, over its poses inside the limits (`within`).

    n_ok: (8,) int, poses inside the limits. wrist_sin: (8,) smallest |sin q5| (1 for arms
    without a wrist joint; −inf when n_ok = 0). jump: (8,) largest joint step [rad] between
    consecutive poses inside the limits (0 for one pose; inf when n_ok = 0). margin: (8,)
    worst-case margin [rad]: min(joint-limit margin, asin(wrist_sin)) (−inf when n_ok = 0).
    feasible: (8,) every pose inside, wrist_sin ≥ wrist_sin_min, jump ≤ max_joint_jump_rad·scale.
    """

    n_ok: np.ndarray
    wrist_sin: np.ndarray
    jump: np.ndarray
    margin: np.ndarray
    feasible: np.ndarray


def branch_feasibility(robot: Robot, Q: np.ndarray, within: np.ndarray, settings: IKSettings,
                       jump_scale: float = 1.0) -> BranchStats:
    """Feasibility and margins of every branch at once, from `opw_branches` output Q (B, M, n)
    [rad] (NaN where unreachable) and within (B, M). jump_scale: the path is subsampled by this
    factor, so the joint-jump threshold grows by it. Used by `choose_branch` and
    `paintcell.robots.placement.path_margin`."""
    B, M = within.shape
    n_ok = within.sum(axis=1)
    empty = n_ok == 0
    wi = robot.wrist_joint_index
    if wi is not None:
        wsin = np.where(within, np.abs(np.sin(np.where(within, Q[:, :, wi], 0.0))), np.inf)
        wrist_sin = wsin.min(axis=1)
    else:
        wrist_sin = np.ones(B)
    Qw = np.where(within[:, :, None], Q, 0.0)
    lim = np.where(within, np.minimum(Qw - robot.q_lower, robot.q_upper - Qw).min(axis=2), np.inf)
    margin = np.minimum(lim.min(axis=1), np.arcsin(np.minimum(wrist_sin, 1.0)))
    # Step from the previous pose inside the limits (poses outside are skipped, not joined).
    last = np.maximum.accumulate(np.where(within, np.arange(M), -1), axis=1)
    prev = np.concatenate([np.full((B, 1), -1), last[:, :-1]], axis=1)
    Qp = np.take_along_axis(Qw, np.maximum(prev, 0)[:, :, None], axis=1)
    step = np.abs(Qw - Qp).max(axis=2)
    jump = np.where(within & (prev >= 0), step, 0.0).max(axis=1)
    wrist_sin = np.where(empty, -np.inf, wrist_sin)
    jump = np.where(empty, np.inf, jump)
    margin = np.where(empty, -np.inf, margin)
    feasible = ((n_ok == M) & (wrist_sin >= settings.wrist_sin_min)
                & (jump <= settings.max_joint_jump_rad * jump_scale))
    return BranchStats(n_ok, wrist_sin, jump, margin, feasible)


def choose_branch(robot: Robot, Q: np.ndarray, within: np.ndarray,
                  q_seed: npt.ArrayLike | None, settings: IKSettings) -> int:
    """The branch (0..7) for a whole pass, from `opw_branches` output.

    Feasible (`branch_feasibility`): every pose inside the limits, |sin q5| ≥ wrist_sin_min, no
    jump > max_joint_jump_rad. Among feasible branches, those with a worst-case margin (joint
    limit [rad] or asin|sin q5|) of at least `comfort_margin_rad` come first; then the one closest
    to q_seed (time at full speed) when given, else the largest margin. If none is feasible: most
    poses inside the limits, then the largest wrist margin, then the smallest jump.
    """
    st = branch_feasibility(robot, Q, within, settings)
    B = len(st.n_ok)
    if q_seed is not None:
        first = Q[np.arange(B), np.argmax(within, axis=1)]
        pref = -np.max(np.abs(first - np.asarray(q_seed)) / robot.v_max, axis=1)
        pref = np.where(st.n_ok == 0, -np.inf, pref)
    else:
        pref = st.margin
    feas = [b for b in range(B) if st.feasible[b]]
    comfy = [b for b in feas if st.margin[b] >= settings.comfort_margin_rad]
    if comfy or feas:
        return max(comfy or feas, key=lambda b: pref[b])
    w_cap = settings.wrist_sin_min
    return max(range(B), key=lambda b: (st.n_ok[b], min(st.wrist_sin[b], w_cap), -st.jump[b],
                                        pref[b]))


# --- paths ------------------------------------------------------------------------------------
def _check_path(robot: Robot, T_world_tcp: npt.ArrayLike) -> np.ndarray:
    T = np.asarray(T_world_tcp, float)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) == 0:
        raise RobotError(f"{robot.name}: a path must be a non-empty finite (M, 4, 4) array of "
                         f"T_world_tcp poses, got shape {T.shape}")
    # A scaled or sheared pose is no TCP pose: reject it rather than report it unreachable.
    return check_poses(T, f"{robot.name}: T_world_tcp", error=RobotError)


def solve_path(robot: Robot, T_world_tcp: npt.ArrayLike, q_seed: npt.ArrayLike | None = None,
               free_spin: bool = False, settings: IKSettings | None = None) -> IKPathResult:
    """Joint path (M, n) [rad] for the TCP poses T_world_tcp (M, 4, 4) of one pass.

    q_seed: (n,) joint angles [rad] to stay close to (e.g. the end of the previous pass).
    free_spin: constrain only the spray axis (TCP z), not the rotation about it.
    Unreachable poses get a best-effort q and are flagged in `result.reachability`.
    """
    s = settings or IKSettings()
    T = _check_path(robot, T_world_tcp)
    if q_seed is not None:
        q_seed = robot.check_q(q_seed)
    M, n = len(T), robot.nq
    q = np.empty((M, n))
    branch = -1
    if robot.has_closed_form:
        ref = q_seed if q_seed is not None else robot.q_home
        Qc, _, within = opw_branches(robot, T, ref)
        branch = choose_branch(robot, Qc, within, q_seed, s)
        Qb, ok = Qc[branch], within[branch]
        q_prev = Qb[int(np.argmax(ok))] if ok.any() else np.asarray(ref, float)
        for i in range(M):
            if ok[i] and not free_spin:
                qi, conv = dls(robot, T[i], Qb[i], max_iters=s.warm_iters, settings=s)
            else:
                start = Qb[i] if (ok[i] and i == 0) else q_prev
                qi, conv = dls(robot, T[i], start, free_spin=free_spin,
                               max_iters=s.warm_iters, settings=s)
                if not conv and ok[i]:
                    qi, conv = dls(robot, T[i], Qb[i], free_spin=free_spin,
                                   max_iters=s.warm_iters, settings=s)
            q[i] = q_prev = qi
        method = "opw+dls" if robot.opw is not None else "closed-form+dls"
    else:
        q_prev, _ = cold_start(robot, T[0], q_seed, free_spin=free_spin, settings=s)
        q[0] = q_prev
        for i in range(1, M):
            q_prev, _ = dls(robot, T[i], q_prev, free_spin=free_spin, max_iters=s.warm_iters,
                            settings=s)
            q[i] = q_prev
        method = "dls"
    report = ReachabilityReport.measure(robot, q, T, free_spin=free_spin,
                                        thresholds=s.thresholds())
    return IKPathResult(q=q, reachability=report, branch=branch, method=method)


def combined_report(results: list[IKPathResult]) -> ReachabilityReport:
    """One report over the passes of `solve_paths` (pass k = results[k])."""
    return ReachabilityReport.concatenate([r.reachability for r in results])
