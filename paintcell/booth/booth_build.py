"""One film build over the whole body (`paintcell.booth.booth_programs` applies it after
planning the parts).

Each library part is planned on its own: the planner picks its pass spacing from the part's
curvature, so at the same bell flow and nominal speed the parts get different film builds
(18 µm on the roof against 32–38 µm on the door and fender at the default bell) and the body's
σ/μ measures that mismatch more than the robots' work. A paint shop sets the bell's flow per
brush (its brush table) so every zone reaches the specified film build. Here: every part's
applicator flow is scaled by

    k_p = target / μ_p,

μ_p the area-weighted mean of the part's planned film on its own surface, so the planned mean
of every part is the target. The film is linear in the flow (every rate of the ESRB model is
multiplied by k), so the trajectories, the cycle and each part's σ/μ are unchanged; the film and
the paint used scale by k. Robots sharing a part share its flow, so the seam between two pieces
of a split part keeps the plan's own pass overlap.

The target [m] is `Booth.film_target_um` if given, else the body's area-weighted planned mean
(the paint on the body unchanged).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from paintcell.booth.booth import BoothError
from paintcell.coverage.plan import CoveragePlan
from paintcell.paint.deposition import thickness
from paintcell.paint.metrics import uniformity
from paintcell.surface.surface_data import Surface

#: flow factors outside this range are refused (a bell's flow range is about 1:5 either way of
#: its nominal; outside it the atomization and so the spray pattern change).
FLOW_FACTOR_RANGE = (0.2, 5.0)


def planned_mean_m(plan: CoveragePlan, surface: Surface) -> tuple[float, float]:
    """(area-weighted mean [m], area [m²]) of a plan's film on its own part surface, over the
    vertices its film is judged on (a mesh part's skin: `Surface.judged_vertex_mask`)."""
    film = thickness(plan.applicator, plan.gun_samples(), surface.vertices, surface.normals)
    u = uniformity(film, surface.vertex_areas, mask=surface.judged_vertex_mask())
    return float(u.mean_m), float(u.area_m2)


def common_film_build(surfaces: list[Surface], plans: list[CoveragePlan], names: list[str],
                      target_um: float | None) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """The plans with each part's flow scaled to the common target (module doc), and a record
    {target_um, parts: {name: {planned_mean_um, flow_factor}}} for the report.

    names: a label per part. Raises BoothError when a factor leaves FLOW_FACTOR_RANGE.
    """
    stats = [planned_mean_m(p, s) for p, s in zip(plans, surfaces, strict=True)]
    means = np.array([m for m, _ in stats])
    areas = np.array([a for _, a in stats])
    target = (float(means @ areas / areas.sum()) if target_um is None else 1e-6 * target_um)
    if not target > 0:
        raise BoothError(f"film_target_um = {target_um} must be > 0")
    out, rec = [], {}
    lo, hi = FLOW_FACTOR_RANGE
    for name, plan, mean in zip(names, plans, means, strict=True):
        k = target / mean
        if not lo <= k <= hi:
            raise BoothError(f"part {name!r} plans {1e6 * mean:.1f} µm; reaching "
                             f"{1e6 * target:.1f} µm needs {k:.2f}× the bell flow, outside "
                             f"{lo}–{hi}×; set film_target_um nearer the parts' planned films")
        out.append(dataclasses.replace(plan, applicator=plan.applicator.scaled(k)))
        rec[name] = {"planned_mean_um": 1e6 * float(mean), "flow_factor": float(k)}
    return out, {"target_um": 1e6 * target,
                 "rule": ("film_target_um of the booth" if target_um is not None else
                          "the body's area-weighted planned mean (paint on the body unchanged)"),
                 "parts": rec}


def reversed_plan(plan: CoveragePlan) -> CoveragePlan:
    """The plan with its passes in the reverse order, each run backwards: the same samples,
    spray axes, speeds and dwell, so the same film (the bell's footprint is symmetric under a
    reversal of travel); times re-counted from each pass's new start."""
    out = []
    for p in plan.passes[::-1]:
        out.append(dataclasses.replace(
            p, positions=p.positions[::-1].copy(), spray_axes=p.spray_axes[::-1].copy(),
            travel_dirs=-p.travel_dirs[::-1], speeds_m_s=p.speeds_m_s[::-1].copy(),
            times_s=p.times_s[-1] - p.times_s[::-1], on_part=p.on_part[::-1].copy(),
            paint_on=p.paint_on[::-1].copy()))
    return dataclasses.replace(plan, passes=tuple(out))
