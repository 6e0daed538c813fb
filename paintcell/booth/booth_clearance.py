"""How close each robot's program comes to the WHOLE body, every part of it (not only the part
the robot paints): a kinematic sweep of the program in MuJoCo before anything executes.

A robot painting the fender can hit the door beside it: its wrist over the fender's edge, or the
joint-space retract from the last pass back home sweeping across the neighbour. The booth's
allocation (`paintcell.booth.booth_programs`) measures every candidate program here, against
the merged body at its nominal placement, with MuJoCo's own distance (`mujoco.mj_geomDistance`)
between the same collision geoms the execution uses (the robot's capsules and the body's convex
slabs of `paintcell.execution.cell_part`). A rail robot's carriage position for each pass
is chosen with a penalty where its arm comes within `PLACEMENT_MARGIN_M` of the body
(`rail_penalty`, `paintcell.robots.rail.best_rail_position`). A program still closer than the
booth's `body_clearance_m` to the body is built again — approach and retract folded (the
shoulder and elbow pulled back before the wrist turns), its home on the passes' wrist branch
(`wrist_flipped_home`: the same pose, no wrist flip next to the body), farther back-offs
(`clear_settings`) — and, if it still comes too close, its allocation is rejected with the
robot, the parts and the time named.

Rail robots track the conveyor with their carriage (`paintcell.booth.conveyor`), so their
programs keep their geometry relative to the body exactly and the static sweep is the executed
one. A fixed-base robot's tracked program differs from its static one by the IK on the moving
target; MuJoCo's execution still counts its contacts.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import mujoco
import numpy as np

from paintcell.surface.surface_data import Surface

#: sampling of the sweep [s] (the bell moves ≤ 1.5 m/s: ≤ 15 mm between checks).
SWEEP_DT_S = 0.01
#: clearance ladder of `clear_settings`: factors on the approach / retract / turn-around back-offs.
CLEAR_FACTORS = (2.0, 3.0)
#: rail placement (`paintcell.robots.rail.best_rail_position`): clearance wanted between the arm
#: along a pass and the body [m], and the weight of its penalty (a touching arm costs ≥ this;
#: the comfort costs of a feasible rail position are ≲ 1, an infeasible one 1e3).
PLACEMENT_MARGIN_M = 0.15
PLACEMENT_WEIGHT = 10.0
#: poses of a pass the placement measures (its ends and evenly between).
PLACEMENT_POSES = 12


@dataclass(frozen=True)
class Clearance:
    """One program's clearance to the body.

    min_distance_m: the smallest signed distance [m] between any robot collision geom and any
    part of the body (negative: penetration; `margin_m` when nothing came closer).
    n_close: sampled instants closer than the margin. first_t_s: the first such instant [s]
    (None: none). bodies: the robot bodies that came close, closest first. parts: the body's parts
    (their index in `Booth.parts`) that were approached.
    """

    min_distance_m: float
    n_close: int
    first_t_s: float | None
    bodies: tuple[str, ...]
    parts: tuple[int, ...]

    @property
    def clear(self) -> bool:
        """Nothing came closer than the margin."""
        return self.n_close == 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe."""
        return {"min_distance_m": self.min_distance_m, "n_close": self.n_close,
                "first_t_s": self.first_t_s, "bodies": list(self.bodies),
                "parts": list(self.parts)}


