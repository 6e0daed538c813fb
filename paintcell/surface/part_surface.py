"""A part's surface from what a scenario names: a library part, a mesh/CAD `[part]` table or a
bare mesh path, checked against the memory budget first (a mesh file by `import_part`, which
also sniffs its bytes: `paintcell.surface.mesh_io.sniff_mesh`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from paintcell.core.errors import PaintcellError
from paintcell.surface.part_spec import CAD_SUFFIXES, MESH_SUFFIXES, MeshPart
from paintcell.surface.surface_data import Surface

__all__ = ["part_surface"]


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
    return import_part(replace(spec, file=str(path)), resolution_m=res, setting=res_key)[0]
