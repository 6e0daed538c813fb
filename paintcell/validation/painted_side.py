"""Which pieces of a part were painted and judged, and the check that no part of the painted
side was left out.

A part file's pieces, as the import chose them (`paintcell.surface.part_import`, recorded in
`PartRegions.pieces`): each with its area [m²], painted or not, and why; a closed solid's back
(inner) skin is among the unpainted. The check: the area of the pieces `pieces = "auto"` would
paint (close to the part, facing its painted side, not hidden, not a stray bit) that the
scenario's `pieces` left out must be zero; a judged region smaller than the painted side is no
PASS.
"""

from __future__ import annotations

from typing import Any

from paintcell.surface.surface_data import Surface
from paintcell.validation.validate_report import Check

__all__ = ["painted_side_checks", "painted_side_metrics", "parts_painted_side"]


def painted_side_metrics(surface: Surface) -> dict[str, Any]:
    """`pieces` (the records), `painted_area_m2` / `not_painted_area_m2` (summed over them),
    `judged_area_m2` (the faces of the judged regions) and `painted_side_left_out_m2`; empty for
    a surface without regions (a library part: all of it is judged)."""
    regs = surface.regions
    if regs is None or not regs.pieces:
        return {}
    from paintcell.surface.regions import face_areas

    pieces = [dict(p) for p in regs.pieces]
    return {
        "pieces": pieces,
        "painted_area_m2": sum(float(p["area_m2"]) for p in pieces if p["painted"]),
        "not_painted_area_m2": sum(float(p["area_m2"]) for p in pieces if not p["painted"]),
        "judged_area_m2": float(face_areas(surface.vertices,
                                           surface.faces[regs.face_mask()]).sum()),
        "painted_side_left_out_m2": sum(float(p["area_m2"]) for p in pieces
                                        if p["on_painted_side"] and not p["painted"]),
    }


def painted_side_checks(m: dict[str, Any]) -> list[Check]:
    """The check "painted side left out" (≤ 0 m²), naming the pieces; none without pieces."""
    if "painted_side_left_out_m2" not in m:
        return []
    v = float(m["painted_side_left_out_m2"])
    ok = v <= 0.0
    detail = "" if ok else (
        "pieces " + ", ".join(f"{p['piece']} ({float(p['area_m2']):.3f} m²)" for p in m["pieces"]
                              if p["on_painted_side"] and not p["painted"])
        + " face the painted side but are not painted; write [part] pieces = \"auto\"")
    return [Check(name="painted side left out", value=v, limit=0.0, unit="m²", passed=ok,
                  kind="max", detail=detail)]


def parts_painted_side(parts: dict[str, Surface]) -> dict[str, Any]:
    """`painted_side_metrics` of several parts (a booth's body) as one: every part's records,
    each piece named "<part> <piece>", areas summed; empty when no part has pieces."""
    pieces: list[dict[str, Any]] = []
    out: dict[str, Any] = {}
    for name, surf in parts.items():
        m = painted_side_metrics(surf)
        if not m:
            continue
        pieces += [{**p, "piece": f"{name} {p['piece']}"} for p in m["pieces"]]
        for k in ("painted_area_m2", "not_painted_area_m2", "judged_area_m2",
                  "painted_side_left_out_m2"):
            out[k] = out.get(k, 0.0) + float(m[k])
    return {"pieces": pieces, **out} if pieces else {}
