"""Film refinement: re-time every pass together against the simulated film on the real part.

The paper's speed QP (§3) times one pass at a time on its own band of sub-offset curves, and the
film guard (`coverage_family._film_guard`) can only blend those speeds back toward constant. Two
things it cannot see are left thin or thick on a real part: the rim of an opening, where the brush
goes off over the hole (`openings.brush_off_openings`) and the paint its footprint would have put on
the rim is missing, and the stripes where neighbouring passes' films add up differently from the
band's model (pass ends, the outer edge, a narrow strip between a window and the part's edge).

Because film thickness is linear in the dwell time of each gun sample (eq. 1: film = Σ_s rate_s ·
dwell_s), the whole plan's film on the real mesh is M · s, where s are slowness multipliers on the
planned dwell at knots spaced `KNOT_SPACING_M` along each pass (linear between knots) and M is the
deposition model summed over the samples each knot carries. `refine_speeds` solves the bounded
least-squares problem

    min_s  Σ_v a_v (M s − μ)_v² / (A μ²)  +  λ_smooth Σ ‖Δ² s‖²  +  λ_keep Σ (s − 1)²
    s.t.   every sample's new speed v / s stays in [v_min, min(v_max, robot cap)]

(a_v vertex areas, off the interior × `edge_weight` in the fit, A their sum, μ the mean film
of the start: the film is held where it is, only its spread shrinks) with
OSQP (a box-constrained QP on the normal equations; the bounds OSQP finds active are held, the
free knots solved exactly by Cholesky and the result checked against the optimality conditions,
`scipy.optimize.lsq_linear`'s bounded-variable least squares where the check fails:
`bounded_minimum`), rebuilds speeds and times, and
keeps the result only when the simulated film's σ/μ on the part is lower than before, on the
whole part and on its interior. The start is the planned timing, slowed to
the robot's speed caps where it exceeds them (what the robot would paint; a robot-aware re-plan,
`paintcell.motion.speed_feedback`, passes them), so the refined speeds stay within what the
robot can follow.

`refine_plan` runs it on one part with the planner's settings. A cell whose robots sweep in step
(a booth: the door's passes at the fender's pace, the roof's two pieces side by side, start
delays measured on these timings) refines each part with every pass's DURATION held
(`refine_parts`, `keep_pace`; `Booth.film_refine_pace`): the speeds still move along each pass
to even the film, but each pass starts and ends when it did, so robots in step stay in step and
the allocation's estimates and the stagger see the same program lengths. Re-timed freely, every
part drifts: four of the booth scenario's five ranked allocations then failed the arm stagger
and the fifth left a robot idle. `refine_together` then re-times every part's passes as one fit
against the film they lay together (the seams, which each part refined alone cannot see), the
durations free this time (see its doc). M's column blocks are kept by their passes' content
between fits (`_Blocks`): a booth's joint fit builds the same ones for its fit, its relaxed fit
and its refit with the worst part weighed.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.linalg import cholesky, solve_triangular
from scipy.optimize import lsq_linear

from paintcell.coverage.offset_polyline import arc_length
from paintcell.coverage.plan import CoveragePlan, PassPlan, times_from_speeds
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate, thickness
from paintcell.paint.deposition_samples import GunSamples
from paintcell.surface.surface_data import Surface

if TYPE_CHECKING:
    from paintcell.coverage.coverage_settings import PlannerSettings

#: spacing of the slowness knots along each pass [m] (a few per footprint diameter).
KNOT_SPACING_M = 0.08
#: weight of the second differences of the slowness along a pass (smooth speed changes).
SMOOTH_WEIGHT = 3e-3
#: weight of the slowness' departure from the planned speeds (keeps the cycle time).
KEEP_WEIGHT = 3e-4
#: gun samples per deposition-rate block (memory: block × vertices floats).
_BLOCK = 64
#: most (vertex, knot) entries of the fitted film matrix: the fit holds 2 such float64 arrays
#: (the matrix and its weighted copy), so 2e7 entries is ~0.3 GB at the peak. A
#: larger part is fitted on an evenly strided subset of its vertices (area weights scaled to the
#: part's); the result is still judged on the film of every vertex.
MAX_FIT_ENTRIES = 20_000_000
#: weights of the interior vertices tried in turn when a fit lowers σ/μ on the whole part but
#: not on the interior (`refine_speeds`).
INTERIOR_WEIGHTS = (1.0, 2.0, 4.0, 8.0)
#: weight of a pass's relative duration change when the pace is kept (`keep_pace`). The film
#: term is (σ/μ)² ≈ 0.005 at 7 %; a 1 % longer or shorter pass costs 1e3 · 1e-4 = 0.1, twenty
#: times the whole film term, so the durations stay within ~0.1 % (`refine_parts`' record).
PASS_TIME_WEIGHT = 1e3
#: A pass the seams' blending switched off entirely is painted again (`refine_together`) at the
#: samples where a relaxed joint fit, free to take its paint down to none, still wants at least
#: this share of its top-speed film (`refine_speeds`' paint_share). On the seed-1 SUV line the
#: rear doors' and quarters' top passes (the only ones over the frame headers under the roof)
#: wanted up to 0.35–0.50 and the seven other candidates at most 0.03. A share read per sample
#: against each sample's own top speed gave back more (at 0.2) or less (at 0.5) of the capped
#: stretches and left the body's planned σ/μ 0.5–0.9 pp higher on the captured plans.
RESTORE_SHARE = 0.2


def refine_plan(app: Applicator, surface: Surface, passes: list[PassPlan],
                st: PlannerSettings, caps_m_s: list[np.ndarray | None] | None = None,
                keep_pace: bool = False) -> tuple[list[PassPlan], dict[str, Any]]:
    """`refine_speeds` on a part with its planner settings `st` (speed bounds; interior: beyond
    the film guard's band from the part's boundary, every vertex if none is), within the
    robot's speed caps (per pass in execution order, in its execution direction); keep_pace:
    every pass's duration held (`PASS_TIME_WEIGHT`)."""
    from paintcell.paint.metrics import boundary_band_mask, boundary_vertices

    interior = boundary_band_mask(surface.vertices,
                                  surface.vertices[boundary_vertices(surface.faces)],
                                  st.film_guard_band_m)
    if not interior.any():
        interior = np.ones(len(surface.vertices), bool)
    return refine_speeds(app, surface, passes, st.v_min_m_s, st.v_max_m_s, interior, caps_m_s,
                         pass_time_weight=PASS_TIME_WEIGHT if keep_pace else 0.0)


