"""`MeshPart`: what a painter knows about a part file, as a scenario's `[part]` table declares it.

```toml
[part]
file = "../../shared/meshes/reach_hood_panel.ply"   # relative to the scenario file
units = "auto"            # m | mm | cm | in | auto
pieces = "auto"           # auto | largest (by area) | all | [0, 2]
pieces_gap_m = 0.04       # auto: pieces this close that face the painted side are one part
side = "auto"             # auto | [0, 0, 1] painted-side direction in the part frame
```

Every key is checked by `MeshPart.from_dict`; a bad one is refused in one line naming the key, the
valid values and what to write instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from paintcell.core.errors import SurfaceError

__all__ = ["CAD_SUFFIXES", "CHORD_TOLERANCE_RANGE_M", "FILL_HOLES_RANGE_M", "MESH_SUFFIXES",
           "MeshPart", "PIECES_GAP_M", "PIECES_GAP_RANGE_M", "PartSpecError", "REGIONS", "UNITS_M"]

#: Length of one file unit in metres.
UNITS_M: dict[str, float] = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")
CAD_SUFFIXES = (".step", ".stp", ".iges", ".igs")
#: Default largest gap between pieces painted as one part, `pieces = "auto"` [m].
PIECES_GAP_M = 0.04
#: Valid `pieces_gap_m` [m], bounds included.
PIECES_GAP_RANGE_M = (0.0, 0.5)
#: The regions a part's film can be judged on (`judge`).
REGIONS = ("skin", "hem", "inner", "back", "edge")
#: Valid `chord_tolerance_m` [m]: the CAD tessellation's largest chord error, bounds included.
CHORD_TOLERANCE_RANGE_M = (1e-6, 0.05)
#: Valid `fill_holes_m` [m]: the equivalent diameter below which a loop is a scan hole.
FILL_HOLES_RANGE_M = (0.0, 1.0)


class PartSpecError(SurfaceError):
    """A `[part]` table (or `MeshPart`) is malformed."""


@dataclass(frozen=True)
class MeshPart:
    """A part read from a mesh or CAD file.

    file: path of an STL/OBJ/PLY mesh or a STEP/IGES CAD file (relative paths are relative to the
        scenario file: `from_dict` resolves them against `base_dir`).
    units: length unit of the file's coordinates: "m", "mm", "cm", "in", or "auto" (inferred from
        the size a car part can have; `paintcell.surface.part_import` says what it chose
        and why).
    pieces: "auto" (the largest piece and every piece that lies within `pieces_gap_m` of it,
        faces the painted side and is not hidden behind it; stray bits under 1 % of its area
        left out: `paintcell.surface.pieces`), "largest" (the connected piece of largest area),
        "all", or a tuple of piece indices (pieces are numbered by decreasing area, as
        `paintcell inspect` lists them).
    pieces_gap_m: with pieces = "auto", the largest gap between pieces painted as one part [m].
    side: "auto" (the convex, visible skin) or a direction (x, y, z) in the part frame toward the
        painted side [-] (need not be unit length).
    chord_tolerance_m: largest distance between a CAD surface and its tessellation [m] (STEP/IGES;
        0.05 mm keeps facets of a 1 m radius ~20 mm wide, so the remesh is not left faceted).
    fill_holes_m: boundary loops with an equivalent diameter (perimeter / π) below this are scan
        holes and are filled; larger ones are openings [m].
    judge: regions the film metrics are judged on ("skin", "hem", "inner", "back", "edge":
        turned edges and lips).
    name: surface name (default: the file stem).
    """

    file: str
    units: str = "auto"
    pieces: str | tuple[int, ...] = "auto"
    pieces_gap_m: float = PIECES_GAP_M
    side: str | tuple[float, float, float] = "auto"
    chord_tolerance_m: float = 5e-5
    fill_holes_m: float = 0.03
    judge: tuple[str, ...] = ("skin",)
    name: str | None = None

    def __post_init__(self) -> None:
        _check(self)

    @property
    def path(self) -> Path:
        """The file as a Path."""
        return Path(self.file)

    @property
    def stem(self) -> str:
        """Surface name: `name` or the file stem with characters other than [A-Za-z0-9_-] as _."""
        raw = self.name or self.path.stem
        return "".join(c if c.isalnum() or c in "_-" else "_" for c in raw)

    @classmethod
    def from_dict(cls, table: dict[str, Any], base_dir: str | Path | None = None) -> MeshPart:
        """A MeshPart from a scenario's `[part]` table; `file` is resolved against `base_dir`."""
        if not isinstance(table, dict):
            raise PartSpecError(f"[part] must be a table (got {type(table).__name__}); write "
                                "[part] with file = \"...\"")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(table) - set(names))
        if unknown:
            raise PartSpecError(f"[part] has unknown key(s) {unknown}; valid keys: {names}")
        if "file" not in table:
            raise PartSpecError("[part] has no file; add file = \"path/to/part.stl\" (relative "
                                "to the scenario file)")
        kw = dict(table)
        if not isinstance(kw["file"], str) or not kw["file"]:
            raise PartSpecError(f"[part] file = {kw['file']!r} must be a path string")
        p = Path(kw["file"])
        if base_dir is not None and not p.is_absolute():
            p = Path(base_dir) / p
        kw["file"] = str(p)
        for key in ("pieces", "side", "judge"):
            if isinstance(kw.get(key), list):
                kw[key] = tuple(kw[key])
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this part (tuples as lists; `name` only when set)."""
        d: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "name" and v is None:
                continue
            d[f.name] = list(v) if isinstance(v, tuple) else v
        return d


def _is_num(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _check(p: MeshPart) -> None:
    if not isinstance(p.file, str) or not p.file:
        raise PartSpecError(f"[part] file = {p.file!r} must be a path string")
    suffix = Path(p.file).suffix.lower()
    if suffix not in MESH_SUFFIXES + CAD_SUFFIXES:
        ok = ", ".join(MESH_SUFFIXES + CAD_SUFFIXES)
        raise PartSpecError(f"[part] file {p.file!r} has suffix {suffix!r}; give an "
                            f"STL/OBJ/PLY mesh or a STEP/IGES file ({ok})")
    if p.units not in (*UNITS_M, "auto"):
        raise PartSpecError(f"[part] units = {p.units!r} is not one of m, mm, cm, in, auto; "
                            "write units = \"mm\" (or \"auto\" to infer it)")
    if isinstance(p.pieces, str):
        if p.pieces not in ("auto", "largest", "all"):
            raise PartSpecError(f"[part] pieces = {p.pieces!r}; write pieces = \"auto\", "
                                "\"largest\", \"all\" or a list of piece indices like [0, 2]")
    elif not (isinstance(p.pieces, tuple) and p.pieces
              and all(isinstance(i, int) and not isinstance(i, bool) and i >= 0
                      for i in p.pieces)):
        raise PartSpecError(f"[part] pieces = {p.pieces!r}; write \"auto\", \"largest\", "
                            "\"all\" or a non-empty list of piece indices >= 0 like [0, 2]")
    lo, hi = PIECES_GAP_RANGE_M
    if not _is_num(p.pieces_gap_m) or not lo <= p.pieces_gap_m <= hi:
        raise PartSpecError(f"[part] pieces_gap_m = {p.pieces_gap_m!r} must be a length between "
                            "0 and 0.5 m; write e.g. pieces_gap_m = 0.04")
    if isinstance(p.side, str):
        if p.side != "auto":
            raise PartSpecError(f"[part] side = {p.side!r}; write side = \"auto\" or a direction "
                                "like [0, 0, 1] toward the painted side")
    elif not (isinstance(p.side, tuple) and len(p.side) == 3 and all(map(_is_num, p.side))
              and any(abs(x) > 0 for x in p.side)):
        raise PartSpecError(f"[part] side = {p.side!r}; write \"auto\" or three numbers, not all "
                            "zero, like [0, 0, 1] (painted-side direction in the part frame)")
    lo, hi = CHORD_TOLERANCE_RANGE_M
    if not _is_num(p.chord_tolerance_m) or not lo <= p.chord_tolerance_m <= hi:
        raise PartSpecError(f"[part] chord_tolerance_m = {p.chord_tolerance_m!r} must be a "
                            "length between 1e-6 and 0.05 m; write e.g. chord_tolerance_m = 5e-5")
    lo, hi = FILL_HOLES_RANGE_M
    if not _is_num(p.fill_holes_m) or not lo <= p.fill_holes_m <= hi:
        raise PartSpecError(f"[part] fill_holes_m = {p.fill_holes_m!r} must be a length between "
                            "0 and 1 m; write e.g. fill_holes_m = 0.03 (0: fill no hole)")
    if not (isinstance(p.judge, tuple) and p.judge and all(r in REGIONS for r in p.judge)):
        raise PartSpecError(f"[part] judge = {p.judge!r}; write a non-empty list of regions "
                            f"from {list(REGIONS)}, e.g. judge = [\"skin\"]")
    if p.name is not None and (not isinstance(p.name, str) or not p.name):
        raise PartSpecError(f"[part] name = {p.name!r} must be a non-empty string")
