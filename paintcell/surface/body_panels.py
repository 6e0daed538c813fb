"""A car body read into its panels: `load_body(path)` → `BodyPanel`s in metres, body frame.

Body frame: x forward (the car's front at +x), y to the car's left, z up.

A path is either
- one mesh (STL/OBJ/PLY/…) or CAD (STEP/IGES) file holding the whole body. Its panels are found
  from the gaps between them: the file's connected pieces, pieces closer than `join_gap_m`
  (default `JOIN_GAP_M`, a crack in one panel rather than a panel gap) joined into one panel,
  and stray bits under `STRAY_AREA_FRACTION` of the largest panel's area dropped (as
  `paintcell.surface.pieces` does for a part). Each panel is wound outward (away from the body's
  centre) and named by where it sits (`panel_names`);
- or a folder holding a `body.json` manifest (or the manifest itself), which names each panel's
  file, its placement in the body frame and the side the paint goes on:

```json
{"units": "mm",
 "panels": [{"name": "front_door_left", "file": "front_door_left.stl", "side": "left",
             "placement": {"xyz_m": [0, 0, 0], "rpy_rad": [0, 0, 0]}}]}
```

  `units` is one of m, mm, cm, in, auto (as `[part] units`, `paintcell.surface.part_spec`);
  `placement` (optional, identity when the files are in the body frame) moves a file's points p
  to R(roll, pitch, yaw) p + xyz, the angles about the fixed x, y, z axes in that order.

Every refusal is one `BodyError` line naming the file or the key and what to write instead.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from paintcell.core.errors import SurfaceError
from paintcell.core.safe_paths import kind_of
from paintcell.surface.mesh_io import choose_units, read_part_file
from paintcell.surface.part_import import split_pieces
from paintcell.surface.part_spec import UNITS_M
from paintcell.surface.pieces import STRAY_AREA_FRACTION
from paintcell.surface.sheet_mesh import boundary_edges

__all__ = ["BODY_SIDES", "BodyError", "BodyPanel", "JOIN_GAP_M", "MANIFEST_NAME",
           "SIDE_DIRECTIONS", "load_body", "panel_names"]

#: The painter's side of a panel and its unit direction in the body frame.
SIDE_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "left": (0.0, 1.0, 0.0), "right": (0.0, -1.0, 0.0), "top": (0.0, 0.0, 1.0),
    "front": (1.0, 0.0, 0.0), "rear": (-1.0, 0.0, 0.0)}
BODY_SIDES = tuple(SIDE_DIRECTIONS)
#: Pieces of one file closer than this are one panel (a crack, not a panel gap) [m].
JOIN_GAP_M = 1e-3
#: The manifest's name inside a body folder.
MANIFEST_NAME = "body.json"

#: Names of a side's panels front to rear, by how many there are; of the tops front to rear; of
#: the rear's panels bottom to top. Other counts are numbered (`left_2`).
_SIDE_NAMES = {1: ("side",), 2: ("front_door", "rear_door"),
               3: ("front_fender", "door", "rear_quarter"),
               4: ("front_fender", "front_door", "rear_door", "rear_quarter")}
_TOP_NAMES = {1: ("roof",), 2: ("hood", "roof"), 3: ("hood", "roof", "trunk_lid")}
_END_NAMES: dict[str, dict[int, tuple[str, ...]]] = {
    "front": {1: ("front_bumper",)},
    "rear": {1: ("rear_bumper",), 2: ("rear_bumper", "tailgate")}}


class BodyError(SurfaceError):
    """A body file or folder cannot be read into panels."""


@dataclass(frozen=True, eq=False)
class BodyPanel:
    """One painted panel of a body.

    mesh: its triangles in metres, body frame, wound toward the painter; area_m2: its area;
    side: "left" | "right" | "top" | "front" | "rear"; direction: that side's unit vector in the
    body frame, toward the painter; normal: the panel's area-weighted mean unit normal; source:
    the file it came from.
    """

    name: str
    mesh: trimesh.Trimesh
    area_m2: float
    side: str
    direction: tuple[float, float, float]
    normal: tuple[float, float, float]
    source: str


def load_body(path: str | Path, units: str = "auto", join_gap_m: float = JOIN_GAP_M,
              stray_fraction: float = STRAY_AREA_FRACTION) -> list[BodyPanel]:
    """The panels of the body at `path` (module doc), sorted by name.

    units: the file's length unit ("m", "mm", "cm", "in" or "auto": inferred from the body's
    size, `paintcell.surface.mesh_io.choose_units`); join_gap_m: pieces of a single file closer
    than this are one panel [m]; stray_fraction: pieces under this share of the largest panel's
    area are dropped [-]. Raises BodyError (or SurfaceError for an unreadable file) in one line.
    """
    if units not in (*UNITS_M, "auto"):
        raise BodyError(f"units {units!r} is not one of m, mm, cm, in, auto; write units=\"mm\" "
                        "(or \"auto\" to infer it from the body's size)")
    p = Path(path)
    if p.is_dir() or p.suffix.lower() == ".json":
        panels = _from_manifest(p / MANIFEST_NAME if p.is_dir() else p, units)
    elif not p.exists():
        raise BodyError(f"body {p} does not exist; give a mesh/CAD file of the body or a folder "
                        f"holding {MANIFEST_NAME}")
    else:
        panels = _from_mesh(p, units, join_gap_m, stray_fraction)
    if len(panels) < 2:
        raise BodyError(f"body {p} holds {len(panels)} panel(s); a body needs at least 2 — give "
                        "the whole body, or a manifest naming each panel's file")
    return sorted(panels, key=lambda b: b.name)


def _oriented(name: str, v: np.ndarray, f: np.ndarray, side: str | None,
              centre: np.ndarray, source: str) -> BodyPanel:
    """A panel with consistent winding, wound toward `side` (or away from `centre`)."""
    m = trimesh.Trimesh(v, f, process=False)
    trimesh.repair.fix_winding(m)
    out = float(np.sum(m.area_faces * np.einsum("ij,ij->i", m.face_normals,
                                                m.triangles_center - centre)))
    n = (m.face_normals * m.area_faces[:, None]).sum(0)
    if side is not None:
        out = float(n @ np.asarray(SIDE_DIRECTIONS[side]))
    if out < 0:
        m = trimesh.Trimesh(m.vertices, m.faces[:, ::-1], process=False)
        n = -n
    n = n / max(float(np.linalg.norm(n)), 1e-300)
    if side is None:
        side = max(BODY_SIDES, key=lambda s: float(n @ np.asarray(SIDE_DIRECTIONS[s])))
    return BodyPanel(name, m, float(m.area), side, SIDE_DIRECTIONS[side],
                     (float(n[0]), float(n[1]), float(n[2])), source)


def _from_mesh(p: Path, units: str, join_gap_m: float, stray_fraction: float
               ) -> list[BodyPanel]:
    raw = read_part_file(p)
    scale = choose_units(np.ptp(raw.vertices, axis=0), units, raw.cad).scale_m
    m = trimesh.Trimesh(raw.vertices * scale, raw.faces, process=False)
    m.merge_vertices()
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    groups = _join(v, f, split_pieces(v, f), join_gap_m)
    area = m.area_faces
    a = np.array([float(area[g].sum()) for g in groups])
    groups = [g for g, ag in zip(groups, a, strict=True) if ag >= stray_fraction * a.max()]
    centre = _centre(v[np.unique(f[np.concatenate(groups)])])
    panels = []
    for g in groups:
        used, inv = np.unique(f[g], return_inverse=True)
        panels.append(_oriented("", v[used], inv.reshape(-1, 3), None, centre, str(p)))
    names = panel_names([(b.side, b.mesh.triangles_center.mean(0), b.area_m2) for b in panels])
    return [BodyPanel(nm, b.mesh, b.area_m2, b.side, b.direction, b.normal, b.source)
            for nm, b in zip(names, panels, strict=True)]


def _centre(v: np.ndarray) -> np.ndarray:
    return 0.5 * (v.min(0) + v.max(0))


def _join(v: np.ndarray, f: np.ndarray, groups: list[np.ndarray], gap_m: float
          ) -> list[np.ndarray]:
    """`groups` with those closer than `gap_m` merged (closest distance between the pieces'
    surfaces, vertex to triangle both ways)."""
    piece = np.empty(len(v), np.int64)
    rims = []
    for i, g in enumerate(groups):
        piece[f[g].ravel()] = i
        be = boundary_edges(f[g])
        rims.append(be if len(be) else f[g][:, :2])   # a closed piece: all its edges
    rim = np.concatenate(rims)
    reach = gap_m + float(np.linalg.norm(v[rim[:, 1]] - v[rim[:, 0]], axis=1).max())
    ends = np.unique(rim)
    pairs = ends[cKDTree(v[ends]).query_pairs(reach, output_type="ndarray")]
    cand = {(int(a), int(b)) for a, b in np.sort(piece[pairs], axis=1) if a != b}
    parent = list(range(len(groups)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    meshes: dict[int, trimesh.Trimesh] = {}
    for i, j in sorted(cand):
        if root(i) == root(j):
            continue
        d = np.inf
        for a, b in ((i, j), (j, i)):
            if b not in meshes:
                meshes[b] = trimesh.Trimesh(v, f[groups[b]], process=False)
            va = v[np.unique(f[groups[a]])]
            near = cKDTree(meshes[b].vertices[np.unique(f[groups[b]])]).query(
                va, distance_upper_bound=reach)[0]
            if np.isfinite(near).any():
                d = min(d, float(trimesh.proximity.closest_point(
                    meshes[b], va[np.isfinite(near)])[1].min()))
        if d <= gap_m:
            parent[root(j)] = root(i)
    merged: dict[int, list[np.ndarray]] = {}
    for i, g in enumerate(groups):
        merged.setdefault(root(i), []).append(g)
    return [np.sort(np.concatenate(gs)) for gs in merged.values()]


def panel_names(panels: list[tuple[str, np.ndarray, float]]) -> list[str]:
    """Names by where each panel sits, from (side, centroid [m], area [m²]) of each.

    A side's panels (left, right) front to rear: 4 are front_fender, front_door, rear_door,
    rear_quarter (3: front_fender, door, rear_quarter; 2: front_door, rear_door), each suffixed
    with the side (`front_door_left`); the tops front to rear: hood, roof, trunk_lid (2: hood,
    roof); the front: front_bumper; the rear bottom to top: rear_bumper, tailgate. Other counts
    are numbered from the front or the bottom (`left_1`, `top_2`)."""
    names = [""] * len(panels)
    table: dict[int, tuple[str, ...]]
    for side in BODY_SIDES:
        idx = [i for i, (s, _, _) in enumerate(panels) if s == side]
        if side in ("front", "rear"):
            idx.sort(key=lambda i: (float(panels[i][1][2]), -panels[i][2]))
            table = _END_NAMES[side]
        else:
            idx.sort(key=lambda i: (-float(panels[i][1][0]), -panels[i][2]))
            table = _TOP_NAMES if side == "top" else _SIDE_NAMES
        base = table.get(len(idx))
        for k, i in enumerate(idx):
            if base is None:
                names[i] = f"{side}_{k + 1}"
            else:
                names[i] = base[k] if side in ("top", "front", "rear") else f"{base[k]}_{side}"
    return names


def _from_manifest(path: Path, units: str) -> list[BodyPanel]:
    from scipy.spatial.transform import Rotation

    if path.exists() and not path.is_file():   # a FIFO would block the read: refuse at once
        raise BodyError(f"manifest {path} is a {kind_of(path.stat().st_mode)}, not a regular "
                        "file; give the body.json itself")
    if not path.is_file():
        raise BodyError(f"{path.parent} holds no {path.name}; write a {MANIFEST_NAME} naming "
                        "each panel's file (paintcell.surface.body_panels), or give the body's "
                        "mesh file")
    try:
        doc = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BodyError(f"{path} is not JSON ({_first_line(exc)}); write the manifest as JSON") \
            from None
    if not isinstance(doc, dict) or not isinstance(doc.get("panels"), list):
        raise BodyError(f"{path} has no \"panels\" list; write {{\"units\": \"mm\", \"panels\": "
                        "[{\"name\": ..., \"file\": ..., \"side\": ...}]}")
    declared = doc.get("units", "auto")
    if declared not in (*UNITS_M, "auto"):
        raise BodyError(f"{path}: units {declared!r} is not one of m, mm, cm, in, auto; write "
                        "\"units\": \"mm\"")
    if units != "auto" and declared not in ("auto", units):
        raise BodyError(f"{path} says units {declared!r} but {units!r} was asked for; drop one "
                        "of them")
    unit = units if declared == "auto" else declared
    read: list[tuple[dict[str, Any], np.ndarray, np.ndarray, Path]] = []
    for k, rec in enumerate(doc["panels"]):
        if not isinstance(rec, dict) or not all(isinstance(rec.get(x), str) and rec.get(x)
                                                for x in ("name", "file", "side")):
            raise BodyError(f"{path}: panels[{k}] needs \"name\", \"file\" and \"side\" "
                            "strings; write {\"name\": \"hood\", \"file\": \"hood.stl\", "
                            "\"side\": \"top\"}")
        if rec["side"] not in BODY_SIDES:
            raise BodyError(f"{path}: panel {rec['name']!r} has side {rec['side']!r}; write "
                            f"one of {', '.join(BODY_SIDES)}")
        f = path.parent / rec["file"]
        if not f.is_file():
            raise BodyError(f"{path}: panel {rec['name']!r} names file {rec['file']!r}, which "
                            f"is not in {path.parent}; put it there or fix \"file\"")
        raw = read_part_file(f)
        read.append((rec, raw.vertices, raw.faces, f))
    names = [r[0]["name"] for r in read]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise BodyError(f"{path}: panel name(s) {dup} appear more than once; name each panel once")
    if unit == "auto":
        allv = np.concatenate([r[1] for r in read]) if read else np.zeros((1, 3))
        unit = choose_units(np.ptp(allv, axis=0), "auto").units
    out = []
    for rec, v, f, src in read:
        pl: Any = rec.get("placement") or {}
        if not isinstance(pl, dict):
            raise BodyError(f"{path}: panel {rec['name']!r} placement must be a table like "
                            "{\"xyz_m\": [0, 0, 0], \"rpy_rad\": [0, 0, 0]}")
        try:
            xyz, rpy = (np.asarray(pl.get(k, [0.0, 0.0, 0.0]), float)
                        for k in ("xyz_m", "rpy_rad"))
        except (TypeError, ValueError):
            xyz = rpy = np.zeros(0)
        if xyz.shape != (3,) or rpy.shape != (3,) or not np.all(np.isfinite([*xyz, *rpy])):
            raise BodyError(f"{path}: panel {rec['name']!r} placement needs \"xyz_m\" and "
                            "\"rpy_rad\" of three numbers each, e.g. [0, 0, 0]")
        vb = Rotation.from_euler("xyz", rpy).apply(v * UNITS_M[unit]) + xyz
        m = trimesh.Trimesh(vb, f, process=False)
        m.merge_vertices()
        out.append(_oriented(rec["name"], np.asarray(m.vertices), np.asarray(m.faces),
                             rec["side"], np.zeros(3), str(src)))
    return out


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__