def refine_parts(surfaces: list[Surface], plans: list[CoveragePlan],
                 settings: list[PlannerSettings], names: list[str],
                 caps: list[list[np.ndarray | None] | None] | None = None
                 ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """Each part's plan refined with its passes' durations held (`refine_plan(keep_pace=True)`).

    surfaces, plans: per part, its surface and plan (part frame); settings: per part, its
    `PlannerSettings`; names: a label per part; caps: per part, its robot's speed caps [m/s]
    (`refine_plan`). Returns the plans and a record {rule, parts: {name: applied, σ/μ
    before/after [%], largest pass duration change [s]}}.
    """
    out, rec = [], {}
    caps = caps if caps is not None else [None] * len(plans)
    for s, plan, st, name, cap in zip(surfaces, plans, settings, names, caps, strict=True):
        passes, info = refine_plan(plan.applicator, s, list(plan.passes), st, cap, keep_pace=True)
        change = [float((q.times_s[-1] - q.times_s[0]) - (p.times_s[-1] - p.times_s[0]))
                  for p, q in zip(plan.passes, passes, strict=True)]
        rec[name] = {"applied": bool(info["applied"]),
                     "nsd_before_pct": info.get("nsd_capped_pct", info["nsd_before_pct"]),
                     "nsd_after_pct": info.get("nsd_after_pct"),
                     "max_pass_duration_change_s": float(max(np.abs(change), default=0.0)),
                     **({"reason": info["reason"]} if "reason" in info else {})}
        out.append(replace(plan, passes=tuple(passes)))
    return out, {"rule": "each part re-timed against its film with every pass's duration held "
                         f"(weight {PASS_TIME_WEIGHT:g}); kept where σ/μ drops on the part and "
                         "its interior", "parts": rec}


def refine_together(surface: Surface, plans: list[CoveragePlan],
                    settings: list[PlannerSettings], interior: np.ndarray,
                    caps: list[list[np.ndarray | None] | None] | None = None,
                    pass_time_weight: float = 0.0,
                    restorable: list[list[np.ndarray | None]] | None = None,
                    edge_weight: float = 1.0, vertex_weight: np.ndarray | None = None
                    ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """Several parts' plans re-timed as one against the film they lay together on `surface`:
    where two parts meet, both parts' edge passes and overspray paint the seam, and each part
    refined alone (`refine_parts`) sees only its own. One least-squares fit over every pass's
    knots (`refine_speeds`, each pass at its part's flow and speed bounds).

    The passes' durations are free by default (pass_time_weight 0; `PASS_TIME_WEIGHT` holds
    them): each part's own refinement already held its pace, and the joint fit moves what is
    left a little (on the seed-1 SUV line under 0.9 s a pass, the passes 0.2 s shorter in all);
    held, the fit cannot move paint between a seam's two sides (a pass that should run faster
    over a seam must then run slower elsewhere) and the SUV line's body film gained 0.8 pp
    instead of 1.3 pp. The programs, their stagger and the cycle are built afterwards from the
    re-timed plans.

    A pass whose paint the seams' blending switched off entirely (`restorable`) may be painted
    again: over a narrow strip between two parts (a door's frame header under the roof) the
    pass that would paint it lays more on the neighbour and is switched off, and the strip is
    left thin. A relaxed fit, free to take each such pass's paint down to none
    (`refine_speeds`' paint_free), says how much of it the film wants at each sample; where it
    wants at least `RESTORE_SHARE` of its top-speed film (there: under the robot's cap) its
    samples are switched on again, and every pass is re-timed with them, kept when that beats
    the fit without them. The relaxed fit weighs the film by area alone: weighing the seams
    more (edge_weight) it asks for more of those passes back than the film can take (on the
    seed-1 SUV line's last round at weight 3: 145 samples against 117, the body's σ/μ 5.34 %
    against 4.61 %).

    surface: the parts together, in the plans' frame (a vertex of zero area is not judged);
    plans: per part, at its own deposition model; settings: per part, its `PlannerSettings`
    (speed bounds); interior: (N,) bool, the vertices the result must not be worse on either
    (`refine_body`: those away from the seams); caps: per part, per pass its robot's speed caps
    [m/s] (or None); restorable: per part, per pass the brush-on samples (bool (M,)) the seams'
    blending switched off, or None; edge_weight: the fits' weight of the vertices off the
    interior (`refine_speeds`; the relaxed fit's is 1); vertex_weight: (N,) a further weight of
    each vertex in the fits (`refine_speeds`; not in the relaxed fit). Returns the plans
    (re-timed where σ/μ drops on the whole and on the interior; otherwise as given, slowed to
    the caps where they asked for more, as `refine_speeds` returns them) and a record {rule,
    applied, σ/μ before/after [%], knots, largest pass duration change and the passes' total
    change [s], the passes painted again ("part:pass": samples) and each candidate's largest
    wanted share}.
    """
    caps = caps if caps is not None else [None] * len(plans)
    passes: list[PassPlan] = []
    apps: list[Applicator] = []
    lo: list[float] = []
    hi: list[float] = []
    cap_all: list[np.ndarray | None] = []
    owner: list[int] = []
    for k, (plan, st, cap) in enumerate(zip(plans, settings, caps, strict=True)):
        passes += list(plan.passes)
        apps += [plan.applicator] * len(plan.passes)
        lo += [st.v_min_m_s] * len(plan.passes)
        hi += [st.v_max_m_s] * len(plan.passes)
        cap_all += list(cap) if cap is not None else [None] * len(plan.passes)
        owner += [k] * len(plan.passes)
    out, info = refine_speeds(apps, surface, passes, lo, hi, interior, cap_all,
                              pass_time_weight=pass_time_weight, edge_weight=edge_weight,
                              vertex_weight=vertex_weight)
    flat = [m for part in (restorable or [[None] * len(pl.passes) for pl in plans])
            for m in part]
    cand = [i for i, (p, m) in enumerate(zip(passes, flat, strict=True))
            if m is not None and np.any(m) and not p.paint_on.any()]
    given: dict[str, Any] = {}
    if cand:
        out, info, given = _give_back(apps, surface, passes, lo, hi, interior, cap_all,
                                      pass_time_weight, cand, flat, owner, out, info,
                                      edge_weight, vertex_weight)
    change = [float((q.times_s[-1] - q.times_s[0]) - (p.times_s[-1] - p.times_s[0]))
              for p, q in zip(passes, out, strict=True)]
    own = np.asarray(owner)
    refined = [replace(plan, passes=tuple(q for q, o in zip(out, own, strict=True) if o == k))
               for k, plan in enumerate(plans)]
    held = (f"every pass's duration held (weight {pass_time_weight:g})" if pass_time_weight > 0
            else "the passes' durations free")
    rec = {"rule": "every part's passes re-timed together against the film they lay on the "
                   f"body, {held}; kept where σ/μ drops on the body and on its interior",
           "applied": bool(info["applied"]),
           "nsd_before_pct": info.get("nsd_capped_pct", info["nsd_before_pct"]),
           "nsd_after_pct": info.get("nsd_after_pct"), "knots": info.get("knots"),
           "max_pass_duration_change_s": float(max(np.abs(change), default=0.0)),
           "pass_duration_change_s": float(sum(change)),
           **given,
           **({"reason": info["reason"]} if "reason" in info else {})}
    return refined, rec


def _give_back(apps: list[Applicator], surface: Surface, passes: list[PassPlan],
               lo: list[float], hi: list[float], interior: np.ndarray,
               caps: list[np.ndarray | None], pass_time_weight: float, cand: list[int],
               masks: list[np.ndarray | None], owner: list[int], out: list[PassPlan],
               info: dict[str, Any], edge_weight: float = 1.0,
               vertex_weight: np.ndarray | None = None
               ) -> tuple[list[PassPlan], dict[str, Any], dict[str, Any]]:
    """`refine_together`'s passes switched off by the seams, painted again where the film
    wants them: the relaxed fit's share per candidate pass, then the fit with those over
    `RESTORE_SHARE` switched on, kept when it beats the fit without them (`out`, `info`) on the
    whole and is no worse on the interior than the start. Returns the passes, the info (σ/μ
    before: the start without them) and the record's part {passes_painted_again: samples per
    pass, paint_shares: each candidate's largest wanted share}."""
    label = [f"{o}:{i - owner.index(o)}" for i, o in enumerate(owner)]
    trial = [replace(p, paint_on=np.asarray(masks[i], bool)) if i in cand else p
             for i, p in enumerate(passes)]
    _, relaxed = refine_speeds(apps, surface, trial, lo, hi, interior, caps,
                               pass_time_weight=pass_time_weight,
                               paint_free=[i in cand for i in range(len(passes))])
    shares = relaxed.get("paint_share", {})
    wanted = {i: np.asarray(masks[i], bool) & (shares[i] >= RESTORE_SHARE)
              for i in cand if i in shares}
    back = [i for i in cand if i in wanted and wanted[i].any()]
    rec = {"passes_painted_again": {label[i]: int(wanted[i].sum()) for i in back},
           "paint_shares": {label[i]: round(float(np.max(shares.get(i, 0.0))), 4)
                            for i in cand}}
    if not back:
        return out, info, rec
    with_back = [replace(p, paint_on=wanted[i]) if i in back else p
                 for i, p in enumerate(passes)]
    out2, info2 = refine_speeds(apps, surface, with_back, lo, hi, interior, caps,
                                pass_time_weight=pass_time_weight, edge_weight=edge_weight,
                                vertex_weight=vertex_weight)
    start = info.get("nsd_capped_pct", info["nsd_before_pct"])
    start_int = info.get("interior_capped_pct", info["interior_before_pct"])
    best = info["nsd_after_pct"] if info["applied"] else start
    if not (info2["applied"] and info2["nsd_after_pct"] < best
            and info2["interior_after_pct"] <= start_int):
        rec["passes_painted_again"] = {}
        rec["reason_not_painted_again"] = ("no lower σ/μ than the fit without them on the "
                                           "body, or a worse interior than the start")
        return out, info, rec
    info2.update(nsd_before_pct=info["nsd_before_pct"],
                 interior_before_pct=info["interior_before_pct"])
    for k in ("nsd_capped_pct", "interior_capped_pct"):
        info2.pop(k, None)
        if k in info:
            info2[k] = info[k]
    return out2, info2, rec


def _knot_basis(arc_m: np.ndarray, spacing_m: float) -> tuple[sp.csr_matrix, int]:
    """Hat-function basis (M, K) of knots spread evenly over the arc length [m]."""
    length = float(arc_m[-1]) if len(arc_m) else 0.0
    k = max(2, int(np.ceil(length / spacing_m)) + 1)
    x = arc_m / max(length, 1e-12) * (k - 1)
    i0 = np.clip(np.floor(x).astype(int), 0, k - 2)
    f = x - i0
    rows = np.repeat(np.arange(len(arc_m)), 2)
    cols = np.column_stack([i0, i0 + 1]).ravel()
    vals = np.column_stack([1.0 - f, f]).ravel()
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(arc_m), k)), k


