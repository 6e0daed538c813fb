"""The strip behind a pass's extension within the surface (lengths in m).

Algorithm 1 continues each new offset pass within the surface to the boundary. Where that
extension reaches past the pass it was offset from (the part widens, or the start curve is a
short section of a part whose boundary bows toward it), the strip between the extension and the
part's boundary on the previous pass's side has no pass at the index width behind it: painted
by one pass only, it comes out thin (on `reach_hood_panel`, a 0.09 m² lobe at −48 %).
`back_fill` walks the extension's own indexing curves back by the index width and splices what
it reaches onto the end of the previous pass: on the part where the part goes on (the previous
pass is lengthened), beyond the boundary where it does not (a sideways overspray stretch, as an
edge pass gives the last pass of a family) — so every sample of a pass has a neighbour at the
index width on either side, whatever the boundary's direction.
"""

from __future__ import annotations

import numpy as np

from paintcell.coverage.coverage_planner import PassGeom, Planner, mirrored_curve
from paintcell.coverage.coverage_timing import time_pass
from paintcell.coverage.offset import indexing_curves, walk
from paintcell.coverage.offset_polyline import arc_length, resample, tangents, unit


def back_fill(pl: Planner, prev: PassGeom, new: PassGeom, sign: int, width_m: float,
              extension_m: tuple[float, float]) -> bool:
    """Lengthen `prev` by the back-offset of `new`'s extension within the surface.

    prev: the pass `new` was offset from (already timed; re-timed here when it changes);
    new: the new pass, (M, 3) samples whose first `extension_m[0]` and last `extension_m[1]`
        metres of arc length are its extension within the surface;
    sign: +1 for the sweep to the right of the start curve, −1 to the left;
    width_m: the index width between them [m]. Returns whether `prev` changed.
    """
    sp = pl.st.sample_spacing_m
    s = arc_length(new.foot)
    heads = np.flatnonzero(s < extension_m[0] - 0.5 * sp)
    tails = np.flatnonzero(s > s[-1] - extension_m[1] + 0.5 * sp)
    head = _back_piece(pl, new, heads[::-1], sign, width_m, prev.foot[::-1], prev.normals[::-1])
    tail = _back_piece(pl, new, tails, sign, width_m, prev.foot, prev.normals)
    if head is None and tail is None:
        return False
    pieces = ([] if head is None else [tuple(a[::-1] for a in head)]) \
        + [(prev.foot, prev.normals, prev.on_part)] + ([] if tail is None else [tail])
    parts_p, parts_n, parts_f = (list(x) for x in zip(*pieces, strict=True))
    foot, nrm, on = resample(np.concatenate(parts_p), np.concatenate(parts_n), sp,
                             np.concatenate(parts_f))
    added = (0.0 if head is None else float(arc_length(head[0])[-1]),
             0.0 if tail is None else float(arc_length(tail[0])[-1]))
    prev.foot, prev.normals, prev.on_part = foot, nrm, on
    if prev.edge:          # a lengthened end needs no straight continuation of its own
        prev.extra_m = (0.0 if head is not None else prev.extra_m[0],
                        0.0 if tail is not None else prev.extra_m[1])
    prev.curves, prev.timing = None, None
    prev.info.pop("feedback_mismatch", None)
    prev.info["back_fill_m"] = [round(a, 4) for a in added]
    time_pass(pl, prev, prev.width_m if np.isfinite(prev.width_m) else pl.nominal_width)
    return True


def _back_piece(pl: Planner, new: PassGeom, idx: np.ndarray, sign: int, width_m: float,
                prev_foot: np.ndarray, prev_nrm: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Points (K, 3), normals (K, 3), on-part flags (K,) beyond the end of `prev` (given with
    that end last) reached by walking `new`'s samples `idx` (ordered from `prev`'s end
    outward) back by `width_m`; None when fewer than two such points."""
    sp = pl.st.sample_spacing_m
    if len(idx) < 2 or len(prev_foot) < 3:
        return None
    t = tangents(new.foot)[idx]
    curves = indexing_curves(pl.geom, new.foot[idx], t, new.normals[idx])
    # a sample off the part has no indexing curve (as in `Planner.curves_of`)
    curves = [c if on else None for c, on in zip(curves, new.on_part[idx], strict=True)]
    if sign < 0:
        curves = [mirrored_curve(c) for c in curves]
    pts, nrm, inside = walk(curves, -width_m)
    end = prev_foot[-1]
    out = unit(end - prev_foot[-3])
    n_end = prev_nrm[-1]
    out = unit(out - (out @ n_end) * n_end)
    keep = []
    last, skipped = end, 0
    for i in range(len(pts)):                # ≤ a few dozen samples, from prev's end outward
        p = pts[i]
        if not np.all(np.isfinite(p)):       # no indexing curve there (a sample off the part):
            skipped += 1                     # bridged straight if the offset goes on after it
            continue
        if (p - end) @ out <= 0.5 * sp:      # not yet past prev's end (its own stretch)
            continue
        if np.linalg.norm(p - last) > 3.0 * sp * (skipped + 1):   # a jump: cut here
            break
        keep.append(i)
        last, skipped = p, 0
    if len(keep) < 2:
        return None
    k = np.asarray(keep)
    return pts[k], nrm[k], inside[k]
