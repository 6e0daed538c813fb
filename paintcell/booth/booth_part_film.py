"""Each part's film in a booth and its seams' (`paintcell.booth.booth_results` reports it).

Per part, over its judged area (a mesh part's skin; the body's vertices stack the parts in
order): σ/μ of the four films `paintcell.booth.booth_film` lays (plan, trajectory, servo,
executed), the loss of uniformity from plan to execution split by cause, the mean, least and
largest film and the share of the area inside the paint spec's window (`Booth.spec`, planned and
executed). The causes, each a difference of two measured films' σ/μ, so the three add up to
executed − planned exactly (up to float rounding):
- time law: trajectory − plan (the planned TCP path at planned speed against the joint
  trajectory's kinematic TCP at the time law's timing);
- servo: servo − trajectory (the executed TCP against the kinematic TCP, both against the body
  where the conveyor nominally puts it);
- conveyor tracking: executed − servo (the executed TCP against the body where the carrier
  really was, MuJoCo's carrier joint, against it where perfect tracking would have it: the
  nominal conveyor motion the programs were built for).

The seams: each part's vertices within `paintcell.booth.booth_seams.SEAM_BAND_M` of another part
(`seam_band`) against the rest of the part (its interior): mean film, σ/μ and share inside the
spec window of each, and the same for all seams and all interiors of the body.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.booth.booth_film import body_uniformity
from paintcell.booth.booth_seams import SEAM_BAND_M, seam_band
from paintcell.paint.metrics import MetricsError
from paintcell.surface.surface_data import Surface
from paintcell.validation.paint_spec import PaintSpec, SpecError, spec_metrics

__all__ = ["part_film_figures"]

_KINDS = ("plan", "trajectory", "servo", "executed")
_STEM = {"plan": "planned", "trajectory": "trajectory", "servo": "servo", "executed": "executed"}


def _nsd(film: np.ndarray, w: np.ndarray) -> float:
    """σ/μ [%] of film over the vertices of weight w > 0 (nan when none or nothing painted)."""
    if not np.any(w > 0):
        return float("nan")
    try:
        return body_uniformity(film, w)
    except MetricsError:
        return float("nan")


def _inside(film: np.ndarray, body: Surface, faces: np.ndarray, target_m: float,
            spec: PaintSpec) -> float:
    """Share [%] of the faces' area (mask (F,)) inside the spec window around target_m."""
    if not faces.any():
        return float("nan")
    try:
        return spec_metrics(film, body.vertices, body.faces, faces, target_m,
                            spec)["executed_inside_spec_pct"]
    except SpecError:
        return float("nan")


def _figures(tot: dict[str, np.ndarray], w: np.ndarray, body: Surface, faces: np.ndarray,
             target_m: float, spec: PaintSpec) -> dict[str, float]:
    """σ/μ of every film kind, the loss split, film mean / min / max and spec shares over the
    vertices of weight w (judged areas) and the faces `faces`."""
    out = {f"{_STEM[k]}_nsd_pct": _nsd(tot[k], w) for k in _KINDS}
    out.update({
        "loss_pp": out["executed_nsd_pct"] - out["planned_nsd_pct"],
        "loss_time_law_pp": out["trajectory_nsd_pct"] - out["planned_nsd_pct"],
        "loss_servo_pp": out["servo_nsd_pct"] - out["trajectory_nsd_pct"],
        "loss_conveyor_pp": out["executed_nsd_pct"] - out["servo_nsd_pct"],
    })
    sel = w > 0
    for k in ("plan", "executed"):
        f = tot[k]
        out[f"{_STEM[k]}_mean_um"] = (1e6 * float(f @ w / w.sum()) if sel.any()
                                      else float("nan"))
        out[f"{_STEM[k]}_inside_spec_pct"] = _inside(f, body, faces, target_m, spec)
    ex = tot["executed"][sel]
    out["executed_min_um"] = 1e6 * float(ex.min()) if sel.any() else float("nan")
    out["executed_max_um"] = 1e6 * float(ex.max()) if sel.any() else float("nan")
    return out


