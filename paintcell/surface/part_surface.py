"""A part's surface from what a scenario names: a library part, a mesh/CAD `[part]` table or a
bare mesh path, checked against the memory budget first and, for a mesh file, sniffed so a
corrupt file is refused in one line."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from paintcell.core.errors import PaintcellError
from paintcell.surface.part_spec import CAD_SUFFIXES, MESH_SUFFIXES, MeshPart
from paintcell.surface.surface import Surface

__all__ = ["part_surface", "sniff_mesh"]


def part_surface(part: str | MeshPart, res: float, source: str | None = None,
                 res_key: str = "resolution_m") -> Surface:
    """A part's surface in its own frame at remesh edge length res [m]: a library part name, a
    mesh/CAD `MeshPart` (a scenario's or a booth's `[part]` table) or a bare path (every [part]
    setting at its default); a relative file is relative to `source` (the scenario file).
    res_key names the setting in the budget's error."""
    from paintcell.surface import parts

    if isinstance(part, str) and part in parts.PART_NAMES:
        from paintcell.core.budget import check_surface_budget

        # The area from a coarse build (~40 ms) sizes the real one before it allocates.
        area = parts.get_part(part, resolution_m=max(res, 0.05)).area
        check_surface_budget(area, res, res_key)
        return parts.get_part(part, resolution_m=res)
    # A mesh/CAD file: a [part] table, or a bare path (every [part] setting at its default).
    if isinstance(part, MeshPart):
        spec = part
    elif Path(part).suffix.lower() in MESH_SUFFIXES + CAD_SUFFIXES:
        spec = MeshPart(file=part)
    else:
        raise PaintcellError(f"part {part!r} is neither a library part "
                             f"({', '.join(parts.PART_NAMES)}) nor a mesh/CAD file")
    from paintcell.surface.part_import import import_part

    path = Path(spec.file)
    if not path.is_absolute() and source:
        path = Path(source).parent / path
    if path.is_file() and path.suffix.lower() in MESH_SUFFIXES:
        sniff_mesh(path)
    return import_part(replace(spec, file=str(path)), resolution_m=res)[0]


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
        raise PaintcellError(f"{what} is empty; export the part surface again")

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
        raise PaintcellError(f"{what} is neither a binary STL ({len(data)} bytes, the header's "
                             f"{n_hint} triangles need {84 + 50 * n_hint}) nor an ASCII STL; the "
                             "file is truncated or not an STL — export it again")
    if suffix == ".obj" and not is_text():
        raise PaintcellError(f"{what} is not a text OBJ file (it holds non-UTF-8 bytes); the "
                             "file is corrupt or not an OBJ — export it again")
    if suffix == ".ply" and not data.startswith(b"ply"):
        raise PaintcellError(f"{what} does not start with the PLY magic 'ply'; the file is "
                             "corrupt or not a PLY — export it again")
