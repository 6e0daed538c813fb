"""The booth's part plans (`paintcell.booth.booth_programs` builds them first): each part's
surface and its plan as the planner makes it (`plan_parts`), then what the booth does to the
plans together (`finish_plans`): passes run backwards where a part says `reverse`, the film
refined with the robots' pace held (`paintcell.coverage.film_refine.refine_parts`), one film build
(`paintcell.booth.booth_build`), blended seams (`paintcell.booth.booth_seams`) and every part
re-timed together against the body's film, the durations free and the passes the blend switched
off painted again where that film wants them (`refine_body`: the seams).

The two steps are apart so the robot-aware speeds (`paintcell.motion.speed_feedback`) can plan
a part again under its robots' speed caps and finish the plans the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from paintcell.booth.booth import Booth, BoothError
from paintcell.booth.booth_build import reversed_plan
from paintcell.booth.booth_film import judged_body_mask, merge_surfaces
from paintcell.coverage.plan import CoveragePlan
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface_data import Surface

#: the body's refinement fits the seams' film (the vertices near another part,
#: `paintcell.booth.booth_seams.seam_band`) at this many times their area's weight
#: (`refine_body`). Fitted by area alone, the seed-1 SUV line's seams are ~1.6× as uneven as the
#: interiors; its last robot-aware round's body film (planned σ/μ, seams ÷ interiors) at
#: weights 1, 2 and 3: 4.82 % and 1.58×, 4.64 % and 1.38×, 4.61 % and 1.28×, its worst panel
#: (the front fascia, by its own interior) 7.76, 7.90 and 8.02 %: the first fit's; at weight 2
#: `weigh_worst_part`'s second fit, the fascia weighed 1.7×, gives 7.53 % and 1.42×.
SEAM_FIT_WEIGHT = 2.0


@dataclass
class PartPlans:
    """Each part as planned (`plan_parts`): surfaces (part frames), the planner's own plans
    (generation order, not reversed), the placements in the body frame, the skins the planner
    covered, its settings per part, and the bell."""

    surfaces: list[Surface]
    plans: list[CoveragePlan]
    T_body_parts: list[np.ndarray]
    skins: list[Surface]
    settings: list[Any]
    applicator: Applicator


@dataclass
class FinishedPlans:
    """The plans the robots run (`finish_plans`), the body surface and the records."""

    plans: list[CoveragePlan]
    body: Surface
    refine: dict[str, Any] = field(default_factory=dict)
    film_build: dict[str, Any] = field(default_factory=dict)
    seams: dict[str, Any] = field(default_factory=dict)


def part_settings(booth: Booth) -> list[dict[str, Any]]:
    """Each part's planner table: the booth's `[planner]` under the part's own."""
    return [{**booth.planner, **bp.planner} for bp in booth.parts]


def plan_parts(booth: Booth, fast: bool, tasks: Any = None) -> PartPlans:
    """Load each part (the scenario's loader: import, repair, remesh, regions) and plan its skin.
    tasks: a `paintcell.booth.booth_tasks.TaskPool` that plans the parts at once (None: one
    after the other in this process; the plans are the same)."""
    res = booth.fast_resolution_m if fast else booth.resolution_m
    app = Applicator.default() if booth.applicator is None \
        else Applicator.from_toml(booth.applicator)
    out = PartPlans([], [], [], [], [], app)
    if tasks is None:
        planned = [plan_part(booth, i, res, app) for i in range(len(booth.parts))]
    else:   # a mesh or CAD part's surface read here and sent, a library part's made there
        futs = [tasks.submit(plan_part, booth, i, res, app,
                             None if bp.mesh is None else part_surface_of(booth, i, res))
                for i, bp in enumerate(booth.parts)]
        planned = [f.result() for f in futs]
    for bp, (s, skin, st, plan) in zip(booth.parts, planned, strict=True):
        out.plans.append(plan)
        out.surfaces.append(s)
        out.skins.append(skin)
        out.settings.append(st)
        out.T_body_parts.append(bp.placement.matrix)
    return out