def _seam_figures(film: np.ndarray, w: np.ndarray, body: Surface, faces: np.ndarray,
                  band: np.ndarray, target_m: float, spec: PaintSpec) -> dict[str, float]:
    """The executed film in the seam band and in the interior of the vertices of weight w."""
    fband = band[body.faces].all(axis=1)
    out: dict[str, float] = {"seam_area_pct": (100.0 * float(w[band].sum() / w.sum())
                                               if w.sum() > 0 else float("nan"))}
    for name, vm, fm in (("seam", band, fband), ("interior", ~band, ~fband)):
        wv = w * vm
        out[f"{name}_executed_mean_um"] = (1e6 * float(film @ wv / wv.sum()) if wv.sum() > 0
                                           else float("nan"))
        out[f"{name}_executed_nsd_pct"] = _nsd(film, wv)
        out[f"{name}_executed_inside_spec_pct"] = _inside(film, body, faces & fm, target_m, spec)
    return out


def part_film_figures(body: Surface, tot: dict[str, np.ndarray], areas: np.ndarray,
                      judged_faces: np.ndarray | None, offs: np.ndarray, keys: list[str],
                      target_m: float, spec: PaintSpec) -> dict[str, Any]:
    """{"part_film": {part key: figures}, "seam_film": the body's seams and interiors,
    "seam_nsd_ratio": the seams' executed σ/μ ÷ the interiors' [-] (NaN without both),
    "seam_band_m", and the whole body's "planned_inside_spec_pct" (its planned film in the
    window), "planned_mean_um", "executed_min_um", "executed_max_um" and the executed film's
    largest and RMS difference from the planned, "max_thickness_diff_um",
    "rms_thickness_diff_um" (over the judged area)}.

    tot: the robots' films summed, kind → (N,) [m] on `body`'s vertices; areas: (N,) the judged
    vertices' areas [m²] (0 elsewhere); judged_faces: (F,) bool, the faces the spec shares are
    measured over (None: all); offs: (P + 1,) each part's first vertex, then N; keys: the parts'
    "index:name"; target_m: the spec window's centre [m] (`booth_spec_metrics`'s)."""
    faces = body.faces
    fmask = np.ones(len(faces), bool) if judged_faces is None else np.asarray(judged_faces, bool)
    band = seam_band(body.vertices, [int(offs[i + 1] - offs[i]) for i in range(len(keys))])
    parts: dict[str, dict[str, float]] = {}
    for i, key in enumerate(keys):
        w = np.zeros(len(areas))
        w[offs[i]:offs[i + 1]] = areas[offs[i]:offs[i + 1]]
        own = fmask & (faces[:, 0] >= offs[i]) & (faces[:, 0] < offs[i + 1])
        parts[key] = {**_figures(tot, w, body, own, target_m, spec),
                      **_seam_figures(tot["executed"], w, body, own, band, target_m, spec)}
    w = np.asarray(areas, float)
    whole = _figures(tot, w, body, fmask, target_m, spec)
    diff = (tot["executed"] - tot["plan"])[w > 0]
    seams = _seam_figures(tot["executed"], w, body, fmask, band, target_m, spec)
    return {"part_film": parts,
            "seam_film": seams,
            # NaN (a failed check) when the body has no seam or no interior
            "seam_nsd_ratio": seams["seam_executed_nsd_pct"] / seams["interior_executed_nsd_pct"]
            if seams["interior_executed_nsd_pct"] > 0 else float("nan"),
            "seam_band_m": SEAM_BAND_M,
            **{k: whole[k] for k in ("planned_inside_spec_pct", "planned_mean_um",
                                     "executed_min_um", "executed_max_um")},
            "max_thickness_diff_um": 1e6 * float(np.abs(diff).max()),
            "rms_thickness_diff_um": 1e6 * float(np.sqrt(diff ** 2 @ w[w > 0] / w.sum()))}
