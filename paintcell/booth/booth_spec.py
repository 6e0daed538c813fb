"""A booth's parts against its paint spec (`Booth.spec`, `paintcell.validation.paint_spec`).

The window is centred on the spec's `target_film_um`, else the booth's `film_target_um`, else
the whole body's planned mean film over the judged area; the whole body's share of judged area
inside it and each part's are reported, and the worst part's share is what the booth's window
check holds (`paintcell.booth.booth_results`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.booth.booth import Booth
from paintcell.surface.surface_data import Surface
from paintcell.validation.paint_spec import spec_metrics

__all__ = ["booth_spec_metrics"]


def booth_spec_metrics(booth: Booth, body: Surface, tot: dict[str, np.ndarray],
                       areas: np.ndarray,
                       judged_faces: np.ndarray | None, offs: np.ndarray) -> dict[str, Any]:
    """The paint spec's figures: the window around the spec's target (else the booth's
    `film_target_um`, else the body's planned mean over the judged area), the whole body's
    share inside it and each part's (`part_executed_inside_spec_pct`), the worst part's share
    (`min_part_executed_inside_spec_pct`, with its shares below and above).

    tot: the robots' films summed, {"plan", "executed", …} each (N,) [m] on `body`'s vertices;
    areas: (N,) the judged vertices' areas [m²] (0 elsewhere); judged_faces: (F,) bool, the
    faces the shares are measured over (None: all); offs: (P + 1,) the first vertex of each part
    as the body stacks them, then the vertex count."""
    spec = booth.spec
    own = (1e-6 * booth.film_target_um if booth.film_target_um is not None
           else float(tot["plan"] @ areas / areas.sum()))
    target = spec.target_m(own)
    faces = body.faces
    fmask = np.ones(len(faces), bool) if judged_faces is None else np.asarray(judged_faces, bool)
    out: dict[str, Any] = spec_metrics(tot["executed"], body.vertices, faces, fmask, target, spec)
    out.update({"spec_window_pct": spec.window_pct, "spec_min_inside_pct": spec.min_inside_pct,
                "spec_max_nsd_pct": spec.max_nsd_pct})
    per: dict[str, dict[str, float]] = {}
    for i, bp in enumerate(booth.parts):
        own_faces = fmask & (faces[:, 0] >= offs[i]) & (faces[:, 0] < offs[i + 1])
        per[f"{i}:{bp.part}"] = spec_metrics(tot["executed"], body.vertices, faces, own_faces,
                                             target, spec)
    out["part_executed_inside_spec_pct"] = {k: v["executed_inside_spec_pct"]
                                            for k, v in per.items()}
    worst = min(per, key=lambda k: per[k]["executed_inside_spec_pct"])
    for k in ("inside", "below", "above"):
        out[f"min_part_executed_{k}_spec_pct"] = per[worst][f"executed_{k}_spec_pct"]
    out["min_part_executed_inside_spec_part"] = worst
    return out
