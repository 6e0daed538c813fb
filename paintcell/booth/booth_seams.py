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

Per seam (`Booth.seam_shares = "per seam"`, `per_seam_shares`): a seam is a pair of parts, and a
brush-on sample belongs to the seam with the part it paints most after its own; each seam gets
its own share. Coordinate descent from the best single share (every seam at it, the same film):
seam by seam, in order, every other share (and no blending) is tried, and the one giving the
smallest whole-body planned σ/μ over the judged area is kept when it is lower than the current
one; at most `MAX_SEAM_SWEEPS` sweeps over the seams, ending early after a sweep that changes
nothing. The body film is the sum of the parts' films and a part's film the sum of its samples'
(each sample's dwell comes from its times, not from the brush), so a trial re-evaluates only the
samples of the seam's two parts that it switches on or off.

`seam_band` marks the body's vertices near another part (the seams' film, measured apart from
each part's interior by `paintcell.booth.booth_part_film`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from paintcell.booth.booth_film import plan_gun_in_body
from paintcell.coverage.patches import SEAM_SHARES, ownership_brush_off, seam_volumes
from paintcell.coverage.plan import CoveragePlan, PassPlan
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate, thickness
from paintcell.paint.deposition_samples import GunSamples
from paintcell.paint.metrics import uniformity
from paintcell.surface.surface_data import Surface

#: a vertex is in a seam band when another part's nearest vertex lies within this [m]: about a
#: bell footprint's half-width, the reach of the neighbour's edge passes and overspray.
SEAM_BAND_M = 0.10
#: per-seam shares: at most this many coordinate-descent sweeps over the seams.
MAX_SEAM_SWEEPS = 3


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
                     judged: np.ndarray | None = None, per_seam: bool = False
                     ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """The plans with the samples that paint other parts more than their own switched off
    (module doc), and a record {rule, seam_shares, share, nsd by share, samples switched off per
    part}; per_seam: each seam's share then chosen by `per_seam_shares` (its record added).

    body: the parts' surfaces merged in the body frame
    (`paintcell.booth.booth_film.merge_surfaces`, parts
    stacked in order, part_counts vertices each); plans: per part, in its part frame;
    judged: (N,) bool, the body's vertices the film is judged on
    (`paintcell.booth.booth_film.judged_body_mask`; None: every vertex).
    """
    offs = np.cumsum([0, *part_counts])
    vols, nbrs = [], []
    for k, (plan, T) in enumerate(zip(plans, T_body_parts, strict=True)):   # a few parts
        own = np.zeros(len(body.vertices), bool)
        own[offs[k]:offs[k + 1]] = True
        moved = [pass_in_body(p, T) for p in plan.passes]
        if per_seam:
            v3 = part_volumes(plan.applicator, moved, own, body, part_counts)
            vols.append([(a, b) for a, b, _ in v3])
            nbrs.append([c for _, _, c in v3])
        else:
            vols.append(seam_volumes(plan.applicator, moved, own, body))

    def blended(share: float) -> tuple[list[CoveragePlan], list[int]]:
        out, n = [], []
        for plan, v in zip(plans, vols, strict=True):
            passes, n_off = ownership_brush_off(list(plan.passes), v, share)
            out.append(dataclasses.replace(plan, passes=tuple(passes)))
            n.append(n_off)
        return out, n

    films: dict[tuple[int, bytes], np.ndarray] = {}

    def part_film(k: int, plan: CoveragePlan) -> np.ndarray:
        """Part k's film [m] on the body with this plan of its (only paint switches here, so
        its paint-on samples name the film: a repeated one is not computed again)."""
        key = (k, np.packbits(np.concatenate([p.paint_on for p in plan.passes])).tobytes())
        if key not in films:
            films[key] = thickness(plan.applicator, plan_gun_in_body(plan, T_body_parts[k]),
                                   body.vertices, body.normals)
        return films[key]

    def body_nsd(ps: list[CoveragePlan]) -> float:
        film = sum(part_film(k, p) for k, p in enumerate(ps))
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
    rec = {"rule": "samples painting other parts more than share × their own switched off; "
                   "share: the smallest whole-body σ/μ",
           "seam_shares": "one", "share": best_s, "body_planned_nsd_pct": best_nsd,
           "unblended_planned_nsd_pct": unblended, "nsd_by_share_pct": tried,
           "samples_switched_off": dict(zip(names, n, strict=True))}
    if not per_seam:
        return out, rec
    return per_seam_shares(body, plans, T_body_parts, vols, nbrs, names, judged, best_s, rec,
                           part_film)


def part_volumes(app: Applicator, passes: list[PassPlan], own: np.ndarray, body: Surface,
                 part_counts: list[int]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per pass (in the body frame, of the part whose vertices are `own`): the film volume rates
    [m³/s] each sample puts on its own part and on the others (as
    `paintcell.coverage.patches.seam_volumes`), and the index of the other part it paints most
    (-1: none)."""
    part_of = np.repeat(np.arange(len(part_counts)), part_counts)
    w = np.zeros((len(body.vertices), len(part_counts)))
    w[np.arange(len(part_of)), part_of] = np.where(own, 0.0, body.vertex_areas)
    w_own = np.where(own, body.vertex_areas, 0.0)
    w_other = np.where(own, 0.0, body.vertex_areas)
    out = []
    for p in passes:                        # tens of passes
        rate = deposition_rate(app, p.positions, p.spray_axes, p.travel_dirs, body.vertices,
                               body.normals)
        by_part = rate @ w
        nbr = np.where(by_part.max(axis=1) > 0, by_part.argmax(axis=1), -1)
        out.append((rate @ w_own, rate @ w_other, nbr))
    return out


def per_seam_shares(body: Surface, plans: list[CoveragePlan], T_body_parts: list[np.ndarray],
                    vols: list[list[tuple[np.ndarray, np.ndarray]]],
                    nbrs: list[list[np.ndarray]], names: list[str], judged: np.ndarray | None,
                    start: float | None, rec: dict[str, Any],
                    part_film: Callable[[int, CoveragePlan], np.ndarray] | None = None
                    ) -> tuple[list[CoveragePlan], dict[str, Any]]:
    """Each seam's share by coordinate descent from the single share `start` (None: no
    blending) (module doc). vols, nbrs: per part, per pass, `part_volumes`' (own, other) and
    neighbour; rec: the single share's record, returned with {seams: share per seam, steps:
    σ/μ by accepted change, film_evaluations (the trial films asked for; a sample set asked
    for again is taken from a cache), single_share_planned_nsd_pct} added and its
    figures those of the shares chosen; converged: the last sweep changed nothing.
    part_film(k, plan): part k's film [m] on the body with the plan (None: computed here)."""
    n = len(plans)
    own_v = [np.concatenate([v[0] for v in vk]) for vk in vols]
    oth_v = [np.concatenate([v[1] for v in vk]) for vk in vols]
    nbr = [np.concatenate(nk) for nk in nbrs]
    on = [np.concatenate([p.paint_on for p in pl.passes]) for pl in plans]
    lo = min(SEAM_SHARES)
    seams = sorted({(min(k, int(j)), max(k, int(j))) for k in range(n)
                    for j in np.unique(nbr[k][on[k] & (nbr[k] >= 0)
                                              & (oth_v[k] > lo * own_v[k])])})
    options: list[float | None] = [*SEAM_SHARES, None]
    shares: dict[tuple[int, int], float | None] = dict.fromkeys(seams, start)

    def off_mask(k: int, sh: dict[tuple[int, int], float | None]) -> np.ndarray:
        tab = np.full(n + 1, np.inf)                  # index n: no neighbour
        for (a, b), x in sh.items():
            if k in (a, b) and x is not None:
                tab[b if a == k else a] = x
        s = tab[np.where(nbr[k] >= 0, nbr[k], n)]
        fin = np.isfinite(s)
        return on[k] & fin & (oth_v[k] > np.where(fin, s, 0.0) * own_v[k])

    guns = []
    for pl, T in zip(plans, T_body_parts, strict=True):     # a few parts, all samples
        R, t = T[:3, :3], T[:3, 3]
        ps = pl.passes
        guns.append((pl.applicator, np.concatenate([p.positions for p in ps]) @ R.T + t,
                     np.concatenate([p.spray_axes for p in ps]) @ R.T,
                     np.concatenate([p.travel_dirs for p in ps]) @ R.T,
                     np.concatenate([p.dwell_s() for p in ps])))
    n_eval = 0
    # a trial's film by its part and samples; the sweeps ask for many again (a seam whose parts
    # did not change since the last sweep tries the same switches): kept sparse, the nonzero
    # vertices only (a few samples paint a few bell footprints of the body)
    seen: dict[tuple[int, bytes], tuple[np.ndarray, np.ndarray]] = {}

    def film_of(k: int, keep: np.ndarray) -> np.ndarray:
        nonlocal n_eval
        out = np.zeros(len(body.vertices))
        if not keep.any():
            return out
        n_eval += 1
        key = (k, np.packbits(keep).tobytes())
        if key not in seen:
            app, pos, ax, tr, dw = guns[k]
            f = thickness(app, GunSamples(pos[keep], ax[keep], tr[keep], dw[keep]),
                          body.vertices, body.normals)
            nz = np.flatnonzero(f)
            seen[key] = (nz, f[nz])
        nz, val = seen[key]
        out[nz] = val
        return out

    def nsd(films: list[np.ndarray]) -> float:
        return float(uniformity(np.sum(films, axis=0), body.vertex_areas, mask=judged).nsd_pct)

    offs = [off_mask(k, shares) for k in range(n)]
    films = [film_of(k, on[k] & ~offs[k]) for k in range(n)]
    cur = nsd(films)
    steps: list[dict[str, Any]] = [{"sweep": 0, "seam": None, "share": start,
                                    "body_planned_nsd_pct": cur}]
    label = {e: f"{names[e[0]]}|{names[e[1]]}" for e in seams}
    changed, sweeps = True, 0
    for sweep in range(1, MAX_SEAM_SWEEPS + 1):
        changed, sweeps = False, sweep
        for e in seams:                               # tens of seams
            best: tuple[float, Any] | None = None
            for x in options:                         # ten options
                if x == shares[e]:
                    continue
                trial = {**shares, e: x}
                cand = list(films)
                moved = []
                for k in sorted(set(e)):              # the seam's two parts
                    m = off_mask(k, trial)
                    if np.array_equal(m, offs[k]):
                        continue
                    # superposition: add the samples switched on, take off those switched off
                    cand[k] = films[k] + film_of(k, offs[k] & ~m) - film_of(k, m & ~offs[k])
                    moved.append((k, m))
                if not moved:
                    continue
                val = nsd(cand)
                if val < cur - 1e-9 and (best is None or val < best[0]):
                    best = (val, (x, cand, moved))
            if best is not None:
                cur, (x, films, moved) = best[0], best[1]
                shares[e] = x
                for k, m in moved:
                    offs[k] = m
                steps.append({"sweep": sweep, "seam": label[e], "share": x,
                              "body_planned_nsd_pct": cur})
                changed = True
        if not changed:
            break
    out = []
    for pl, m in zip(plans, offs, strict=True):
        ends = np.cumsum([len(p.paint_on) for p in pl.passes])
        passes = [dataclasses.replace(p, paint_on=p.paint_on & ~m[e0 - len(p.paint_on):e0])
                  if m[e0 - len(p.paint_on):e0].any() else p
                  for p, e0 in zip(pl.passes, ends, strict=True)]
        out.append(dataclasses.replace(pl, passes=tuple(passes)) if any(
            q is not p for q, p in zip(passes, pl.passes, strict=True)) else pl)
    if part_film is None:
        def part_film(k: int, plan: CoveragePlan) -> np.ndarray:
            return thickness(plan.applicator, plan_gun_in_body(plan, T_body_parts[k]),
                             body.vertices, body.normals)
    final = float(uniformity(sum(part_film(k, p) for k, p in enumerate(out)),
                             body.vertex_areas, mask=judged).nsd_pct)
    return out, {**rec, "rule": "per seam (a pair of parts; a sample's seam: the part it paints "
                               "most after its own): samples painting other parts more than the "
                               "seam's share × their own switched off; shares by coordinate "
                               "descent from the best single share, a change kept when the "
                               "whole-body σ/μ drops",
                 "seam_shares": "per seam", "single_share_planned_nsd_pct":
                     rec["body_planned_nsd_pct"], "body_planned_nsd_pct": final,
                 "seams": {label[e]: shares[e] for e in seams}, "steps": steps,
                 "film_evaluations": n_eval, "sweeps": sweeps, "converged": not changed,
                 "samples_switched_off": {nm: int(m.sum()) for nm, m in
                                          zip(names, offs, strict=True)}}
