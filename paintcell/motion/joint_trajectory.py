"""`JointTrajectory`: one continuous robot program sampled at the control rate.

Produced by `paintcell.motion.trajectory` (TOPP-RA paint passes + ruckig moves between
them) and consumed by `paintcell.execution.execute` (MuJoCo) and
`paintcell.output.export_rapid` (RAPID). World frame, SI units.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_path, atomic_write_npz
from paintcell.core.errors import PaintcellError

# Segment kinds of each sample (the `segment` array).
APPROACH, PAINT, TURNAROUND, RETRACT = 0, 1, 2, 3


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges [a, b) of the True runs of a boolean array (brush on, slowed)."""
    d = np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


class TrajectoryError(PaintcellError):
    """A joint trajectory cannot be built, loaded or is inconsistent."""


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """A robot program sampled at a fixed rate.

    t_s: (K,) sample times [s], uniform step `dt_s`, starting at 0.
    q, qd, qdd: (K, n) joint positions [rad], velocities [rad/s], accelerations [rad/s²].
    tcp_pos_world: (K, 3) TCP position from forward kinematics [m].
    tcp_rot_world: (K, 3, 3) TCP orientation (columns: travel x, y, spray z).
    v_tcp_planned: (K,) planned TCP speed from the coverage plan [m/s] (0 off the passes).
    paint_on: (K,) brush on.
    pass_index: (K,) index of the plan pass being painted, -1 between passes.
    segment: (K,) segment kind (APPROACH, PAINT, TURNAROUND, RETRACT).
    s_pass_m: (K,) TCP arc length along the current pass [m] (nan off the passes).
    robot_name, joint_names: which robot and joint order.
    slowdowns: where a joint limit made the TCP slower than planned: dicts with pass, s_start_m,
        s_end_m, t_start_s, duration_s, max_speed_deficit_pct, limiting (joint/limit names).
    pass_summary: per pass: planned vs time-parameterized duration, speed-following error.
    flow: (K,) the bell flow the program commands ÷ its part's flow [-] (the brush table's
        level): below 1 where the time law is slower than the plan, so the film keeps the plan's
        build (`paintcell.motion.flow`); 1 off the passes and where the plan is met. Left out:
        1 everywhere (a program at constant flow).
    """

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tcp_pos_world: np.ndarray
    tcp_rot_world: np.ndarray
    v_tcp_planned: np.ndarray
    paint_on: np.ndarray
    pass_index: np.ndarray
    segment: np.ndarray
    s_pass_m: np.ndarray
    robot_name: str
    joint_names: tuple[str, ...]
    slowdowns: tuple[dict[str, Any], ...] = ()
    pass_summary: tuple[dict[str, Any], ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)
    flow: np.ndarray = field(default_factory=lambda: np.ones(0))

    _ARRAYS = ("t_s", "q", "qd", "qdd", "tcp_pos_world", "tcp_rot_world", "v_tcp_planned",
               "paint_on", "pass_index", "segment", "s_pass_m", "flow")

    def __post_init__(self) -> None:
        k = len(self.t_s)
        flow = np.asarray(self.flow, float)
        flow = np.ones(k) if len(flow) == 0 else flow
        if not np.all(np.isfinite(flow)) or np.any(flow <= 0) or np.any(flow > 1 + 1e-12):
            raise TrajectoryError("trajectory flow must be in (0, 1] (the commanded bell flow ÷ "
                                  "the part's flow)")
        object.__setattr__(self, "flow", flow)
        for name in self._ARRAYS:
            if len(getattr(self, name)) != k:
                raise TrajectoryError(f"trajectory array {name} has {len(getattr(self, name))} "
                                      f"rows, expected {k}")

    @property
    def dt_s(self) -> float:
        """Sample period [s]."""
        return float(self.t_s[1] - self.t_s[0])

    @property
    def duration_s(self) -> float:
        """Cycle time of the whole program [s]."""
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def paint_time_s(self) -> float:
        """Time with the brush on [s]."""
        return float(np.count_nonzero(self.paint_on) * self.dt_s)

    def save_npz(self, path: str | Path) -> None:
        """Write all arrays and metadata to one `.npz` atomically."""
        arrays = {name: getattr(self, name) for name in self._ARRAYS}
        arrays["_json"] = np.array(json.dumps({
            "format": "paintcell.JointTrajectory/1",
            "robot_name": self.robot_name,
            "joint_names": list(self.joint_names),
            "slowdowns": list(self.slowdowns),
            "pass_summary": list(self.pass_summary),
            "meta": self.meta,
        }))
        atomic_write_npz(path, arrays)

    @classmethod
    def load_npz(cls, path: str | Path) -> JointTrajectory:
        """Read a trajectory written by `save_npz`."""
        path = Path(path)
        if not path.exists():
            raise TrajectoryError(f"trajectory file {path} does not exist; run the trajectory "
                                  "stage first (`paintcell run`)")
        with np.load(path) as z:
            meta = json.loads(str(z["_json"]))
            if meta.get("format") != "paintcell.JointTrajectory/1":
                raise TrajectoryError(f"{path} is not a paintcell joint trajectory")
            # the flow is optional (programs written at constant flow); every other array is not
            arrays = {name: z[name] for name in cls._ARRAYS
                      if name in z.files or name != "flow"}
        return cls(**arrays, robot_name=meta["robot_name"],
                   joint_names=tuple(meta["joint_names"]),
                   slowdowns=tuple(meta["slowdowns"]), pass_summary=tuple(meta["pass_summary"]),
                   meta=meta["meta"])

    def save_csv(self, path: str | Path) -> None:
        """Write a CSV (one row per sample: t, q, qd, TCP xyz, planned speed, paint, pass,
        segment, commanded flow ÷ the part's)."""
        n = self.q.shape[1]
        header = (["t_s"] + [f"q{i + 1}_rad" for i in range(n)]
                  + [f"qd{i + 1}_rad_s" for i in range(n)]
                  + ["tcp_x_m", "tcp_y_m", "tcp_z_m", "v_planned_m_s", "paint_on", "pass_index",
                     "segment", "flow"])
        data = np.column_stack([self.t_s, self.q, self.qd, self.tcp_pos_world, self.v_tcp_planned,
                                self.paint_on.astype(int), self.pass_index, self.segment,
                                self.flow])
        fmt = ["%.4f"] + ["%.7f"] * (2 * n) + ["%.6f"] * 3 + ["%.5f", "%d", "%d", "%d", "%.2f"]
        with atomic_path(path) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)