class _Blocks:
    """The film matrix's column blocks of recently fitted passes (`_film_matrix`), by content
    (the pass's samples, timing and brush-on, its deposition model, the fitted points), the
    least recently used dropped past `BLOCK_CACHE_BYTES`. A body's joint fit builds the same
    blocks again and again: its fit, its relaxed fit (only the passes it frees differ) and its
    refit with the worst part weighed (all equal) share them. A block is computed the same way
    whether kept or not, so the fits are equal bit for bit."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes, self.used = max_bytes, 0
        self._blocks: OrderedDict[bytes, np.ndarray] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: bytes) -> np.ndarray | None:
        with self._lock:
            block = self._blocks.get(key)
            if block is not None:
                self._blocks.move_to_end(key)
            return block

    def put(self, key: bytes, block: np.ndarray) -> None:
        if block.nbytes > self.max_bytes:
            return
        with self._lock:
            if key in self._blocks:
                return
            self._blocks[key] = block
            self.used += block.nbytes
            while self.used > self.max_bytes:
                self.used -= self._blocks.popitem(last=False)[1].nbytes


#: most bytes of film-matrix blocks kept between fits (`_Blocks`): about one body's matrix
#: (`MAX_FIT_ENTRIES` float64 entries is 0.16 GB).
BLOCK_CACHE_BYTES = 200_000_000
_BLOCKS = _Blocks(BLOCK_CACHE_BYTES)


def _block_key(app: Applicator, p: PassPlan, b: sp.csr_matrix, points_key: bytes) -> bytes:
    """The content key of one pass's film-matrix block (`_Blocks`): its deposition model,
    samples, brush-on, dwell and knot basis b, and the fitted points' key."""
    h = hashlib.blake2b(points_key, digest_size=20)
    h.update(repr(sorted(app.to_dict().items())).encode())     # exact floats (round trip)
    for arr in (p.positions, p.spray_axes, p.travel_dirs, p.paint_on, p.dwell_s(), b.data,
                b.indices, b.indptr, np.asarray(b.shape)):
        a = np.ascontiguousarray(arr)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.digest()



