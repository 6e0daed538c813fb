"""A real part file → a paintable `Surface` with regions, and a report of every choice made.

read (trimesh / OCCT) → units (explicit or inferred, size checked) → repair (pymeshlab) → pieces
(connected, numbered by decreasing area; `pieces = "auto"` paints the largest with every piece
close to it that faces its painted side, `paintcell.surface.pieces`; each piece recorded, painted
or not and why) → painted side (given, or the convex side) → regions
(skin, hems, inner panels, back side; the back side of a closed or double-sided shell is
dropped) → small holes filled → isotropic remesh of each region to the scenario resolution.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import trimesh

from paintcell.core.budget import check_surface_budget
from paintcell.core.errors import SurfaceError
from paintcell.surface.mesh_io import UnitChoice, choose_units, read_part_file
from paintcell.surface.mesh_repair import RepairReport, fill_small_holes, remesh, repair
from paintcell.surface.mesh_thinning import thin_for_resolution
from paintcell.surface.part_spec import MeshPart
from paintcell.surface.pieces import choose_pieces
from paintcell.surface.regions import (
    BACK,
    EDGE,
    SKIN,
    Opening,
    PartRegions,
    classify_faces,
    face_areas,
    find_openings,
)
from paintcell.surface.surface_data import Surface, surface_from_triangles

__all__ = ["ImportReport", "PieceInfo", "import_part", "split_pieces"]


@dataclass(frozen=True)
class PieceInfo:
    """One connected piece of the file: index (by decreasing area), faces, area [m²], size [m];
    painted: kept in the part; why: why it was kept or left out; on_side: a piece
    `pieces = "auto"` joins (close, facing the painted side, not hidden, not a stray bit), so
    leaving it out leaves part of the painted side unpainted."""

    index: int
    n_faces: int
    area_m2: float
    extent_m: tuple[float, ...]
    painted: bool = False
    why: str = ""
    on_side: bool = False

    def record(self) -> dict[str, Any]:
        """JSON-safe record for the verdict (`PartRegions.pieces`)."""
        return {"piece": str(self.index), "area_m2": self.area_m2, "painted": self.painted,
                "why": self.why, "on_painted_side": self.on_side}


@dataclass(frozen=True, eq=False)
class ImportReport:
    """What `import_part` found and chose (for `paintcell inspect` and `init`)."""

    spec: MeshPart
    fmt: str
    units: UnitChoice
    extent_m: tuple[float, ...]
    pieces: tuple[PieceInfo, ...]
    selected: tuple[int, ...]
    painted_direction: tuple[float, ...]
    side_reason: str
    repair: RepairReport
    closed_shell: bool
    region_areas_m2: dict[str, float]
    openings: tuple[Opening, ...]
    area_before_remesh_m2: float
    area_after_remesh_m2: float
    resolution_m: float | None
    mean_curvature_range_1_m: tuple[float, float]


def _submesh(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used, inv = np.unique(f, return_inverse=True)
    return v[used], inv.reshape(-1, 3).astype(np.int64)


#: Largest relative area change an isotropic remesh may make before it is redone finer [-].
REMESH_AREA_RTOL = 0.005


def _remesh_keeping_area(v: np.ndarray, f: np.ndarray, target_m: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Remesh at `target_m`, halving it (up to 3 times) while the area moves by more than
    `REMESH_AREA_RTOL` (features smaller than the target: a narrow strip, a tiny part)."""
    a0 = float(face_areas(v, f).sum())
    for _ in range(4):
        rv, rf = remesh(v, f, target_m)
        if abs(float(face_areas(rv, rf).sum()) / a0 - 1.0) <= REMESH_AREA_RTOL:
            return rv, rf
        target_m /= 2.0
    return v, f   # no remesh keeps the area: keep the repaired tessellation


def split_pieces(v: np.ndarray, f: np.ndarray) -> list[np.ndarray]:
    """Face-index arrays of the edge-connected pieces, by decreasing area (ties: lowest face)."""
    m = trimesh.Trimesh(v, f, process=False)
    groups = trimesh.graph.connected_components(m.face_adjacency, nodes=np.arange(len(f)),
                                                min_len=1)
    a = face_areas(v, f)
    groups = [np.sort(np.asarray(g)) for g in groups]
    return sorted(groups, key=lambda g: (-float(a[g].sum()), int(g[0])))


