"""Film on the regions that are not judged: hems, flanges and turned edges, reported apart.

Painters check the hem and flange film on their own: it is not part of the skin's uniformity
(the metrics are judged on the skin) but too little there is a corrosion risk and too much a run.
For a real part with regions (`paintcell.surface.regions.PartRegions`), each non-judged
region that has
area gets its planned and executed mean film [µm], its executed σ/μ [%] and its executed mean
relative to the judged skin's [%].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.paint.metrics import uniformity
from paintcell.surface.surface_data import Surface

#: regions reported apart (paintcell.surface.regions.REGION_NAMES minus the skin and
#: the dropped back side).
REPORTED = ("hem", "edge", "inner")


def region_film(surface: Surface, planned_m: np.ndarray, executed_m: np.ndarray,
                judged_mean_m: float) -> dict[str, Any]:
    """Metrics of the non-judged regions (keys `{region}_…`); empty without regions.

    planned_m / executed_m: (N,) film per vertex [m]; judged_mean_m: executed mean film on the
    judged regions [m]."""
    regs = surface.regions
    if regs is None:
        return {}
    out: dict[str, Any] = {}
    V, F = surface.vertices, surface.faces
    tri = V[F]
    face_area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                      axis=1)
    for name in REPORTED:
        fm = regs.face_mask((name,))
        if name in regs.judged or not fm.any():
            continue
        # the region's own area per vertex (a third of each of its faces): exact for linear films
        areas = np.bincount(F[fm].ravel(), weights=np.repeat(face_area[fm] / 3.0, 3),
                            minlength=len(V))
        m = areas > 0
        if not m.any():
            continue
        u_e = uniformity(executed_m, areas, mask=m)
        u_p = uniformity(planned_m, areas, mask=m)
        out[f"{name}_planned_mean_um"] = 1e6 * u_p.mean_m
        out[f"{name}_executed_mean_um"] = 1e6 * u_e.mean_m
        out[f"{name}_executed_nsd_pct"] = u_e.nsd_pct
        out[f"{name}_executed_vs_skin_pct"] = (100.0 * u_e.mean_m / judged_mean_m
                                              if judged_mean_m > 0 else float("nan"))
    return out
