"""Memory and time estimates of the expensive stages, checked before they allocate.

A scenario with a typo in a setting (a 50 m spray σ, a 0.1 mm resolution) must be refused in one
line with the figure and the setting to change, not die of a MemoryError minutes later or swap
the machine. The estimates follow the allocations of the code they guard:

- surface: vertices ≈ area / resolution² (area measured on a coarse build of the part), about
  `BYTES_PER_VERTEX` each (positions, normals, faces, curvature, trimesh caches, three film maps);
- planner: the index-width curve (`paintcell.coverage.index_width.single_pass_profile`)
evaluates a dense
  (gun samples × profile points) float64 matrix whose sides grow with the applicator footprint;
- validation: the deposition sums surface points × gun samples (trace binned at 5 ms) pairs at
  ~`PAIRS_PER_S` (benchmarks/deposition.py measures ~1.9e8 /s on 2 cores; the bound is a third).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from paintcell.core.errors import PaintcellError

__all__ = ["BudgetError", "available_bytes", "check_profile_budget", "check_surface_budget",
           "check_validation_budget", "gib"]

#: Bytes per surface vertex over the run (measured: the door at 5 mm, ~35 k vertices, peaks
#: ~0.1 GB above the interpreter in the surface and validation stages ≈ 3 kB/vertex).
BYTES_PER_VERTEX = 3000
#: Pessimistic deposition throughput for the time estimate [pairs/s].
PAIRS_PER_S = 6e7
#: Longest validation deposition accepted before refusing [s].
MAX_VALIDATION_S = 3600.0


class BudgetError(PaintcellError):
    """A stage would need more memory or time than the machine has."""


def gib(n_bytes: float) -> str:
    """A byte count in GiB for messages."""
    return f"{n_bytes / 2**30:.3g} GiB"


def available_bytes() -> int:
    """Memory the run may use: MemAvailable (Linux) or physical memory, capped by
    `PAINTCELL_MAX_MEMORY_GB` when set."""
    avail = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                avail = int(line.split()[1]) * 1024
                break
    except OSError:
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            avail = 2**62
    cap = os.environ.get("PAINTCELL_MAX_MEMORY_GB")
    if cap:
        try:
            avail = min(avail, int(float(cap) * 2**30))
        except ValueError:
            raise BudgetError(f"PAINTCELL_MAX_MEMORY_GB = {cap!r} is not a number of GB") \
                from None
    return int(avail)


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
            f"footprint radius, more than the {gib(have)} available; check sigma_x_m / "
            f"sigma_y_m / ring_* of {where} (a paint bell's pattern is ~0.3 m)")


def check_surface_budget(area_m2: float, resolution_m: float, setting: str) -> int:
    """Refuse a resolution whose surface would not fit in memory; returns the vertex estimate."""
    n = int(area_m2 / resolution_m**2)
    need = float(n) * BYTES_PER_VERTEX
    have = available_bytes()
    if need > 0.8 * have:
        coarsest = math.sqrt(area_m2 * BYTES_PER_VERTEX / (0.8 * have))
        raise BudgetError(
            f"{setting} = {resolution_m:g} m gives ~{n:,} surface points on {area_m2:.3g} m² "
            f"(~{gib(need)}), more than the {gib(have)} available; set {setting} >= "
            f"{coarsest:.2g} m")
    return n


def check_validation_budget(n_points: int, n_samples: int, setting: str) -> float:
    """Refuse a validation deposition estimated above `MAX_VALIDATION_S`; returns seconds."""
    t = float(n_points) * n_samples / PAIRS_PER_S
    if t > MAX_VALIDATION_S:
        raise BudgetError(
            f"the validation film maps need ~{t / 3600:.3g} h ({n_points:,} surface points × "
            f"{n_samples:,} gun samples, each map); coarsen {setting} or shorten the program")
    return t