def _film_matrix(apps: list[Applicator], passes: list[PassPlan], basis: list[sp.csr_matrix],
                 points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(N, K) film [m] at each point per unit slowness of each knot (planned dwell); apps: the
    deposition model of each pass. Each pass's block is kept (`_BLOCKS`) for the next fit."""
    k_total = sum(b.shape[1] for b in basis)
    out = np.zeros((len(points), k_total))
    pts = np.ascontiguousarray(points, float)
    nrm = np.ascontiguousarray(normals, float)
    points_key = hashlib.blake2b(pts.tobytes() + nrm.tobytes(), digest_size=20).digest()
    col = 0
    for app, p, b in zip(apps, passes, basis, strict=True):
        key = _block_key(app, p, b, points_key)
        block = _BLOCKS.get(key)
        if block is None:
            block = np.zeros((len(points), b.shape[1]))
            on = np.flatnonzero(p.paint_on)
            dB = sp.diags(p.dwell_s()) @ b                     # (M, K_p) dwell per knot [s]
            for i in range(0, len(on), _BLOCK):
                idx = on[i:i + _BLOCK]
                rate = deposition_rate(app, p.positions[idx], p.spray_axes[idx],
                                       p.travel_dirs[idx], points, normals)   # (s, N) [m/s]
                block += (dB[idx].T @ rate).T
            _BLOCKS.put(key, block)
        out[:, col:col + b.shape[1]] = block
        col += b.shape[1]
    return out


def _second_diff(k: int) -> sp.csr_matrix:
    if k < 3:
        return sp.csr_matrix((0, k))
    return sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(k - 2, k), format="csr")