def _convexity(m: trimesh.Trimesh) -> float:
    """Σ edge length × dihedral angle, + where the surface bends away from its normals [m·rad]:
    positive when the faces are wound toward the convex side."""
    if len(m.face_adjacency) == 0:
        return 0.0
    e = m.vertices[m.face_adjacency_edges]
    length = np.linalg.norm(e[:, 0] - e[:, 1], axis=1)
    sign = np.where(m.face_adjacency_convex, 1.0, -1.0)
    return float(np.sum(length * m.face_adjacency_angles * sign))


def _orient(v: np.ndarray, f: np.ndarray, groups: list[np.ndarray], side: np.ndarray | None,
            raw_normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, str, bool]:
    """Wind every selected piece toward the painted side; returns faces, unit d, reason, closed."""
    f = f.copy()
    closed_any = False
    reasons = []
    for g in groups:
        m = trimesh.Trimesh(v, f[g], process=False)
        n_sum = (m.face_normals * m.area_faces[:, None]).sum(0)
        if m.is_watertight:
            closed_any = True
            if m.volume < 0:
                f[g] = f[g][:, ::-1]
        elif side is not None:
            if n_sum @ side < 0:
                f[g] = f[g][:, ::-1]
        else:
            c = _convexity(m)
            diag = float(np.linalg.norm(m.extents))
            if abs(c) > 1e-3 * diag:
                if c < 0:
                    f[g] = f[g][:, ::-1]
                reasons.append("the convex side")
            else:
                if n_sum @ raw_normal < 0:
                    f[g] = f[g][:, ::-1]
                reasons.append("flat part: the side the file's normals mostly face")
    main = trimesh.Trimesh(v, f[groups[0]], process=False)
    if side is not None:
        return f, side, "set in the scenario (side)", closed_any
    if main.is_watertight:
        # Closed shell: the skin is the convex side of its thinnest axis, judged on the faces
        # within 60° of it (the rim between the two skins meets both at convex edges, and a
        # thin solid's long rim would outweigh the skins' own curvature).
        w, vec = np.linalg.eigh(np.cov((main.vertices[np.unique(main.faces)]).T))
        axis = vec[:, 0]
        scores = []
        for s in (1.0, -1.0):
            keep = (main.face_normals @ (s * axis)) > 0.5
            sub = trimesh.Trimesh(main.vertices, main.faces[keep], process=False)
            scores.append(_convexity(sub) if keep.any() else -np.inf)
        d = axis if scores[0] >= scores[1] else -axis
        return f, d, "closed shell: the convex side of its thinnest axis", True
    n_sum = (main.face_normals * main.area_faces[:, None]).sum(0)
    d = n_sum / max(float(np.linalg.norm(n_sum)), 1e-300)
    return f, d, "auto: " + (reasons[0] if reasons else "the convex side"), closed_any


def import_part(spec: MeshPart, resolution_m: float | None = 0.01,
                setting: str = "resolution_m") -> tuple[Surface, ImportReport]:
    """Read, check, repair, orient, classify and remesh a part file (see the module docstring).

    resolution_m: target edge length of the isotropic remesh [m]; None keeps the repaired
    tessellation. setting: the name of resolution_m in the caller's input, for the budget's
    error. Raises SurfaceError (BudgetError for a surface too fine to fit in memory) with a
    one-line fix on any bad file or setting; MeshLab's own failures are named with the file.
    """
    import pymeshlab

    try:
        return _import_part(spec, resolution_m, setting)
    except SurfaceError as exc:      # every refusal names the file
        if str(spec.file) in str(exc):
            raise
        raise SurfaceError(f"{spec.file}: {exc}") from exc
    except pymeshlab.PyMeshLabException as exc:
        msg = (str(exc).strip().splitlines() or ["no message"])[0]
        raise SurfaceError(f"mesh {spec.file} cannot be repaired ({msg}); re-export the part "
                           "surface from your CAD/scan tool") from exc


