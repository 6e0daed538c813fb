"""Algorithm 1 of the paper: start curve, offsets within the surface at optimized index widths,
per-pass speed optimization, assembled into a `CoveragePlan`.

    select the start curve (§2.3); optimize its speed (§3)
    repeat: offset the latest pass to its right at the index width of §4; optimize its speed
    until the offset lies completely outside the surface
    the same to the left of the start curve

Index widths: planar surfaces use the Fig. 5 rule (`planar_index_width`, one width for all
passes). Curved surfaces (extruded or not) use markers along the current pass spaced by its total
curvature; at each marker the surface is approximated by the extrusion of the marker's indexing
curve and the brute-force search over n future passes (eq. 3) gives the best σ/μ per candidate
width; the paper's constant-index restriction keeps the widths feasible at every marker, and the
cost penalizes small widths and |w0 − w−1|. The new pass is the offset of every sample of the
current pass by w0 along its indexing curve (geodesic), continued within the surface to the
boundary and beyond it by `overspray_m` along the tangent. After the last pass that touches the
surface, the first offset that lies completely outside is kept as a sideways overspray pass
(`edge_passes`), painted over the virtual extension of the surface. Where the current pass's end
samples have no offset there (their indexing curves left the surface along the boundary the pass
ends at, `paintcell.coverage.offset.walk`), the edge pass continues straight along its own
path as far as the current pass reaches, then by the overspray.
An offset that leaves the surface over only part of its length keeps that stretch as a sideways
pass over the virtual extension (its end is not extended within the surface), and where a new
pass is extended within the surface past the pass it came from, the extension is walked back by
the index width onto that pass (`paintcell.coverage.back_fill`): a boundary oblique to
the passes gets the neighbour pass an edge pass gives a parallel one.

The code lives in `coverage_settings` (`PlannerSettings`), `coverage_planner` (pass geometry and
the width choice), `coverage_timing` (overspray, band, speed QP, execution order) and
`coverage_family` (Algorithm 1 on one pass family); this module is the entry point `plan_coverage`
(input checks, then patches or one family).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from tqdm import tqdm

from paintcell.core.errors import AxisTurnError, PlanError
from paintcell.coverage.coverage_family import plan_family
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.patches import plan_patches
from paintcell.coverage.plan import CoveragePlan
from paintcell.coverage.smoothing import FOOTPRINT_FRACTION
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface_data import Surface

__all__ = ["AUTO_SMOOTHING_RETRIES", "plan_coverage"]


def plan_coverage(surface: Surface, applicator: Applicator,
                  settings: PlannerSettings | None = None,
                  speed_caps_m_s: dict[int, np.ndarray] | None = None,
                  tool_x: dict[int, np.ndarray] | None = None) -> CoveragePlan:
    """Plan uniform coverage of `surface` with `applicator` (paper Algorithm 1).

    surface: a `paintcell.surface.analytic.Surface` in its part frame; applicator: the
    deposition model; settings: `PlannerSettings` (defaults when None);
    speed_caps_m_s: optional per-pass speed upper bounds {side: (M,) [m/s]}, one per TCP sample of
        that pass in its generation direction (`plan.passes[i]` reversed when i is odd): the speed
        QP re-plans under them (robot-aware speeds, `paintcell.motion.speed_feedback`). A
        re-plan with the same
        part and settings reproduces the same passes, so caps taken from a plan fit its re-plan
        (it re-times the passes kept from that plan: `paintcell.coverage.
        family_geometry`, byte-identical to planning them again);
    tool_x: optional per-pass bell x axes {side: (M, 3)} in the part frame, same sample order as
        the caps: the orientation the robot will hold about the spray axis (a robot that frees
        the bell's spin); the deposition model (QP, film) then uses it as the travel axis.
    Returns a `CoveragePlan` in the part frame: passes in execution order (side −k … +k,
    alternating direction), TCP at standoff along the normal, speeds and times, on_part /
    paint_on flags, index widths, the start-curve rule and the settings (with a `report` entry:
    per-pass width choice, markers, speed-QP status). The plan holds no wall-clock timing, so
    the same input gives a byte-identical saved plan (the pipeline records stage times).
    With `smoothing_m = "auto"`, a plan that fails because the bell axis cannot follow the
    surface within `max_axis_turn_rad_m` is planned again on the surface smoothed at 2×, then
    4× the auto scale (the report's `auto_smoothing` says so; the settings record the scale; a
    progress bar on a terminal shows the retries). At the auto scale itself, the first such
    pass in either start order of `first_side = "best"` ends that plan (the orders are planned
    a pass at a time in turn) rather than the other order planning on at a scale the surface
    has already shown too fine: crs_cowling_creases met it on the left-first order's pass 3
    while the right-first one went on for 39 passes (~20 s) before it met one too; forced
    through (the limiter run to convergence), its plan at the auto scale had 109 passes at a
    predicted σ/μ of 82 %. At the retry scales both orders plan on as before (at 2× the
    cowling's right-first order meets such a pass and the left-first one plans, 35 passes).
    Raises PlanError when an offset self-intersects or the loop does not terminate, and its
    subclass AxisTurnError when the bell axis cannot follow the surface (at every scale tried).
    """
    if not isinstance(surface, Surface):
        raise PlanError(f"plan_coverage needs a paintcell.surface.analytic.Surface, got "
                        f"{type(surface).__name__}; build one with Surface.from_mesh or "
                        "paintcell.surface.parts.get_part")
    if not isinstance(applicator, Applicator):
        raise PlanError("plan_coverage needs an Applicator (paintcell.paint.applicator), "
                        f"got {type(applicator).__name__}; use Applicator.default() or from_toml")
    if settings is not None and not isinstance(settings, PlannerSettings):
        raise PlanError(f"plan_coverage settings must be PlannerSettings or None, got "
                        f"{type(settings).__name__}; use PlannerSettings.from_dict for a dict")
    st = PlannerSettings() if settings is None else settings
    auto = st.smoothing_m == "auto"
    try:        # with "auto", a pass the bell cannot follow in either start order ends this plan
        return _plan(surface, applicator, st, speed_caps_m_s, tool_x, axis_turn_fails_fast=auto)
    except AxisTurnError as e:
        if not auto:
            raise
        first = e
    # "auto" smoothing (a quarter of the footprint radius) left a feature the bell axis cannot
    # follow within max_axis_turn_rad_m: plan on the surface smoothed at twice, then four times
    # that scale (half and all of the footprint radius — still the spray's own scale). Each
    # plan can take minutes on a large part: a bar (on a terminal only) says which scale runs.
    base = FOOTPRINT_FRACTION * applicator.footprint_radius_m
    bar = tqdm(AUTO_SMOOTHING_RETRIES, desc="auto smoothing: bell axis too fast, planning again",
               unit="plan", leave=False, disable=None)
    try:
        for k in bar:
            bar.set_postfix_str(f"smoothing {k:g}× = {k * base:.3f} m")
            try:
                plan = _plan(surface, applicator, replace(st, smoothing_m=k * base),
                             speed_caps_m_s, tool_x)
            except AxisTurnError:
                continue
            plan.settings["report"]["auto_smoothing"] = (
                f"smoothing_m 'auto' ({base:.3f} m): {first}; planned at {k:g} × that scale")
            return plan
    finally:
        bar.close()
    raise first


#: Multiples of the "auto" smoothing scale tried, in turn, when the bell axis cannot follow it
#: (`paintcell.core.errors.AxisTurnError`).
AUTO_SMOOTHING_RETRIES = (2.0, 4.0)


def _plan(surface: Surface, applicator: Applicator, st: PlannerSettings,
          speed_caps_m_s: dict[int, np.ndarray] | None,
          tool_x: dict[int, np.ndarray] | None, axis_turn_fails_fast: bool = False
          ) -> CoveragePlan:
    if st.patches:
        return plan_patches(surface, applicator, replace(st, patches=False),
                            speed_caps_m_s=speed_caps_m_s, tool_x=tool_x)
    return plan_family(surface, applicator, st, speed_caps_m_s, tool_x, axis_turn_fails_fast)