def refine_speeds(app: Applicator | Sequence[Applicator], surface: Surface,
                  passes: list[PassPlan], v_min_m_s: float | Sequence[float],
                  v_max_m_s: float | Sequence[float], interior: np.ndarray,
                  caps_m_s: list[np.ndarray | None] | None = None,
                  pass_time_weight: float = 0.0,
                  paint_free: Sequence[bool] | None = None,
                  edge_weight: float = 1.0, vertex_weight: np.ndarray | None = None
                  ) -> tuple[list[PassPlan], dict[str, Any]]:
    """Passes re-timed so the simulated film on `surface` is as even as the bounds allow.

    app: the deposition model, or one per pass (passes of several parts at their own flows,
    `refine_together`); surface: the real part (film judged on every vertex, area weighted: a
    vertex of zero area is not judged); passes: the plan's passes in execution order;
    v_min_m_s / v_max_m_s: speed bounds [m/s], or one per pass; interior: (N,) bool, the
    vertices away from the boundary (the result must not be worse there either); caps_m_s: per
    pass (M,) robot speed caps [m/s] or None;
    pass_time_weight: weight of each pass's duration staying as planned (relative squared
    change, added to the fit; 0: free) — robots that sweep in step keep their pace
    (`refine_parts`);
    paint_free: per pass, whether the fit may take its paint down to none (a relaxed fit that
    asks how much a pass is wanted, `refine_together`): its knots range from zero slowness up,
    with no pull toward the planned speed nor its duration, and the mean film is that of the
    other passes; info["paint_share"] then gives, per such pass and sample ((M,), interpolated
    from its knots), each knot's fitted slowness over its slowness at the top speed of the most
    constrained sample it carries: the share of that film it wants (a knot over a stretch the
    robot caps reads against the cap, so a capped stretch is wanted less than its free samples
    would be); the speeds returned for such a pass mean nothing;
    edge_weight: the fit's weight of the vertices off the interior, relative to their areas
    (the interior's is 1, or more while `INTERIOR_WEIGHTS` are tried); vertex_weight: (N,) a
    further weight of each vertex in the fit, × the above (None: 1; `refine_body` weighs a
    body's worst part more); σ/μ is judged by area alone, whatever the fit weighed.
    Returns the passes (unchanged when refining does not lower σ/μ on both the whole part and
    the interior) and an info dict (σ/μ before/after [%], cycle change [s], knots).
    """
    V, N, a = surface.vertices, surface.normals, surface.vertex_areas
    caps = caps_m_s or [None] * len(passes)
    apps = _per_pass(app, len(passes), "applicators")
    v_lo = _per_pass(v_min_m_s, len(passes), "v_min_m_s")
    v_hi = _per_pass(v_max_m_s, len(passes), "v_max_m_s")
    free = [False] * len(passes) if paint_free is None else [bool(f) for f in paint_free]

    def nsd(f: np.ndarray, m: np.ndarray | None = None) -> float:
        w = a if m is None else a * m
        mean = np.dot(w, f) / w.sum()
        return 100.0 * float(np.sqrt(np.dot(w, (f - mean) ** 2) / w.sum()) / mean)

    def film_of(ps: list[PassPlan]) -> np.ndarray:      # the paint-free passes left out
        return _plan_film(apps, [replace(p, paint_on=np.zeros_like(p.paint_on)) if f else p
                                 for p, f in zip(ps, free, strict=True)], V, N)

    film0 = film_of(passes)
    info: dict[str, Any] = {"nsd_before_pct": nsd(film0),
                            "interior_before_pct": nsd(film0, interior), "applied": False}
    # Where the planned speeds exceed the robot's caps the robot paints the capped speeds: the
    # refinement starts from that timing and must beat its film (the plan's own is out of reach).
    tops = [_top(p, c, hi) for p, c, hi in zip(passes, caps, v_hi, strict=True)]
    if any(np.any(p.speeds_m_s > t) for p, t in zip(passes, tops, strict=True)):
        passes = [_retimed(p, np.minimum(p.speeds_m_s, t))
                  for p, t in zip(passes, tops, strict=True)]
        film0 = film_of(passes)
        info.update(nsd_capped_pct=nsd(film0), interior_capped_pct=nsd(film0, interior))
    before = (nsd(film0), nsd(film0, interior))
    mu = float(np.dot(a, film0) / a.sum())
    if not mu > 0:
        info["reason"] = "no film on the part"
        return passes, info
    basis, lo, hi = [], [], []
    for p, top, lo_v in zip(passes, tops, v_lo, strict=True):
        b, k = _knot_basis(arc_length(p.positions), KNOT_SPACING_M)
        basis.append(b)
        # s ≥ v/top and s ≤ v/v_min at every sample a knot carries (s = 1 is inside: v ≤ top)
        s_lo, s_hi = p.speeds_m_s / top, p.speeds_m_s / min(lo_v, float(top.min()))
        bc = b.tocsc()
        for j in range(k):
            rows = bc.indices[bc.indptr[j]:bc.indptr[j + 1]]
            if len(rows) == 0:          # a knot between two far-apart samples: it carries none
                lo.append(1.0 - 1e-6)
                hi.append(1.0 + 1e-6)
                continue
            lo.append(float(s_lo[rows].max()))
            hi.append(float(max(s_hi[rows].min(), lo[-1] + 1e-6)))
    lo_a, hi_a = np.asarray(lo), np.asarray(hi)
    knot_pass = np.concatenate([np.full(b.shape[1], i) for i, b in enumerate(basis)])
    free_k = np.asarray(free, bool)[knot_pass]
    top_lo = lo_a.copy()                # the slowness at the top speed
    lo_a = np.where(free_k, 0.0, lo_a)
    n_k = sum(b.shape[1] for b in basis)
    stride = max(1, int(np.ceil(len(V) * n_k / MAX_FIT_ENTRIES)))
    fit = np.arange(0, len(V), stride)
    M = _film_matrix(apps, passes, basis, V[fit], N[fit])
    info.update(knots=int(n_k), fit_vertices=int(len(fit)))
    problem = _FitProblem(apps=apps, passes=passes, basis=basis, tops=tops, areas=a, fit=fit,
                          interior=interior, mu=mu, M=M, lo=lo_a, hi=hi_a,
                          v_min_m_s=v_lo, pass_time_weight=pass_time_weight,
                          vertices=V, normals=N, free=np.asarray(free, bool),
                          keep_target=np.where(free_k, 0.0, 1.0), edge_weight=edge_weight,
                          vertex_weight=vertex_weight)
    # Fitted with the interior weighted 1×; if the result lowers σ/μ on the whole part but not
    # on its interior, fitted again with the interior weighted more (INTERIOR_WEIGHTS): the fit
    # trades some of the edge's gain for the interior, and the first that lowers both is kept.
    tried = []
    for w_int in INTERIOR_WEIGHTS:
        out, film, s, solver, dt = _fit(problem, w_int)
        after = (nsd(film), nsd(film, interior))
        tried.append({"interior_weight": w_int, "nsd_pct": after[0], "interior_pct": after[1]})
        if any(free):       # a relaxed fit: its shares are the answer, not its acceptance
            break
        if after[0] < before[0] and after[1] <= before[1]:
            break
        if not after[0] < before[0]:       # no gain on the whole part: more weight won't help
            break
    if any(free):     # per knot, then interpolated to the samples (docstring)
        share = s / np.maximum(top_lo, 1e-12)
        info["paint_share"] = {i: basis[i] @ share[knot_pass == i]
                               for i in np.flatnonzero(free).tolist()}
    info.update(nsd_after_pct=after[0], interior_after_pct=after[1], solver=solver,
                slowness_range=[float(s.min()), float(s.max())], cycle_change_s=dt,
                interior_weights_tried=tried)
    if not after[0] < before[0]:
        info["reason"] = "no lower σ/μ on the whole part"
        return passes, info
    if not after[1] <= before[1]:
        info["reason"] = "no lower σ/μ on the interior at any interior weight"
        return passes, info
    info["applied"] = True
    return out, info