def part_surface_of(booth: Booth, i: int, res: float) -> Surface:
    """Part i's surface in its own frame at edge length res [m] (a library part made, a mesh or
    CAD file read)."""
    from paintcell.surface import parts
    from paintcell.surface.part_surface import part_surface

    bp = booth.parts[i]
    if bp.mesh is None and bp.part not in parts.PART_NAMES:
        raise BoothError(f"booth part {bp.part!r} is not a library part "
                         f"({', '.join(parts.PART_NAMES)}); a mesh/CAD file goes in a "
                         "[parts.part] table with file = \"...\"")
    return part_surface(bp.part if bp.mesh is None else bp.mesh, res)


def plan_part(booth: Booth, i: int, res: float, app: Applicator,
              surface: Surface | None = None) -> tuple[Surface, Surface, Any, CoveragePlan]:
    """Part i planned at edge length res [m] with the bell `app`: its surface (`surface`, else
    `part_surface_of`), the skin the planner covers, its `PlannerSettings` and its plan."""
    from paintcell.core.settings import settings_from
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.coverage.coverage_settings import PlannerSettings

    s = part_surface_of(booth, i, res) if surface is None else surface
    kw = part_settings(booth)[i]
    if booth.film_refine_pace:      # refined later with the pace held (refine_parts)
        kw = {**kw, "film_refine": False}
    st = settings_from(PlannerSettings, kw, "planner")
    # a real part's planner covers its skin, as a scenario's (`pipeline.make_plan`)
    skin = s.region_surface(("skin",))
    return s, skin, st, plan_coverage(skin, app, st)


def finish_plans(booth: Booth, pp: PartPlans, plans: list[CoveragePlan],
                 caps: list[list[np.ndarray | None] | None] | None = None) -> FinishedPlans:
    """The robots' plans from the planner's `plans` (one per part, generation order): reversed
    where the part says so, refined with the pace held (`Booth.film_refine_pace`), one film build,
    seams blended, then (`film_refine_pace`, two parts or more) every part re-timed together
    against the body's film (`refine_body`). caps: per part, per pass of its finished plan
    (execution order) the robot's speed caps [m/s] the refinement keeps under (None: none)."""
    plans = [reversed_plan(pl) if bp.reverse else pl
             for pl, bp in zip(plans, booth.parts, strict=True)]
    names = [f"{i}:{bp.part}" for i, bp in enumerate(booth.parts)]
    refine: dict[str, Any] = {"rule": "off"}
    if booth.film_refine_pace:
        from paintcell.core.settings import settings_from
        from paintcell.coverage.coverage_settings import PlannerSettings
        from paintcell.coverage.film_refine import refine_parts

        # a part whose planner says film_refine = false (booth or part table) is not refined
        kws = part_settings(booth)
        on = [i for i, kw in enumerate(kws) if kw.get("film_refine") is not False]
        refined, refine = refine_parts(
            [pp.surfaces[i] for i in on], [plans[i] for i in on],
            [planned_speeds(settings_from(PlannerSettings, kws[i], "planner"), plans[i])
             for i in on],
            [names[i] for i in on], None if caps is None else [caps[i] for i in on])
        plans = [refined[on.index(i)] if i in on else pl for i, pl in enumerate(plans)]
        refine["parts"].update({names[i]: {"applied": False,
                                           "reason": "planner.film_refine = false"}
                                for i in range(len(plans)) if i not in on})
    build: dict[str, Any] = {"rule": "off: each part at the default bell flow"}
    if booth.common_film_build:
        from paintcell.booth.booth_build import common_film_build

        plans, build = common_film_build(pp.surfaces, plans, names, booth.film_target_um)
    body = merge_surfaces(pp.surfaces, pp.T_body_parts, booth.name)
    seams: dict[str, Any] = {"rule": "off" if not booth.blend_seams else "one part: no seams"}
    unblended = plans
    if booth.blend_seams and len(plans) > 1:
        from paintcell.booth.booth_seams import blend_part_seams

        plans, seams = blend_part_seams(body, plans, pp.T_body_parts,
                                        [len(x.vertices) for x in pp.surfaces], names,
                                        judged_body_mask(pp.surfaces),
                                        per_seam=booth.seam_shares == "per seam")
    if booth.film_refine_pace and len(plans) > 1:
        plans, refine["body"] = refine_body(booth, pp, plans, body, caps, unblended)
        if "samples_switched_off" in seams:
            # the body's refinement may paint some of them again: what stays off in the end
            seams["samples_off_after_refinement"] = dict(zip(
                names, samples_off(plans, unblended), strict=True))
    return FinishedPlans(plans, body, refine, build, seams)


