"""What a part's surface and its mesh file cost in memory, checked before they are built.

- surface: vertices ≈ area / resolution² (the area measured on a coarse build of a library part,
  or on the mesh file as read), about `BYTES_PER_VERTEX` each (positions, normals, faces,
  curvature, trimesh caches, three film maps) over the run;
- mesh file: `BYTES_PER_INPUT_FACE` per face while it is read and thinned, the faces counted
  before reading (a binary STL's header, other formats from their size).

The memory the process may use is `paintcell.core.memory.memory_room`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from paintcell.core.memory import BudgetError, available_bytes, gib, room_text

__all__ = ["BYTES_PER_INPUT_FACE", "BYTES_PER_VERTEX", "check_mesh_file_budget",
           "check_surface_budget", "file_face_estimate"]

#: Bytes per surface vertex over the run (measured: the door at 5 mm, ~35 k vertices, peaks
#: ~0.1 GB above the interpreter in the surface and validation stages ≈ 3 kB/vertex).
BYTES_PER_VERTEX = 3000
#: Peak bytes per face of a mesh file while it is read and thinned (a binary STL triangle soup:
#: trimesh's vertices, faces and normals, the clustering's keys; `benchmarks/huge_mesh.py`
#: measured 1.06 GiB peak for `paintcell inspect` of 2 million faces, interpreter included).
BYTES_PER_INPUT_FACE = 600
#: Bytes per face of each format's file, at least (binary STL 50; an OBJ face and its share of
#: vertices ~30 as text; PLY binary ~25), for an estimate of the faces before reading.
_MIN_FILE_BYTES_PER_FACE = {".stl": 50, ".obj": 30, ".ply": 25}


def file_face_estimate(path: Path) -> int:
    """The faces a mesh file holds: a binary STL's header count, else an upper estimate from
    the file size."""
    size = path.stat().st_size
    if path.suffix.lower() == ".stl" and size >= 84:
        with open(path, "rb") as fh:
            n = int.from_bytes(fh.read(84)[80:84], "little")
        if size == 84 + 50 * n:   # a binary STL (its header may start with "solid" too)
            return n
        return size // 250        # an ASCII facet is ~250 bytes
    return size // _MIN_FILE_BYTES_PER_FACE.get(path.suffix.lower(), 25)


def check_mesh_file_budget(path: str | os.PathLike[str]) -> int:
    """Refuse a mesh file whose faces could not be read in memory; returns the face estimate."""
    path = Path(path)
    n = file_face_estimate(path)
    need = float(n) * BYTES_PER_INPUT_FACE
    if need > 0.8 * available_bytes():
        raise BudgetError(f"mesh {path} holds ~{n:,} faces (~{gib(need)} to read), more than "
                          f"{room_text()}; decimate it in your CAD or mesh tool first")
    return n


def check_surface_budget(area_m2: float, resolution_m: float, setting: str,
                         what: str | None = None) -> int:
    """Refuse a resolution whose surface would not fit in memory; returns the vertex estimate.
    setting: the resolution's name in the user's input; what: the part file, named first."""
    n = int(area_m2 / resolution_m**2)
    need = float(n) * BYTES_PER_VERTEX
    have = available_bytes()
    if need > 0.8 * have:
        coarsest = math.sqrt(area_m2 * BYTES_PER_VERTEX / (0.8 * max(have, 1)))
        raise BudgetError(
            (f"{what}: " if what else "")
            + f"{setting} = {resolution_m:g} m gives ~{n:,} surface points on {area_m2:.3g} m² "
            f"(~{gib(need)}), more than {room_text()}; set {setting} >= {coarsest:.2g} m")
    return n