@dataclass(frozen=True)
class _FitProblem:
    """What every fit of `refine_speeds` shares: each pass's deposition model, the passes
    (execution order) and their knot bases, each sample's top speed [m/s], the vertices' areas
    [m²], the fitted vertices' indices `fit` and film matrix `M` (film [m] per unit knot
    slowness), the interior mask, the mean film mu [m], the knots' slowness bounds lo / hi, each
    pass's v_min_m_s [m/s], the pass-time weight, the part's vertices and normals (the film
    judged on all of them), which passes are paint-free (`refine_speeds`), each knot's
    target of the pull toward the planned speed (1; 0 on a paint-free pass) and the fit's
    weight of the vertices off the interior (`edge_weight`, × their areas) and of every vertex
    (`vertex_weight`, None: 1)."""

    apps: list[Applicator]
    passes: list[PassPlan]
    basis: list[sp.csr_matrix]
    tops: list[np.ndarray]
    areas: np.ndarray
    fit: np.ndarray
    interior: np.ndarray
    mu: float
    M: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    v_min_m_s: list[float]
    pass_time_weight: float
    vertices: np.ndarray
    normals: np.ndarray
    free: np.ndarray
    keep_target: np.ndarray
    edge_weight: float = 1.0
    vertex_weight: np.ndarray | None = None


