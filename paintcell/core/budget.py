"""Memory and time estimates of the expensive stages, checked before they allocate.

A scenario with a typo in a setting (a 50 m spray σ, a 0.1 mm resolution, a 10 µm profile
spacing) must be refused in one line with the figure and the setting to change, not die of a
MemoryError minutes later or swap the machine. The estimates follow the allocations of the code
they guard; the stages compute their sizes (`paintcell.coverage.index_width.profile_size`,
`search_size`) and these checks hold them to the memory the process may use:

- surface: vertices ≈ area / resolution² (area measured on a coarse build of the part, or on
  the mesh file as read), about `BYTES_PER_VERTEX` each (positions, normals, faces, curvature,
  trimesh caches, three film maps);
- mesh file: `BYTES_PER_INPUT_FACE` per face while it is read and thinned, the faces counted
  before reading (a binary STL's header, other formats from their size);
  `paintcell.surface.mesh_thinning` thins a mesh far finer than the run's resolution;
- planner: the index-width curve (`paintcell.coverage.index_width.single_pass_profile`)
  evaluates a dense (gun samples × profile points) float64 matrix whose sides grow with the
  applicator footprint, and the width search (`index_width.search_widths`) gathers (widths ×
  future-width sets × 2·n_future × profile points) float64 at each marker;
- sweep: `BYTES_PER_SWEEP_SAMPLE` per sample, at most `MAX_SWEEP_SAMPLES`;
- validation: the deposition sums surface points × gun samples (trace binned at 5 ms) pairs at
  ~`PAIRS_PER_S` (benchmarks/deposition.py measures ~1.9e8 /s on 2 cores; the bound is a third).

The memory the run may use (`paintcell.core.memory.memory_room`) is the least of MemAvailable,
the memory cgroup's limit less its usage (a container's `memory.max`), RLIMIT_AS less the
address space in use, and `PAINTCELL_MAX_MEMORY_GB`; each refusal names which bound it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from paintcell.core.memory import (
    BudgetError,
    available_bytes,
    gib,
    room_text,
)

__all__ = ["BYTES_PER_INPUT_FACE", "BYTES_PER_VERTEX", "check_mesh_file_budget",
           "check_planner_budget", "check_profile_budget", "check_surface_budget",
           "check_sweep_budget", "check_validation_budget", "file_face_estimate", "planner_bytes"]

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
#: Pessimistic deposition throughput for the time estimate [pairs/s].
PAIRS_PER_S = 6e7
#: Longest validation deposition accepted before refusing [s].
MAX_VALIDATION_S = 3600.0
#: Memory a sweep holds per sample (its design row, seed, Dask future and record, ~2–4 kB of
#: JSON as a Python dict) [B] — an upper estimate.
BYTES_PER_SWEEP_SAMPLE = 50_000
#: Most samples a sweep takes: the yield's 95 % Clopper–Pearson interval is ±0.1 pp there.
MAX_SWEEP_SAMPLES = 1_000_000


def check_profile_budget(n_gun: int, n_pts: int, footprint_radius_m: float, where: str) -> None:
    """Refuse an index-width curve of `n_gun` gun samples × `n_pts` profile points
    (`paintcell.coverage.index_width.profile_size` of an applicator of footprint radius
    `footprint_radius_m` [m]) that would not fit in memory; `where` names the applicator."""
    need = 8.0 * n_gun * n_pts
    have = available_bytes()
    if need > 0.8 * have:
        raise BudgetError(
            f"the planner's index-width curve needs ~{gib(need)} ({n_gun:,} gun samples × "
            f"{n_pts:,} profile points) for the applicator's {footprint_radius_m:.3g} m "
            f"footprint radius, more than {room_text()}; check sigma_x_m / "
            f"sigma_y_m / ring_* of {where} (a paint bell's pattern is ~0.3 m)")


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


def check_validation_budget(n_points: int, n_samples: int, setting: str) -> float:
    """Refuse a validation deposition estimated above `MAX_VALIDATION_S`; returns seconds."""
    t = float(n_points) * n_samples / PAIRS_PER_S
    if t > MAX_VALIDATION_S:
        raise BudgetError(
            f"the validation film maps need ~{t / 3600:.3g} h ({n_points:,} surface points × "
            f"{n_samples:,} gun samples, each map); coarsen {setting} or shorten the program")
    return t


def planner_bytes(size: dict[str, int]) -> float:
    """Peak bytes of the index-width search at one marker for the sides `size`
    (`paintcell.coverage.index_width.search_size`: widths W, future-width sets C, profile points
    P, gun positions G, future passes n): the gathered pass profiles (W, C, 2n, P), the sums and
    masks (W, C, P) ×3 and the cross profiles (G, P), float64."""
    s = size
    return 8.0 * (s["W"] * s["C"] * s["P"] * (2 * s["n"] + 3) + s["G"] * s["P"])


def check_planner_budget(size: dict[str, int], where: str) -> float:
    """Refuse planner settings whose index-width search (sides `size`, `planner_bytes`) would
    not fit in memory; returns the bytes estimate."""
    need = planner_bytes(size)
    if need > 0.8 * available_bytes():
        raise BudgetError(
            f"{where}: the index-width search needs ~{gib(need)} ({size['W']:,} widths × "
            f"{size['C']:,} future-width sets (future_grid_n^(n_future−1)) × {size['P']:,} "
            f"profile points (2·w_max_m / profile_spacing_m)), more than {room_text()}; raise "
            "profile_spacing_m or w_res_m, or lower future_grid_n or n_future")
    return need


def check_sweep_budget(samples: int, setting: str = "samples") -> None:
    """Refuse a sweep whose samples would not fit in memory, or more than `MAX_SWEEP_SAMPLES`."""
    need = float(samples) * BYTES_PER_SWEEP_SAMPLE
    if samples > MAX_SWEEP_SAMPLES:
        raise BudgetError(f"{setting} = {samples:,} is more than a sweep takes "
                          f"({MAX_SWEEP_SAMPLES:,}: the yield's 95 % interval is then ±0.1 pp); "
                          f"lower {setting}")
    if need > 0.8 * available_bytes():
        fit = int(0.8 * available_bytes() / BYTES_PER_SWEEP_SAMPLE)
        raise BudgetError(f"{setting} = {samples:,} needs ~{gib(need)} for the sweep's records, "
                          f"more than {room_text()}; lower {setting} to {fit:,} or fewer")


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
