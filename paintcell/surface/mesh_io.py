"""Reading a part file into raw triangles, and choosing its length unit.

Meshes (STL/OBJ/PLY/OFF/glTF) are read with trimesh; CAD (STEP/IGES) with the Open CASCADE kernel
(`cadquery-ocp-novtk`), tessellated at a chord tolerance. OCCT converts a STEP/IGES file's declared
unit to millimetres, so CAD coordinates are always millimetres.

A car part is 0.1–6 m across (`PLAUSIBLE_SIZE_M`: a fuel flap to a body side). `choose_units`
takes the file's largest extent and picks the first of m, mm, in, cm that puts it in that range,
and names every other unit that would too (a 52 file-unit part is a 1.33 m door in inches or a
0.52 m panel in cm: no rule tells them apart, the user's `units` does); an explicit unit is
checked against the same range, so a 509 m door or a 1 mm panel is refused with its dimensions
and the `units` setting that would fix it.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from paintcell.core.budget import check_mesh_file_budget
from paintcell.core.errors import SurfaceError
from paintcell.core.safe_paths import kind_of
from paintcell.surface.part_spec import CAD_SUFFIXES, UNITS_M

__all__ = ["PLAUSIBLE_SIZE_M", "RawMesh", "UnitChoice", "choose_units", "read_part_file",
           "sniff_mesh"]

#: Largest extent of a paintable car part [m]: smallest and largest plausible.
PLAUSIBLE_SIZE_M = (0.1, 6.0)
#: Order in which `units = "auto"` tries units: SI first, then what CAD systems export. Inches
#: before centimetres: where both read a car part (10–100 file units, too small in mm) inches
#: read a door or a hood (0.25–2.5 m) and centimetres a panel under 1 m, and inch exports are
#: the commoner of the two (US CAD defaults).
_AUTO_ORDER = ("m", "mm", "in", "cm")


@dataclass(frozen=True)
class RawMesh:
    """Triangles as read: vertices (N, 3) in file units, faces (F, 3) int64, and the format."""

    vertices: np.ndarray
    faces: np.ndarray
    fmt: str
    cad: bool


@dataclass(frozen=True)
class UnitChoice:
    """The unit chosen for a file: its name, metres per file unit, and why (one sentence)."""

    units: str
    scale_m: float
    reason: str
    also_plausible: tuple[str, ...] = ()
    """The other units that make the part a plausible size (`units = "auto"` only)."""


def read_part_file(path: str | os.PathLike[str], chord_tolerance_m: float = 5e-5) -> RawMesh:
    """Read a mesh or CAD file into raw triangles (no repair). Raises SurfaceError if unreadable.

    chord_tolerance_m: largest distance between a CAD surface and its tessellation [m].
    """
    path = Path(path)
    if not path.is_file():
        if path.exists():  # a FIFO would block the reader, a device never ends: refuse at once
            raise SurfaceError(f"part file {path} is a {kind_of(path.stat().st_mode)}, not a "
                               "regular file; give the mesh or CAD file itself")
        raise SurfaceError(f"part file {path} does not exist; check [part] file (relative to "
                           "the scenario file)")
    if path.suffix.lower() in CAD_SUFFIXES:
        v, f = _read_cad(path, chord_tolerance_m)
        return RawMesh(v, f, path.suffix.lower().lstrip("."), True)
    check_mesh_file_budget(path)    # from the size and header only, before the bytes are read
    sniff_mesh(path)
    try:
        if path.suffix.lower() == ".stl":
            # trimesh's STL reader itself: `trimesh.load` would build a scene and hash it
            # (12 s of a 2-million-face file's 12.5 s read, against 0.3 s).
            from trimesh.exchange.stl import load_stl

            with open(path, "rb") as fh:
                d = load_stl(fh)
            v, f = np.asarray(d["vertices"], float), np.asarray(d["faces"], np.int64)
        else:
            src = trimesh.load(path, force="mesh", process=False)
            if not isinstance(src, trimesh.Trimesh):
                raise SurfaceError(f"{path} holds no triangles; export the part surface as an "
                                   "STL, OBJ or PLY triangle mesh, or as STEP")
            v, f = np.asarray(src.vertices, float), np.asarray(src.faces, np.int64)
    except SurfaceError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable files
        msg = (str(exc).strip().splitlines() or [""])[0]
        raise SurfaceError(f"cannot read {path} ({type(exc).__name__}: {msg}); export it as "
                           "STL, OBJ, PLY or STEP") from exc
    if len(f) == 0 or f.ndim != 2 or f.shape[1] != 3:
        raise SurfaceError(f"{path} holds no triangles; export the part surface as an STL, OBJ "
                           "or PLY triangle mesh, or as STEP")
    check_raw(v, f, str(path))
    return RawMesh(v, f, path.suffix.lower().lstrip("."), False)


def sniff_mesh(path: Path) -> None:
    """Refuse a mesh file whose bytes cannot be the format its suffix says, in one line.

    Binary STL: 84-byte header + 50 bytes per triangle (a truncated file does not add up); ASCII
    STL, OBJ and ASCII PLY must be UTF-8 text (random bytes would otherwise reach trimesh's
    text-encoding guesser and come back as an unrelated import error).
    """
    suffix = path.suffix.lower()
    data = path.read_bytes()
    what = f"mesh {path}"
    if not data:
        raise SurfaceError(f"{what} is empty; export the part surface again")

    def is_text() -> bool:
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            return False
        return True

    if suffix == ".stl":
        if len(data) >= 84:
            n = int.from_bytes(data[80:84], "little")
            if len(data) == 84 + 50 * n:
                return
        if data.lstrip()[:5].lower() == b"solid" and is_text():
            return
        n_hint = int.from_bytes(data[80:84], "little") if len(data) >= 84 else 0
        raise SurfaceError(f"{what} is neither a binary STL ({len(data)} bytes, the header's "
                             f"{n_hint} triangles need {84 + 50 * n_hint}) nor an ASCII STL; the "
                             "file is truncated or not an STL — export it again")
    if suffix == ".obj" and not is_text():
        raise SurfaceError(f"{what} is not a text OBJ file (it holds non-UTF-8 bytes); the "
                             "file is corrupt or not an OBJ — export it again")
    if suffix == ".ply" and not data.startswith(b"ply"):
        raise SurfaceError(f"{what} does not start with the PLY magic 'ply'; the file is "
                             "corrupt or not a PLY — export it again")


def check_raw(v: np.ndarray, f: np.ndarray, what: str) -> None:
    """Refuse NaN/inf or absurd coordinates, bad indices and a lone triangle (SurfaceError)."""
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise SurfaceError(f"{what} has {int(bad.sum())} vertices with NaN or inf coordinates; "
                           "re-export the part from your CAD/scan tool")
    big = float(np.abs(v).max()) if len(v) else 0.0
    if big > 1e12:
        raise SurfaceError(f"{what} has coordinates up to {big:.3g} (no unit makes that a car "
                           "part); the export is corrupt, re-export the part")
    if len(f) == 0 or f.min() < 0 or f.max() >= len(v):
        raise SurfaceError(f"{what} faces index missing vertices; re-export the mesh")
    distinct = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    # A face with three distinct but collinear (or coincident) corners has no area either.
    ext = float(np.ptp(v, axis=0).max())
    area2 = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    usable = int((distinct & (area2 > 1e-12 * ext * ext)).sum()) if ext > 0 else 0
    if usable < 2:
        raise SurfaceError(f"{what} has {usable} usable triangle(s) of {len(f)} (the others "
                           "have no area); a part surface needs a triangulated skin, export the "
                           "whole part surface")


def choose_units(extent_file: np.ndarray, units: str, cad: bool = False) -> UnitChoice:
    """The unit of a file with bounding-box extents `extent_file` (3,) in file units.

    units: "m", "mm", "cm", "in" or "auto". cad: the coordinates come from OCCT (millimetres).
    Raises SurfaceError, naming the dimensions and the `units` setting to write, when the part
    would be outside `PLAUSIBLE_SIZE_M`.
    """
    lo, hi = PLAUSIBLE_SIZE_M
    size = float(np.max(extent_file))
    dims = " × ".join(f"{x:.4g}" for x in extent_file)
    if cad:
        if units not in ("auto", "mm"):
            raise SurfaceError(f"[part] units = {units!r} does not apply to STEP/IGES (the file "
                               "declares its unit and is read in mm); write units = \"auto\"")
        choice = UnitChoice("mm", 1e-3, "the CAD file declares its unit (read in mm)")
        units = "mm"
    elif units == "auto":
        fits = [u for u in _AUTO_ORDER if lo <= size * UNITS_M[u] <= hi]
        if not fits:
            raise SurfaceError(
                f"part is {dims} file units: no unit (m, mm, cm, in) makes it {lo:g}–{hi:g} m "
                "across; check the export, or set [part] units and scale it yourself")
        u, also = fits[0], tuple(fits[1:])
        others = [f"{w}: {size * UNITS_M[w]:.3g} m" for w in _AUTO_ORDER
                  if w != u and w not in also]
        reason = (f"largest extent {size:.4g} file units, read as {u} {size * UNITS_M[u]:.3g} m: "
                  f"the first of {', '.join(_AUTO_ORDER)} to give {lo:g}–{hi:g} m "
                  f"({'; '.join(others)})")
        if also:
            reason += ("; AMBIGUOUS: " + ", ".join(
                f"read as {w} it is {size * UNITS_M[w]:.3g} m" for w in also)
                + f" — if so, write [part] units = \"{also[0]}\" (or --units {also[0]})")
        choice = UnitChoice(u, UNITS_M[u], reason, also)
    else:
        choice = UnitChoice(units, UNITS_M[units], f"set in the scenario (units = \"{units}\")")
    size_m = size * choice.scale_m
    if not lo <= size_m <= hi:
        fix = [u for u in _AUTO_ORDER if lo <= size * UNITS_M[u] <= hi]
        hint = (f"write [part] units = \"{fix[0]}\" (or \"auto\")" if fix else
                "check the export: no unit makes it a car part")
        raise SurfaceError(f"part is {dims} {units} = {size_m:.4g} m across, outside the "
                           f"plausible {lo:g}–{hi:g} m of a car part; {hint}")
    return choice


def _read_cad(path: Path, chord_tolerance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """STEP/IGES → triangles [mm] through OCCT: read, tessellate at the chord tolerance, and take
    the triangulation through OCCT's own STL writer (oriented faces, no Python loop over nodes)."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.StlAPI import StlAPI_Writer

    if path.suffix.lower() in (".step", ".stp"):
        from OCP.STEPControl import STEPControl_Reader
        reader = STEPControl_Reader()
    else:
        from OCP.IGESControl import IGESControl_Reader
        reader = IGESControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise SurfaceError(f"cannot read {path} as {path.suffix.upper().lstrip('.')}; "
                           "re-export it from your CAD system (AP203/AP214 STEP)")
    reader.TransferRoots()
    shape = reader.OneShape()
    if shape.IsNull():
        raise SurfaceError(f"{path} holds no shape; export the part's surfaces or solid")
    # Linear deflection in the file's (mm) unit; 0.2 rad angular deflection bounds tight fillets.
    mesh = BRepMesh_IncrementalMesh(shape, chord_tolerance_m * 1e3, False, 0.2, True)
    mesh.Perform()
    with tempfile.TemporaryDirectory() as tmp:
        stl = Path(tmp) / "tessellation.stl"
        writer = StlAPI_Writer()
        writer.ASCIIMode = False
        if not writer.Write(shape, str(stl)) or stl.stat().st_size <= 84:
            raise SurfaceError(f"{path} has no surface to tessellate (curves or points only); "
                               "export the part's faces or solid")
        m = trimesh.load(stl, force="mesh", process=False)
    v = np.asarray(m.vertices, dtype=np.float64)  # type: ignore[attr-defined]
    f = np.asarray(m.faces, dtype=np.int64)  # type: ignore[attr-defined]
    check_raw(v, f, str(path))
    return v, f