def _fit(pb: _FitProblem, w_int: float
         ) -> tuple[list[PassPlan], np.ndarray, np.ndarray, str, float]:
    """One bounded least-squares fit of the knot slownesses (module doc) with the interior
    vertices' area weights multiplied by w_int (the others' by the problem's edge_weight): the
    re-timed passes, their film on every vertex [m], the slownesses, how the solver ended
    (`bounded_minimum`) and the cycle change [s]."""
    passes, basis, fit, mu, pass_time_weight = pb.passes, pb.basis, pb.fit, pb.mu, \
        pb.pass_time_weight
    n_k = len(pb.lo)
    wa = pb.areas[fit] * np.where(pb.interior[fit], w_int, pb.edge_weight)
    if pb.vertex_weight is not None:
        wa = wa * pb.vertex_weight[fit]
    rw = np.sqrt(wa / wa.sum()) / mu
    # The normal equations of ‖A s − b‖² (A: the weighted film rows, the smoothing, the pull
    # toward the planned speeds and the held durations stacked): H = AᵀA, g = Aᵀb. With
    # the QP ½ sᵀHs − gᵀs in the bounds is ‖A s − b‖² / 2 + const (a few hundred to a thousand
    # knots). The pull toward the planned speeds keeps H's eigenvalues ≥ KEEP_WEIGHT: strictly
    # convex, one minimiser (`bounded_minimum`).
    Mw = pb.M * rw[:, None]
    H = Mw.T @ Mw
    g = Mw.T @ (rw * mu)
    col = 0
    for b in basis:
        k = b.shape[1]
        d2 = _second_diff(k)
        if d2.shape[0]:
            H[col:col + k, col:col + k] += SMOOTH_WEIGHT * (d2.T @ d2).toarray()
        col += k
    H[np.diag_indices(n_k)] += KEEP_WEIGHT
    g += KEEP_WEIGHT * pb.keep_target
    if pass_time_weight > 0:          # a pass's new duration is Σ dwell · slowness
        rows, col = np.zeros((len(passes), n_k)), 0
        for i, (p, b) in enumerate(zip(passes, basis, strict=True)):
            rows[i, col:col + b.shape[1]] = (p.dwell_s() @ b) / max(p.times_s[-1] - p.times_s[0],
                                                                    1e-12)
            col += b.shape[1]
        held = rows[~pb.free]           # a paint-free pass's slowness is not its duration
        H += pass_time_weight * (held.T @ held)
        g += pass_time_weight * held.sum(axis=0)
    s, solver = bounded_minimum(H, g, pb.lo, pb.hi)
    out, dt = [], 0.0
    col = 0
    for p, b, top, lo_v in zip(passes, basis, pb.tops, pb.v_min_m_s, strict=True):
        k = b.shape[1]
        with np.errstate(divide="ignore"):        # a paint-free knot at zero: the top speed
            q = _retimed(p, np.clip(p.speeds_m_s / (b @ s[col:col + k]), np.minimum(lo_v, top),
                                    top))
        col += k
        dt += float(q.times_s[-1] - p.times_s[-1])
        out.append(q)
    # the rebuilt timing (trapezoid dwell, clipped speeds) judged by the film itself
    return out, _plan_film(pb.apps, out, pb.vertices, pb.normals), s, solver, dt


