"""The pass geometry of one pass family, kept for robot-aware re-plans (lengths in m).

A robot-aware re-plan (`paintcell.motion.speed_feedback`, for one robot or N)
plans the same part with the same settings under per-sample speed caps and bell x axes. What
those change is the passes' timing only: the start curve, the offsets, the index-width searches
(eq. 3 on the markers' cross profiles), the back-fill and the choice of the start order read the
passes' foot points, never their speeds or bell axes (`_time_pass` writes `timing` and the
`speed_status` entry of `info`, which nothing in Algorithm 1's sweeps reads). So
`coverage_family.plan_family` keeps the geometry of its last plans without caps or bell axes
here (`FamilyGeometry`: the passes before timing, the start curve's rule, the openings, the
smoothing, the planner; or the PlanError such a plan raised), and a re-plan of the same surface,
settings and applicator only re-times those passes, then runs the film guard and the refinement:
byte-identical plans without the sweeps (`benchmarks/replan_cache.py`: reach_hood_panel --fast,
a re-plan 5.3 → 1.3 s CPU).

Memory: at most `MAX_KEPT` geometries (the last ones planned: a booth's parts, a part's patches),
each without the planner's cross-profile tables (only their counts, for the report).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from paintcell.core.errors import PlanError
from paintcell.coverage.coverage_planner import PassGeom, Planner
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface_data import Surface

#: geometries kept (least recently used dropped first): a booth re-plans its parts in turn and a
#: patch plan its patches, so one entry would be replaced before its re-plan came.
MAX_KEPT = 8


@dataclass(eq=False)
class FamilyGeometry:
    """What `plan_family` computes before timing the passes it chose.

    pl: the planner (smoothed surface, settings, applicator; cross-profile tables dropped);
    passes: the chosen start order's passes {side: pass}, untimed; reversed_start: that order;
    candidates: predicted worst σ/μ [%] of each start order planned; start_rule; planar;
    planar_width_m; smooth_scale_m; smoothing_max_shift_m; openings: the part's openings;
    profiles: (cross profiles computed, cache hits) of the width searches; notches: the bays of
    its outline closed for the plan (`paintcell.coverage.notches`)."""

    pl: Planner
    passes: dict[int, PassGeom]
    reversed_start: bool
    candidates: list[float]
    start_rule: str
    planar: bool
    planar_width_m: float | None
    smooth_scale_m: float
    smoothing_max_shift_m: float
    openings: list[Any]
    profiles: tuple[int, int]
    notches: list[Any] = field(default_factory=list)

    def untimed(self) -> FamilyGeometry:
        """A copy whose passes are untimed and may be timed (the kept ones stay as they are)."""
        return FamilyGeometry(
            pl=self.pl, passes={s: _untimed(p) for s, p in self.passes.items()},
            reversed_start=self.reversed_start, candidates=list(self.candidates),
            start_rule=self.start_rule, planar=self.planar, planar_width_m=self.planar_width_m,
            smooth_scale_m=self.smooth_scale_m, smoothing_max_shift_m=self.smoothing_max_shift_m,
            openings=self.openings, profiles=self.profiles, notches=self.notches)


def _untimed(p: PassGeom) -> PassGeom:
    q = copy.copy(p)                 # arrays are replaced, never changed in place
    q.info = dict(p.info)
    q.info.pop("feedback_mismatch", None)    # caps of another plan's passes: timed again
    q.timing = None
    return q


_KEPT: OrderedDict[str, FamilyGeometry | PlanError] = OrderedDict()


def geometry_key(surface: Surface, app: Applicator, st: PlannerSettings,
                 fails_fast: bool) -> str:
    """Digest of what the geometry depends on: the surface (name, vertices, faces), the
    applicator's values (a run loads its bell again for the re-plans), the settings (the timing
    ones cost nothing to include) but `film_refine`, and whether an `AxisTurnError` ends the
    plan at once. The film refinement re-times the timed passes after the geometry is chosen,
    so a part planned without it and then with it (`paintcell init` measures both) plans its
    passes once."""
    kept_settings = {k: v for k, v in st.to_dict().items() if k != "film_refine"}
    h = hashlib.sha1(repr((kept_settings, fails_fast, surface.name)).encode())
    for f in dataclasses.fields(app):
        v = getattr(app, f.name)
        if isinstance(v, np.ndarray):
            h.update(repr((f.name, v.dtype.str, v.shape)).encode())
            h.update(np.ascontiguousarray(v).tobytes())
        else:
            h.update(repr((f.name, v)).encode())
    for a in (surface.vertices, surface.faces):
        h.update(repr((a.dtype.str, a.shape)).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def kept(key: str, app: Applicator) -> FamilyGeometry | None:
    """An untimed copy of the geometry kept under `key` (its planner now painting with `app`,
    the same values), or None; raises (a copy of) the PlanError kept there instead."""
    got = _KEPT.get(key)
    if got is None:
        return None
    _KEPT.move_to_end(key)
    if isinstance(got, PlanError):
        raise copy.copy(got)
    got.pl.app = app
    return got.untimed()


def keep(key: str, geo: FamilyGeometry | PlanError) -> None:
    """Keep an untimed copy of `geo` (the planner's cross-profile tables are dropped: the
    report keeps only their counts), or the PlanError its plan raised (with "auto" smoothing,
    the bell axis that could not follow the surface at the finer scale)."""
    if isinstance(geo, FamilyGeometry):
        geo.pl.cache = {}
        geo.pl.heat = None
        geo = geo.untimed()
    _KEPT[key] = geo
    _KEPT.move_to_end(key)
    while len(_KEPT) > MAX_KEPT:
        _KEPT.popitem(last=False)


def forget() -> None:
    """Drop every kept geometry."""
    _KEPT.clear()
