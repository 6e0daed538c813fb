"""`ExecutedTrace`: what the simulated robot actually did, sampled at every MuJoCo step."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_write_npz
from paintcell.core.errors import PaintcellError
from paintcell.paint.deposition_samples import GunSamples


class TraceError(PaintcellError):
    """An executed trace cannot be loaded or is inconsistent."""


@dataclass(frozen=True)
class Contact:
    """One contact of the robot with the part, the booth or itself during execution.

    time_s: simulation time [s]; body1/body2: MuJoCo body names; depth_m: penetration [m] (> 0).
    """

    time_s: float
    body1: str
    body2: str
    depth_m: float


@dataclass(frozen=True, eq=False)
class ExecutedTrace:
    """The executed program, world frame.

    t_s: (K,) time [s]; q, qd: (K, n) joint positions [rad] and velocities [rad/s];
    tau: (K, n) applied joint torques [N·m]; tcp_pos_world: (K, 3) TCP site position [m];
    tcp_rot_world: (K, 3, 3) TCP site orientation; paint_on: (K,) brush; pass_index: (K,);
    mode: "kinematic" (ideal replay) or "servo"; contacts: every robot contact with the part,
    the booth or itself (also during the settling hold after the program: times past t_s[-1]);
    tau_demand: (K, n) joint torques the controller demanded before the actuator limits clamped
    them [N·m] (kinematic replay: the inverse dynamics of the reference); None in traces written
    before it was recorded. |tau_demand| > τ_max where the actuator saturated.
    flow: (K,) the bell flow the bell really followed ÷ its part's flow [-] (the program's
    brush table, `JointTrajectory.flow`, shifted with the trigger); None: 1 everywhere.
    """

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    tcp_pos_world: np.ndarray
    tcp_rot_world: np.ndarray
    paint_on: np.ndarray
    pass_index: np.ndarray
    mode: str
    contacts: tuple[Contact, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)
    tau_demand: np.ndarray | None = None
    flow: np.ndarray | None = None

    _ARRAYS = ("t_s", "q", "qd", "tau", "tcp_pos_world", "tcp_rot_world", "paint_on", "pass_index")
    #: arrays that may be None (absent from older files).
    _OPTIONAL_ARRAYS = ("tau_demand", "flow")

    def gun_samples(self, T_part_world: np.ndarray | None = None) -> GunSamples:
        """Paint-on samples as `GunSamples` in the part frame (dwell = step time, times the
        commanded flow `flow` and the flow factor of a flow disturbance recorded in `meta`).

        T_part_world: (4, 4) transform from world to part coordinates (identity if None).
        Spray axis = site z, travel = site x, as the TCP convention says.
        """
        T = np.eye(4) if T_part_world is None else np.asarray(T_part_world, float)
        on = self.paint_on.astype(bool)
        dt = np.gradient(self.t_s)[on]
        if self.flow is not None:
            dt = dt * np.asarray(self.flow, float)[on]
        # a flow disturbance (meta flow_scale, flow_drift) scales the film rate, i.e. the dwell
        scale, drift = float(self.meta.get("flow_scale", 1.0)), float(self.meta.get("flow_drift",
                                                                                   0.0))
        if scale != 1.0 or drift != 0.0:
            span = max(float(self.t_s[-1] - self.t_s[0]), 1e-12)
            dt = dt * scale * (1.0 + drift * (self.t_s[on] - self.t_s[0]) / span)
        R = T[:3, :3]
        pos = self.tcp_pos_world[on] @ R.T + T[:3, 3]
        z = self.tcp_rot_world[on][:, :, 2] @ R.T
        x = self.tcp_rot_world[on][:, :, 0] @ R.T
        return GunSamples(positions=pos, spray_axes=z, travel_dirs=x, dwell_s=dt)

    def save_npz(self, path: str | Path) -> None:
        """Write arrays, contacts and metadata to one `.npz` atomically."""
        arrays = {name: getattr(self, name) for name in self._ARRAYS}
        arrays.update({name: getattr(self, name) for name in self._OPTIONAL_ARRAYS
                       if getattr(self, name) is not None})
        arrays["_json"] = np.array(json.dumps({
            "format": "paintcell.ExecutedTrace/1", "mode": self.mode, "meta": self.meta,
            "contacts": [vars(c) for c in self.contacts]}))
        atomic_write_npz(path, arrays)

    @classmethod
    def load_npz(cls, path: str | Path) -> ExecutedTrace:
        """Read a trace written by `save_npz`."""
        path = Path(path)
        if not path.exists():
            raise TraceError(f"trace file {path} does not exist; run the execution stage first")
        with np.load(path) as z:
            meta = json.loads(str(z["_json"]))
            if meta.get("format") != "paintcell.ExecutedTrace/1":
                raise TraceError(f"{path} is not a paintcell executed trace")
            arrays = {name: z[name] for name in cls._ARRAYS}
            arrays.update({name: z[name] for name in cls._OPTIONAL_ARRAYS if name in z.files})
        return cls(**arrays, mode=meta["mode"], meta=meta["meta"],
                   contacts=tuple(Contact(**c) for c in meta["contacts"]))
