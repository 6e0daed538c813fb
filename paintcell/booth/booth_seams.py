"""Seams between the body's parts blended (`paintcell.booth.booth_programs` applies it after the
film build).

Each part is planned on its own, so its edge passes and overspray paint whatever lies next to it
on the body: a neighbouring part's edge (the door's top edge next to the roof, the fender next to
the door). Where two parts meet, both sides' edge tails would paint the seam twice. The parts'
passes are blended across the body the way `paintcell.coverage.patches` blends the seams
between patches
of one part: a brush-on sample whose paint lands on other parts more than `share` × on its own
part is switched off (`paintcell.coverage.patches.seam_volumes`, `ownership_brush_off`, on
the merged body surface in the body frame, each part at its own flow), and the share is the one of
`paintcell.coverage.patches.SEAM_SHARES` whose film over the whole body has the smallest
σ/μ (1.0 when
nothing is switched off at any share). Only paint switches: the passes' geometry and timing, so
the robots' programs' motion, are unchanged.

`seam_band` marks the body's vertices near another part (the seams' film, measured apart from
each part's interior by `paintcell.booth.booth_part_film`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from paintcell.booth.booth_film import plan_gun_in_body
from paintcell.coverage.patches import SEAM_SHARES, ownership_brush_off, seam_volumes
from paintcell.coverage.plan import CoveragePlan, PassPlan
from paintcell.paint.deposition import thickness
from paintcell.paint.metrics import uniformity
from paintcell.surface.surface_data import Surface

#: a vertex is in a seam band when another part's nearest vertex lies within this [m]: about a
#: bell footprint's half-width, the reach of the neighbour's edge passes and overspray.
SEAM_BAND_M = 0.10


def seam_band(vertices_m: np.ndarray, part_counts: list[int], band_m: float = SEAM_BAND_M
              ) -> np.ndarray:
    """(N,) bool over the merged body's vertices (N, 3) [m], parts stacked in order,
    `part_counts` vertices each: True where another part's nearest vertex is within band_m [m]
    (straight-line distance)."""
    v = np.asarray(vertices_m, float)
    offs = np.cumsum([0, *part_counts])
    out = np.zeros(len(v), bool)
    for k in range(len(part_counts)):                          # a few parts
        own = np.zeros(len(v), bool)
        own[offs[k]:offs[k + 1]] = True
        if own.all() or not own.any():
            continue
        d, _ = cKDTree(v[~own]).query(v[own], k=1, distance_upper_bound=band_m)
        out[offs[k]:offs[k + 1]] = d <= band_m
    return out


def pass_in_body(p: PassPlan, T_body_part: np.ndarray) -> PassPlan:
    """A pass moved from its part frame into the body frame by the (4, 4) placement."""
    R, t = T_body_part[:3, :3], T_body_part[:3, 3]
    return dataclasses.replace(p, positions=p.positions @ R.T + t,
                               spray_axes=p.spray_axes @ R.T, travel_dirs=p.travel_dirs @ R.T)


def blend_part_seams(body: Surface, plans: list[CoveragePlan], T_body_parts: list[np.ndarray],
                     part_counts: list[int], names: list[str],
                     judged: np.ndarray | None = None
                     ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """The plans with the samples that paint other parts more than their own switched off
    (module doc), and a record {rule, share, nsd by share, samples switched off per part}.

    body: the parts' surfaces merged in the body frame
    (`paintcell.booth.booth_film.merge_surfaces`, parts
    stacked in order, part_counts vertices each); plans: per part, in its part frame;
    judged: (N,) bool, the body's vertices the film is judged on
    (`paintcell.booth.booth_film.judged_body_mask`; None: every vertex).
    """
    offs = np.cumsum([0, *part_counts])
    vols = []
    for k, (plan, T) in enumerate(zip(plans, T_body_parts, strict=True)):   # a few parts
        own = np.zeros(len(body.vertices), bool)
        own[offs[k]:offs[k + 1]] = True
        moved = [pass_in_body(p, T) for p in plan.passes]
        vols.append(seam_volumes(plan.applicator, moved, own, body))

    def blended(share: float) -> tuple[list[CoveragePlan], list[int]]:
        out, n = [], []
        for plan, v in zip(plans, vols, strict=True):
            passes, n_off = ownership_brush_off(list(plan.passes), v, share)
            out.append(dataclasses.replace(plan, passes=tuple(passes)))
            n.append(n_off)
        return out, n

    def body_nsd(ps: list[CoveragePlan]) -> float:
        film = sum(thickness(p.applicator, plan_gun_in_body(p, T), body.vertices, body.normals)
                   for p, T in zip(ps, T_body_parts, strict=True))
        return float(uniformity(np.asarray(film), body.vertex_areas, mask=judged).nsd_pct)

    unblended = body_nsd(plans)
    tried: dict[str, float] = {}
    best, best_nsd = 1.0, np.inf
    seen: dict[tuple[int, ...], float] = {}
    for share in SEAM_SHARES:                 # nine shares; equal switch-offs reuse the film
        cand, n = blended(share)
        key = tuple(n)
        if key not in seen:
            seen[key] = body_nsd(cand) if sum(n) else unblended
        tried[f"{share:g}"] = seen[key]
        if seen[key] < best_nsd - 1e-12:
            best, best_nsd = share, seen[key]
    out, n = blended(best)
    if best_nsd >= unblended:                 # blending does not help: keep the plans as planned
        out, n, best_s, best_nsd = list(plans), [0] * len(plans), None, unblended
    else:
        best_s = best
    return out, {"rule": "samples painting other parts more than share × their own switched off; "
                         "share: the smallest whole-body σ/μ",
                 "share": best_s, "body_planned_nsd_pct": best_nsd,
                 "unblended_planned_nsd_pct": unblended, "nsd_by_share_pct": tried,
                 "samples_switched_off": dict(zip(names, n, strict=True))}