def _import_part(spec: MeshPart, resolution_m: float | None, setting: str
                 ) -> tuple[Surface, ImportReport]:
    import pymeshlab

    raw = read_part_file(spec.file, spec.chord_tolerance_m)
    units = choose_units(np.ptp(raw.vertices, axis=0), spec.units, raw.cad)
    v0 = raw.vertices * units.scale_m
    f_raw = raw.faces
    if resolution_m is not None:
        check_surface_budget(float(face_areas(v0, f_raw).sum()), resolution_m, setting,
                             spec.file)
    n_file = len(f_raw)
    v_thin, f_thin, cell = thin_for_resolution(v0, f_raw, resolution_m)
    try:
        v, f, rep = repair(v_thin, f_thin)
        v0, f_raw = v_thin, f_thin
    except pymeshlab.PyMeshLabException:
        if cell is None:
            raise
        # vertex clustering can fold a scan's thin features into faces MeshLab cannot orient
        # (bezier_part_scan_12_pieces): repair the file's own tessellation instead
        cell = None
        v, f, rep = repair(v0, f_raw)
    nr = np.cross(v0[f_raw[:, 1]] - v0[f_raw[:, 0]], v0[f_raw[:, 2]] - v0[f_raw[:, 0]]).sum(0)
    if cell is not None:
        rep = replace(rep, thinned_from=n_file, thin_cell_m=cell)
    groups = split_pieces(v, f)
    a = face_areas(v, f)
    side = None
    if spec.side != "auto":
        side = np.asarray(spec.side, float)
        side = side / np.linalg.norm(side)
    # which pieces belong to the part, seen from the largest one's painted side
    f_main, d_main = _orient(v, f, groups[:1], side, nr)[:2]
    choice = choose_pieces(v, f_main, groups, d_main, spec.pieces_gap_m)
    if spec.pieces == "largest":
        sel: tuple[int, ...] = (0,)
    elif spec.pieces == "auto":
        sel = choice.selected
    elif spec.pieces == "all":
        sel = tuple(range(len(groups)))
    else:
        sel = tuple(spec.pieces)  # type: ignore[arg-type]
        bad = [i for i in sel if i >= len(groups)]
        if bad:
            listing = ", ".join(f"{float(a[g].sum()):.3g} m²" for g in groups[:8])
            raise SurfaceError(f"[part] pieces = {list(sel)} but the file has {len(groups)} "
                               f"piece(s) ({listing}); write indices 0..{len(groups) - 1} or "
                               "\"auto\"")
    pieces = tuple(PieceInfo(i, len(g), float(a[g].sum()),
                             tuple(float(x) for x in np.ptp(v[np.unique(f[g])], axis=0)),
                             i in sel, _why(i, sel, choice, spec), i in choice.selected)
                   for i, g in enumerate(groups))
    f, d, side_reason, closed = _orient(v, f, [groups[i] for i in sel], side, nr)
    if spec.pieces == "auto":  # the joined pieces wound toward the largest one's painted side
        f = _wind_toward(v, f, [groups[i] for i in sel[1:]], d)
    keep = np.concatenate([groups[i] for i in sel])
    piece_of = np.empty(len(f), np.int32)
    for i, g in enumerate(groups):
        piece_of[g] = i
    f, piece_of = f[keep], piece_of[keep]
    labels = classify_faces(v, f, piece_of, d, closed=closed)
    records = [p.record() for p in pieces]
    if closed:
        back = face_areas(v, f[labels == BACK])
        for p in np.unique(piece_of[labels == BACK]):
            a_back = float(back[piece_of[labels == BACK] == p].sum())
            # the piece's record keeps its painted side; its back skin is a record of its own
            records[p] = {**records[p], "area_m2": records[p]["area_m2"] - a_back,
                          "why": records[p]["why"] + " (its painted side)"}
            records.append({"piece": f"{p} back side", "painted": False, "on_painted_side": False,
                            "area_m2": a_back,
                            "why": "the back (inner) skin of a closed solid, facing away from "
                                   "the painter"})
        f, piece_of, labels = f[labels != BACK], piece_of[labels != BACK], labels[labels != BACK]
    if not np.any(labels == SKIN):
        raise SurfaceError(f"no face of the part faces the painted side {np.round(d, 3).tolist()}"
                           "; write [part] side = [x, y, z] toward the side to paint")
    used, inv = np.unique(f, return_inverse=True)
    v, f = v[used], inv.reshape(-1, 3).astype(np.int64)
    # Openings: holes of the front (skin and its turned edges) of each piece, after small holes
    # are filled, so their loop runs where the surface turns away from the painter.
    openings: tuple[Opening, ...] = ()
    for p in np.unique(piece_of):
        pv, pf = _submesh(v, f[piece_of == p])
        openings += find_openings(pv, pf, np.isin(labels[piece_of == p], (SKIN, EDGE)),
                                  spec.fill_holes_m)
    # Fill small holes region by region, and remesh each region on its own (their borders stay).
    parts_v: list[np.ndarray] = []
    parts_f: list[np.ndarray] = []
    parts_l: list[np.ndarray] = []
    parts_p: list[np.ndarray] = []
    holes_filled = 0
    area_before = 0.0
    for lab in np.unique(labels):
        for p in np.unique(piece_of[labels == lab]):
            rv, rf = _submesh(v, f[(labels == lab) & (piece_of == p)])
            if lab == SKIN:  # scan holes; a hem strip's or lip's own loops are its outline
                rv, rf, nfill = fill_small_holes(rv, rf, spec.fill_holes_m)
                holes_filled += nfill
            area_before += float(face_areas(rv, rf).sum())
            if resolution_m is not None:
                rv, rf = _remesh_keeping_area(rv, rf, resolution_m)
            off = int(sum(len(x) for x in parts_v))
            parts_v.append(rv)
            parts_f.append(rf + off)
            parts_l.append(np.full(len(rf), lab, np.int8))
            parts_p.append(np.full(len(rf), p, np.int32))
    v, f = np.concatenate(parts_v), np.concatenate(parts_f)
    labels, piece_of = np.concatenate(parts_l), np.concatenate(parts_p)
    regions = PartRegions(face_labels=labels, face_piece=piece_of, painted_direction=d,
                          openings=tuple(sorted(openings, key=lambda o: -o.area_m2)),
                          judged=spec.judge, pieces=tuple(records))
    surf = surface_from_triangles(spec.stem, v, f)
    surf = replace(surf, regions=regions)
    skin_h = surf.mean_curvature[regions.vertex_mask(f, ("skin",))]
    report = ImportReport(
        spec=spec, fmt=raw.fmt, units=units,
        extent_m=tuple(float(x) for x in np.ptp(v0, axis=0)), pieces=pieces, selected=sel,
        painted_direction=tuple(float(x) for x in d), side_reason=side_reason,
        repair=replace(rep, holes_filled=holes_filled), closed_shell=closed,
        region_areas_m2=regions.areas_m2(v, f), openings=regions.openings,
        area_before_remesh_m2=area_before, area_after_remesh_m2=float(face_areas(v, f).sum()),
        resolution_m=resolution_m,
        mean_curvature_range_1_m=(float(np.percentile(skin_h, 1)),
                                  float(np.percentile(skin_h, 99))))
    return surf, report


def _why(i: int, sel: tuple[int, ...], choice: Any, spec: MeshPart) -> str:
    """Why piece i was painted or not (`pieces` as the scenario sets it, `choice` what "auto"
    finds)."""
    if spec.pieces != "auto":
        if i in sel:
            return f"kept by [part] pieces = {spec.pieces!r}"
        extra = "; pieces = \"auto\" paints it" if i in choice.selected else \
            f"; auto: {choice.reasons.get(i, '')}"
        return f"left out by [part] pieces = {spec.pieces!r}{extra}"
    if i == 0:
        return "the largest piece"
    if i in sel:
        return f"joined: {1e3 * choice.gaps_m[i]:.1f} mm from the part, facing its painted side"
    return str(choice.reasons.get(i, "not joined"))


def _wind_toward(v: np.ndarray, f: np.ndarray, groups: list[np.ndarray], d: np.ndarray
                 ) -> np.ndarray:
    """`f` with each open piece of `groups` wound so its area-weighted normal points along d."""
    f = f.copy()
    for g in groups:
        m = trimesh.Trimesh(v, f[g], process=False)
        if not m.is_watertight and float((m.face_normals * m.area_faces[:, None]).sum(0) @ d) < 0:
            f[g] = f[g][:, ::-1]
    return f
