"""A tiny sweep case shared by the sweep tests: a 0.4 × 0.3 m flat plate (a mesh file written
into the test's folder), upright in front of the robot, planned at the coarse resolution: a
~10 s program, ~0.4 s a kinematic sample."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
import trimesh

from tests.helpers import LOOSE_SPEC_TABLE

#: the plate scenario as TOML data (the sweep table is appended by `plate_scenario`).
SCENARIO: dict[str, Any] = {
    "name": "plate",
    "part": "plate.stl",
    "fast_resolution_m": 0.05,
    "part_placement": {"xyz_m": [1.4, 0.0, 1.0],
                       "rpy_rad": [1.5707963267948966, 0.0, -1.5707963267948966]},
    "fast_planner": {"sample_spacing_m": 0.05},
    "trajectory": {"q_home": [0.0, -0.6, 0.3, 0.0, 0.9, 0.0]},
    "thresholds": {"max_loss_pp": 1.0, "max_cycle_time_s": 90.0},
    "spec": LOOSE_SPEC_TABLE,
}


def plate_mesh(path: Path, size_m: tuple[float, float] = (0.4, 0.3), n: int = 21) -> None:
    """A flat grid plate in its own xy plane (normals +z), written as STL."""
    nx, ny = n, max(2, int(round(n * size_m[1] / size_m[0])))
    x, y = np.meshgrid(np.linspace(-size_m[0] / 2, size_m[0] / 2, nx),
                       np.linspace(-size_m[1] / 2, size_m[1] / 2, ny), indexing="ij")
    v = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    a = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    b = a + ny
    f = np.r_[np.c_[a, b, a + 1], np.c_[b, b + 1, a + 1]]
    trimesh.Trimesh(v, f, process=False).export(path)


def plate_scenario(folder: Path, sweep: dict[str, Any] | None = None,
                   nsd: float = 30.0) -> Path:
    """Write plate.stl and plate.toml (a scenario with this [sweep] table) into folder."""
    folder.mkdir(parents=True, exist_ok=True)
    plate_mesh(folder / "plate.stl")
    data = {**SCENARIO, "thresholds": {**SCENARIO["thresholds"], "max_executed_nsd_pct": nsd}}
    if sweep:
        data["sweep"] = sweep
    path = folder / "plate.toml"
    path.write_text(tomli_w.dumps(data))
    return path