class BodyProbe:
    """A one-robot MuJoCo model of the whole body (static, at its nominal placement) that
    measures a robot's poses and programs against it.

    robot: a `paintcell.robots.Robot` at its base (a rail robot: its rail frame); body: the merged
    body surface (body frame); T_world_body: (4, 4); part_of_vertex: (V,) index of the part of
    each body vertex.
    """

    def __init__(self, robot: Any, body: Surface, T_world_body: np.ndarray,
                 part_of_vertex: np.ndarray) -> None:
        from scipy.spatial import cKDTree

        from paintcell.booth.booth_cell import build_booth_cell

        self.bcell = build_booth_cell([robot], body, T_world_body, conveyor=None, booth=False)
        m = self.bcell.cell.model
        # the body's collision slabs (not its visual mesh, whose convex hull spans all parts)
        self._part_geoms = np.flatnonzero((m.geom_bodyid == self.bcell.cell.part_body_id)
                                          & ((m.geom_contype | m.geom_conaffinity) != 0))
        robot = np.zeros(m.nbody, bool)
        robot[self.bcell.body_ids[0]] = True
        self._robot_geoms = np.flatnonzero(robot[m.geom_bodyid]
                                           & ((m.geom_contype | m.geom_conaffinity) != 0))
        self._adr = self.bcell.cell.qpos_adr[self.bcell.columns[0]]
        self._data = mujoco.MjData(m)
        # Which part each collision slab belongs to: the part of the body vertex nearest its
        # centre (a slab is cut from one part's faces).
        T_bw = np.linalg.inv(np.asarray(T_world_body, float))
        mujoco.mj_kinematics(m, self._data)
        centres = self._data.geom_xpos[self._part_geoms] @ T_bw[:3, :3].T + T_bw[:3, 3]
        _, nearest = cKDTree(body.vertices).query(centres)
        self._geom_part = np.full(m.ngeom, -1)
        self._geom_part[self._part_geoms] = np.asarray(part_of_vertex)[nearest]
        # The body is static: its slabs' centres in a k-d tree find the few near each robot geom.
        self._part_tree = cKDTree(self._data.geom_xpos[self._part_geoms])
        self._part_rbound = m.geom_rbound[self._part_geoms]

    def _close(self, q: np.ndarray, margin_m: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot–body geom pairs closer than margin_m at joint values q (n,): their distances
        [m] (negative: penetration), robot body ids and part indices. Pairs whose bounding
        spheres are farther apart than the margin are skipped; the rest are measured by
        `mujoco.mj_geomDistance`."""
        m, d = self.bcell.cell.model, self._data
        d.qpos[self._adr] = q
        mujoco.mj_kinematics(m, d)
        rg, pg = self._robot_geoms, self._part_geoms
        gap = (np.linalg.norm(d.geom_xpos[rg][:, None] - d.geom_xpos[pg][None], axis=2)
               - m.geom_rbound[rg][:, None] - self._part_rbound[None])
        ii, jj = np.nonzero(gap < margin_m)
        dist = np.array([mujoco.mj_geomDistance(m, d, int(rg[i]), int(pg[j]), margin_m, None)
                         for i, j in zip(ii.tolist(), jj.tolist(), strict=True)])
        hit = dist < margin_m if len(dist) else np.zeros(0, bool)
        return (dist[hit], m.geom_bodyid[rg[ii[hit]]],
                self._geom_part[pg[jj[hit]]])

    def _maybe_close(self, q: np.ndarray, margin_m: float) -> np.ndarray:
        """(K,) whether some robot geom of the joint samples q (K, n) may come within margin_m
        of the body: its bounding sphere within the margin of the nearest slab centre's sphere
        of the largest slab (a lower bound of the distance; False: certainly farther)."""
        m, d = self.bcell.cell.model, self._data
        rg = self._robot_geoms
        pos = np.empty((len(q), len(rg), 3))
        for k, qk in enumerate(q):
            d.qpos[self._adr] = qk
            mujoco.mj_kinematics(m, d)
            pos[k] = d.geom_xpos[rg]
        nearest, _ = self._part_tree.query(pos.reshape(-1, 3))
        low = nearest.reshape(len(q), len(rg)) - m.geom_rbound[rg] - self._part_rbound.max()
        return np.asarray((low < margin_m).any(axis=1))

    def distance(self, q: np.ndarray, margin_m: float) -> float:
        """Smallest robot–body distance [m] over the joint samples q (K, n) (margin_m when
        nothing comes closer; negative: penetration)."""
        best = margin_m
        for qk in q[self._maybe_close(q, margin_m)]:
            dist = self._close(qk, margin_m)[0]
            if len(dist):
                best = min(best, float(dist.min()))
        return best

    def rail_penalty(self, margin_m: float, weight: float) -> Any:
        """`paintcell.robots.rail.RailPenalty` for this (rail) robot: weight·((margin − d) /
        margin)² where the arm along the pass comes within margin_m [m] of the body (d: its
        smallest distance; 0 farther)."""
        def penalty(s_m: float, Q: np.ndarray) -> float:
            Q = Q[np.unique(np.linspace(0, len(Q) - 1, PLACEMENT_POSES).astype(int))]
            q = np.column_stack([np.full(len(Q), s_m), Q])
            d = self.distance(q, margin_m)
            return weight * ((margin_m - d) / margin_m) ** 2 if d < margin_m else 0.0
        return penalty

    def clearance(self, q: np.ndarray, t_s: np.ndarray, margin_m: float) -> Clearance:
        """Clearance of the joint samples q (K, n) at times t_s (K,) [s], checked every
        SWEEP_DT_S, against margin_m [m]."""
        m = self.bcell.cell.model
        step = max(1, int(round(SWEEP_DT_S / max(float(t_s[1] - t_s[0]), 1e-9)))) \
            if len(t_s) > 1 else 1
        idx = np.unique(np.r_[np.arange(0, len(q), step), len(q) - 1])
        idx = idx[self._maybe_close(q[idx], margin_m)]
        best, n_close, first = margin_m, 0, None
        close_bodies: dict[str, float] = {}
        parts: set[int] = set()
        for k in idx:
            dist, rb, gp = self._close(q[k], margin_m)
            if not len(dist):
                continue
            n_close += 1
            first = float(t_s[k]) if first is None else first
            best = min(best, float(dist.min()))
            for dk, bk, pk in zip(dist.tolist(), rb.tolist(), gp.tolist(), strict=True):
                name = m.body(int(bk)).name.split("/", 1)[-1]
                close_bodies[name] = min(close_bodies.get(name, np.inf), dk)
                parts.add(int(pk))
        names = tuple(sorted(close_bodies, key=lambda n: close_bodies[n]))
        return Clearance(best, n_close, first, names, tuple(sorted(parts)))


def clear_settings(settings: Any, factor: float) -> Any:
    """`TrajectorySettings` with the approach, retract and turn-around back-offs scaled by
    `factor` and turn-arounds always backed off (`turnaround_max_dip_m` 0): the moves between
    passes and to and from home keep farther from the body."""
    return replace(settings, approach_clearance_m=factor * max(settings.approach_clearance_m, 0.1),
                   retract_clearance_m=factor * max(settings.retract_clearance_m, 0.1),
                   turnaround_clearance_m=factor * settings.turnaround_clearance_m,
                   turnaround_max_dip_m=0.0)


def wrist_flipped_home(robot: Any, q_home: np.ndarray, q_near: np.ndarray) -> np.ndarray | None:
    """The same home pose on the other wrist branch — (q4 ± π, −q5, q6 ± π), the signs that
    land inside the limits closest to q_near (n,) [rad] — when q_near lies on that branch (its
    q5 of the other sign); None otherwise or when no such home is inside the limits.

    An approach or retract between a home on one wrist branch and passes on the other turns the
    wrist through its singularity, swinging the bell through 180° next to the body."""
    wi = getattr(robot, "wrist_joint_index", None)
    if wi is None or np.sign(q_home[wi]) == np.sign(q_near[wi]):
        return None
    best = None
    for a in (-np.pi, np.pi):
        for b in (-np.pi, np.pi):
            h = np.array(q_home, float)
            h[wi - 1] += a
            h[wi] = -h[wi]
            h[wi + 1] += b
            if np.all(h >= robot.q_lower) and np.all(h <= robot.q_upper):
                d = float(np.abs(h - q_near)[wi - 1:wi + 2].sum())
                best = (d, h) if best is None or d < best[0] else best
    if best is None:
        return None
    same = np.allclose(robot.fk(best[1]), robot.fk(np.asarray(q_home, float)), atol=1e-9)
    return best[1] if same else None