def planned_speeds(st: Any, plan: CoveragePlan) -> Any:
    """The part's planner settings `st` at the pace `plan` was planned at: a part planned again
    slower (`paintcell.motion.speed_feedback.paced`, its nominal speed recorded in the plan's
    settings below st's) is refined within its own, paced speed bounds."""
    from paintcell.motion.speed_feedback import paced

    v = plan.settings.get("v_nominal_m_s")
    pace = 1.0 if v is None else float(v) / st.v_nominal_m_s
    return paced(st, pace) if pace < 1.0 - 1e-9 else st


def samples_off(plans: list[CoveragePlan], unblended: list[CoveragePlan]) -> list[int]:
    """Per part, the brush-on samples of `unblended` (the plans before the seams' blending)
    that `plans` (the same passes, blended and refined) leave off."""
    return [int(sum(np.count_nonzero(np.asarray(u.paint_on, bool) & ~np.asarray(p.paint_on, bool))
                    for p, u in zip(pl.passes, ub.passes, strict=True)))
            for pl, ub in zip(plans, unblended, strict=True)]


def part_nsds(body: Surface, part_counts: list[int], plans: list[CoveragePlan]
              ) -> tuple[float, list[float]]:
    """The planned film of `plans` (body frame) on `body` (parts stacked in order, part_counts
    vertices each; a vertex of zero area is not judged): its σ/μ [%] over the body and over
    each part (NaN where a part has no judged area)."""
    from paintcell.booth.booth_film import body_uniformity
    from paintcell.paint.deposition import thickness

    film = sum(thickness(pl.applicator, pl.gun_samples(), body.vertices, body.normals)
               for pl in plans)
    film = np.asarray(film, float)

    def nsd(w: np.ndarray) -> float:        # NaN where nothing is judged or painted
        return body_uniformity(film, w) if w.sum() > 0 and film @ w > 0 else float("nan")

    offs = np.cumsum([0, *part_counts])
    parts = []
    for k in range(len(part_counts)):
        w = np.zeros(len(film))
        w[offs[k]:offs[k + 1]] = body.vertex_areas[offs[k]:offs[k + 1]]
        parts.append(nsd(w))
    return nsd(body.vertex_areas), parts


