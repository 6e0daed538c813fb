"""Film refinement in a booth with the robots' pace kept (`paintcell.booth.booth_programs`
applies it after planning the parts, when `Booth.film_refine_pace` is set).

The planner's film refinement (`paintcell.coverage.film_refine`) re-times all of a part's
passes together against the simulated film on the part. In a booth it runs on each part alone,
and the pass durations it changes are what the robots share: the door's passes run at the
fender's pace so the two side bells sweep in step, the roof's two pieces are painted side by side,
and the start delays that keep the arms apart are measured on these timings. Re-timed on its
own, every part drifts: with it on, four of the five ranked allocations failed the arm stagger and
the fifth left a robot idle (measured on the booth scenario).

Here each part is planned without it and then refined with every pass's DURATION held
(`refine_speeds(pass_time_weight=PASS_TIME_WEIGHT)`): the speeds still move along each pass to
even the film, but each pass starts and ends when it did, so robots sweeping in step stay in step
pass by pass, and the allocation's estimates and the stagger see the same program lengths. As in
the planner, a part keeps its refined timing only when its simulated film's σ/μ is lower than
before on the whole part and on its interior (else it keeps the plan).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from paintcell.coverage.film_refine import refine_speeds
from paintcell.coverage.plan import CoveragePlan
from paintcell.surface.surface import Surface

#: weight of a pass's relative duration change in the refinement's fit. The film term is
#: (σ/μ)² ≈ 0.005 at 7 %; a 1 % longer or shorter pass costs 1e3 · 1e-4 = 0.1, twenty times the
#: whole film term, so the durations stay within ~0.1 % (measured in `refine_parts`' record).
PASS_TIME_WEIGHT = 1e3


def refine_parts(surfaces: list[Surface], plans: list[CoveragePlan],
                 settings: list[Any], names: list[str],
                 caps: list[list[np.ndarray | None] | None] | None = None
                 ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """Each part's plan re-timed against its film with its passes' durations held (module doc).

    surfaces, plans: per part, its surface and plan (part frame); settings: per part, its
    `PlannerSettings` (speed bounds, interior band); names: a label per part. Returns the plans
    and a record {rule, parts: {name: applied, σ/μ before/after [%], largest pass duration
    change [s]}}.
    """
    from paintcell.paint.metrics import boundary_band_mask, boundary_vertices

    out, rec = [], {}
    caps = caps if caps is not None else [None] * len(plans)
    for s, plan, st, name, cap in zip(surfaces, plans, settings, names, caps, strict=True):
        interior = boundary_band_mask(s.vertices, s.vertices[boundary_vertices(s.faces)],
                                      st.film_guard_band_m)
        if not interior.any():
            interior = np.ones(len(s.vertices), bool)
        passes, info = refine_speeds(plan.applicator, s, list(plan.passes), st.v_min_m_s,
                                     st.v_max_m_s, interior, cap,
                                     pass_time_weight=PASS_TIME_WEIGHT)
        change = [float((q.times_s[-1] - q.times_s[0]) - (p.times_s[-1] - p.times_s[0]))
                  for p, q in zip(plan.passes, passes, strict=True)]
        rec[name] = {"applied": bool(info["applied"]),
                     "nsd_before_pct": info.get("nsd_capped_pct", info["nsd_before_pct"]),
                     "nsd_after_pct": info.get("nsd_after_pct"),
                     "max_pass_duration_change_s": float(max(np.abs(change), default=0.0)),
                     **({"reason": info["reason"]} if "reason" in info else {})}
        out.append(dataclasses.replace(plan, passes=tuple(passes)))
    return out, {"rule": "each part re-timed against its film with every pass's duration held "
                         f"(weight {PASS_TIME_WEIGHT:g}); kept where σ/μ drops on the part and "
                         "its interior", "parts": rec}