def bounded_minimum(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray
                    ) -> tuple[np.ndarray, str]:
    """The minimiser of ½ sᵀHs − gᵀs for lo ≤ s ≤ hi (H symmetric positive definite, K × K:
    one minimiser) and how it was found: "unbounded" (H⁻¹g, inside the bounds), "osqp" (the
    bounds OSQP holds active, solved exactly on the others and checked against the optimality
    conditions: 10-20× faster than bounded-variable least squares on the seed-1 SUV body's 1244
    knots, the same slownesses to ~1e-13), or "bvls" (`scipy.optimize.lsq_linear` on the
    Cholesky triangle where the check fails: H = L Lᵀ, ‖Lᵀ s − L⁻¹ g‖² = 2 (½ sᵀHs − gᵀs)
    + const)."""
    L = cholesky(H, lower=True)
    c = solve_triangular(L, g, lower=True)
    s = solve_triangular(L.T, c, lower=False)
    if np.all((s >= lo) & (s <= hi)):
        return s, "unbounded"
    m = osqp.OSQP()
    m.setup(sp.csc_matrix(np.triu(H)), -g, sp.identity(len(g), format="csc"), lo, hi,
            verbose=False, eps_abs=1e-10, eps_rel=1e-10, max_iter=20000, polishing=False)
    sol = m.solve(raise_error=False)
    if sol.x is not None and np.all(np.isfinite(sol.x)) and np.all(np.isfinite(sol.y)):
        # OSQP's own polish rule for which bounds are active: y < 0 lower, y > 0 upper
        s = _kkt_minimum(H, g, lo, hi, sol.x - lo < -sol.y, hi - sol.x < sol.y)
        if s is not None:
            return s, "osqp"
    res = lsq_linear(L.T, c, bounds=(lo, hi), method="bvls")
    return np.clip(res.x, lo, hi), "bvls"


def _kkt_minimum(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 at_lo: np.ndarray, at_hi: np.ndarray) -> np.ndarray | None:
    """The minimiser of ½ sᵀHs − gᵀs in lo ≤ s ≤ hi if it holds exactly the bounds at_lo /
    at_hi (boolean masks): those fixed, the rest solved exactly; None unless the solution
    meets the optimality conditions (the free ones inside their bounds to 1e-10 of the largest
    |s|, the gradient pointing out of every held bound to 1e-9 of the problem's scale)."""
    free = ~(at_lo | at_hi)
    s = np.where(at_lo, lo, np.where(at_hi, hi, 0.0))
    if free.any():
        Lf = cholesky(H[np.ix_(free, free)], lower=True)
        r = g[free] - H[np.ix_(free, ~free)] @ s[~free]
        s[free] = solve_triangular(Lf.T, solve_triangular(Lf, r, lower=True), lower=False)
    grad = H @ s - g
    tol = 1e-9 * max(float(np.abs(g).max()), float(np.abs(H).max() * np.abs(s).max()))
    tol_s = 1e-10 * max(1.0, float(np.abs(s).max()))
    if np.any(s[free] < lo[free] - tol_s) or np.any(s[free] > hi[free] + tol_s) or \
            np.any(grad[at_lo] < -tol) or np.any(grad[at_hi] > tol):
        return None
    return np.clip(s, lo, hi)


def _top(p: PassPlan, cap: np.ndarray | None, v_max_m_s: float) -> np.ndarray:
    """(M,) highest speed each sample of the pass may take [m/s]."""
    return np.full(len(p.speeds_m_s), v_max_m_s) if cap is None else np.minimum(v_max_m_s, cap)


def _retimed(p: PassPlan, speeds_m_s: np.ndarray) -> PassPlan:
    return replace(p, speeds_m_s=speeds_m_s, times_s=times_from_speeds(p.positions, speeds_m_s))


def _per_pass(x: Any, n: int, what: str) -> list[Any]:
    """x as a list of one per pass: a single value repeated n times, else the n given."""
    if isinstance(x, Applicator) or np.ndim(x) == 0:
        return [float(x) if not isinstance(x, Applicator) else x] * n
    out = list(x)
    if len(out) != n:
        raise ValueError(f"{what}: {len(out)} given for {n} passes")
    return out


def _plan_film(apps: list[Applicator], passes: list[PassPlan], points: np.ndarray,
               normals: np.ndarray) -> np.ndarray:
    """(N,) film [m] of the passes' brush-on samples at their planned timing, each pass at its
    own deposition model (passes of equal models summed in one call: the same sums whether the
    parts share one model object or each holds an equal copy, as plans made on workers do)."""
    models: list[Applicator] = []
    for a in apps:                                     # a model per part: a few
        if not any(a is m or a == m for m in models):
            models.append(a)
    out = np.zeros(len(points))
    for app in models:
        mine = [p for a, p in zip(apps, passes, strict=True) if a is app or a == app]
        gun = GunSamples(
            positions=np.concatenate([p.positions[p.paint_on] for p in mine]),
            spray_axes=np.concatenate([p.spray_axes[p.paint_on] for p in mine]),
            travel_dirs=np.concatenate([p.travel_dirs[p.paint_on] for p in mine]),
            dwell_s=np.concatenate([p.dwell_s()[p.paint_on] for p in mine]))
        out += thickness(app, gun, points, normals)
    return out