def weigh_worst_part(body: Surface, part_counts: list[int], plans: list[CoveragePlan],
                     fitted: dict[str, Any], fit: Any, names: list[str]
                     ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """The body's fit (`plans` and its record `fitted`, what fit(None) gave) once more with the
    part of the highest σ/μ weighed by its σ/μ over the body's: a fit of the whole body's
    variance leaves the most uneven part as it is where evening it costs the others, and a
    line's spec judges every part on its own (`Booth.thresholds.max_executed_nsd_pct`).
    fit(weight): the body's fit with the (N,) vertex weights, (plans, record). The re-fit is
    kept when the worst part's σ/μ drops by more than the body's rises, if it does (the planned
    films, by area). Returns the plans and the record of the fit kept, with {worst_part: ...}
    added."""
    rec: dict[str, Any] = {"rule": "the part of the highest σ/μ weighed by its σ/μ over the "
                                   "body's in a second fit, kept when the worst part's σ/μ "
                                   "drops by more than the body's rises",
                           "applied": False}
    whole, parts = part_nsds(body, part_counts, plans)
    if len(parts) < 2 or not np.isfinite(parts).any() or not np.isfinite(whole):
        return plans, {**fitted, "worst_part": {**rec, "reason": "fewer than two judged, "
                                                                 "painted parts"}}
    k = int(np.nanargmax(parts))
    w = parts[k] / whole
    rec.update(part=names[k], weight=round(float(w), 4), body_nsd_before_pct=whole,
               worst_nsd_before_pct=parts[k])
    if not w > 1.0:
        return plans, {**fitted, "worst_part": {**rec, "reason": "no part is more uneven than "
                                                                 "the body"}}
    offs = np.cumsum([0, *part_counts])
    weight = np.ones(len(body.vertices))
    weight[offs[k]:offs[k + 1]] = w
    out, refitted = fit(weight)
    whole2, parts2 = part_nsds(body, part_counts, out)
    rec.update(body_nsd_after_pct=whole2, worst_nsd_after_pct=float(np.nanmax(parts2)),
               worst_part_after=names[int(np.nanargmax(parts2))])
    drop = parts[k] - float(np.nanmax(parts2))
    if not (drop > 0 and whole2 - whole < drop):
        return plans, {**fitted, "worst_part": {
            **rec, "reason": "the worst part's σ/μ drops less than the body's rises, or not"}}
    return out, {**refitted, "worst_part": {**rec, "applied": True}}


def refine_body(booth: Booth, pp: PartPlans, plans: list[CoveragePlan], body: Surface,
                caps: list[list[np.ndarray | None] | None] | None,
                unblended: list[CoveragePlan] | None = None
                ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """The parts' plans (part frames, execution order, seams blended) re-timed together against
    the film they lay on the body (`paintcell.coverage.film_refine.refine_together`): each part
    refined alone sees only its own film, and the seams get both parts' edges. The film is
    judged on the body's judged vertices, its interior those away from the seams
    (`paintcell.booth.booth_seams.seam_band`); the fit weighs the seams' vertices
    `SEAM_FIT_WEIGHT` × their areas (the result is judged by area alone); the passes' durations
    are free (each part's own
    refinement held its pace; the programs and their start delays are built from these plans).
    unblended: the same plans before the seams were blended; a pass the blending switched off
    entirely may be painted again where the body's film wants it (`refine_together`'s
    restorable). Returns the plans and the record."""
    from paintcell.booth.booth_seams import pass_in_body, seam_band
    from paintcell.core.settings import settings_from
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.coverage.film_refine import refine_together

    kws = part_settings(booth)
    if any(kw.get("film_refine") is False for kw in kws):
        return plans, {"applied": False,
                       "reason": "a part's planner says film_refine = false: its film is held"}
    judged = judged_body_mask(pp.surfaces)
    band = seam_band(body.vertices, [len(x.vertices) for x in pp.surfaces])
    interior = judged & ~band
    if not interior.any():          # every judged vertex near a seam: judged on all of them
        interior = judged
    seen = replace(body, vertex_areas=np.where(judged, body.vertex_areas, 0.0))
    moved = [replace(pl, passes=tuple(pass_in_body(p, T) for p in pl.passes))
             for pl, T in zip(plans, pp.T_body_parts, strict=True)]
    restorable = None if unblended is None else [
        [np.asarray(u.paint_on, bool) & ~np.asarray(p.paint_on, bool)
         for p, u in zip(pl.passes, ub.passes, strict=True)]
        for pl, ub in zip(plans, unblended, strict=True)]
    speeds = [planned_speeds(settings_from(PlannerSettings, kw, "planner"), pl)
              for kw, pl in zip(kws, plans, strict=True)]

    def fit(weight: np.ndarray | None) -> tuple[list[CoveragePlan], dict[str, Any]]:
        return refine_together(seen, moved, speeds, interior, caps, restorable=restorable,
                               edge_weight=SEAM_FIT_WEIGHT, vertex_weight=weight)

    out, rec = weigh_worst_part(seen, [len(x.vertices) for x in pp.surfaces], *fit(None), fit,
                                [f"{i}:{bp.part}" for i, bp in enumerate(booth.parts)])
    # only the timing and the paint switches changed: the part-frame passes take them
    return [replace(pl, passes=tuple(replace(p, speeds_m_s=q.speeds_m_s, times_s=q.times_s,
                                             paint_on=q.paint_on)
                                     for p, q in zip(pl.passes, o.passes, strict=True)))
            for pl, o in zip(plans, out, strict=True)], rec

