"""Memory and time estimates of the expensive stages, checked before they allocate.

A scenario with a typo in a setting (a 50 m spray σ, a 0.1 mm resolution, a 10 µm profile
spacing) must be refused in one line with the figure and the setting to change, not die of a
MemoryError minutes later or swap the machine. The estimates follow the allocations of the code
they guard:

- surface and input mesh: `paintcell.surface.surface_budget` (vertices ≈ area / resolution²,
  `BYTES_PER_VERTEX` each; a mesh file's faces before it is read), and
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
from typing import Any

from paintcell.core.memory import (
    BudgetError,
    available_bytes,
    gib,
    memory_cap_bytes,
    memory_room,
    room_text,
)
from paintcell.surface.surface_budget import BYTES_PER_VERTEX, check_surface_budget

__all__ = ["BYTES_PER_VERTEX", "BudgetError", "available_bytes", "check_planner_budget",
           "check_profile_budget", "check_surface_budget", "check_sweep_budget",
           "check_validation_budget", "gib", "memory_cap_bytes", "memory_room", "planner_bytes"]

#: Pessimistic deposition throughput for the time estimate [pairs/s].
PAIRS_PER_S = 6e7
#: Longest validation deposition accepted before refusing [s].
MAX_VALIDATION_S = 3600.0


def profile_size(app: Any) -> tuple[int, int]:
    """(gun samples, profile points) of the index-width curve's dense matrix for `app`."""
    from paintcell.coverage import index_width as iw

    r = app.footprint_radius_m
    n_gun = int(2 * iw._X_RANGE_FACTOR * r / iw._dx(app)) + 1
    n_pts = int(2 * r / min(5e-4, r / 400)) + 1
    return n_gun, n_pts


def check_profile_budget(app: Any, where: str) -> None:
    """Refuse an applicator whose index-width curve would not fit in memory."""
    n_gun, n_pts = profile_size(app)
    need = 8.0 * n_gun * n_pts
    have = available_bytes()
    if need > 0.8 * have:
        raise BudgetError(
            f"the planner's index-width curve needs ~{gib(need)} ({n_gun:,} gun samples × "
            f"{n_pts:,} profile points) for the applicator's {app.footprint_radius_m:.3g} m "
            f"footprint radius, more than {room_text()}; check sigma_x_m / "
            f"sigma_y_m / ring_* of {where} (a paint bell's pattern is ~0.3 m)")


def check_validation_budget(n_points: int, n_samples: int, setting: str) -> float:
    """Refuse a validation deposition estimated above `MAX_VALIDATION_S`; returns seconds."""
    t = float(n_points) * n_samples / PAIRS_PER_S
    if t > MAX_VALIDATION_S:
        raise BudgetError(
            f"the validation film maps need ~{t / 3600:.3g} h ({n_points:,} surface points × "
            f"{n_samples:,} gun samples, each map); coarsen {setting} or shorten the program")
    return t


#: Default bell's footprint radius [m] (`paintcell.paint.applicator.Applicator.default`), the
#: planner budget's assumption at load, before the scenario's applicator is read.
DEFAULT_FOOTPRINT_M = 0.3


def planner_search_size(st: Any, footprint_radius_m: float = DEFAULT_FOOTPRINT_M
                        ) -> dict[str, int]:
    """The sides of the index-width search's dense arrays for `PlannerSettings` `st`
    (`paintcell.coverage.coverage_planner`, `index_width.search_widths`): widths tried W,
    future-width sets C, profile points P, gun positions G, future passes n."""
    from paintcell.coverage.index_width import search_range

    widths = search_range(st.w_min_m, st.w_max_m, st.w_res_m)
    w = len(widths)
    n_fut = min(max(1, st.future_grid_n), w)
    c = n_fut ** max(st.n_future - 1, 0)
    p = int(2 * st.w_max_m / st.profile_spacing_m) + 1
    g = 2 * int(math.ceil((st.w_max_m + footprint_radius_m + st.w_res_m) / st.w_res_m)) + 1
    return {"W": w, "C": c, "P": p, "G": g, "n": st.n_future}


def planner_bytes(st: Any, footprint_radius_m: float = DEFAULT_FOOTPRINT_M) -> float:
    """Peak bytes of the index-width search at one marker: the gathered pass profiles
    (W, C, 2n, P), the sums and masks (W, C, P) ×3 and the cross profiles (G, P), float64."""
    s = planner_search_size(st, footprint_radius_m)
    return 8.0 * (s["W"] * s["C"] * s["P"] * (2 * s["n"] + 3) + s["G"] * s["P"])


def check_planner_budget(st: Any, where: str,
                         footprint_radius_m: float = DEFAULT_FOOTPRINT_M) -> float:
    """Refuse planner settings whose index-width search would not fit in memory (the widths
    tried × the future-width sets × the profile points); returns the bytes estimate."""
    need = planner_bytes(st, footprint_radius_m)
    have = available_bytes()
    if need > 0.8 * have:
        s = planner_search_size(st, footprint_radius_m)
        raise BudgetError(
            f"{where}: the index-width search needs ~{gib(need)} ({s['W']:,} widths × "
            f"{s['C']:,} future-width sets (future_grid_n^(n_future−1)) × {s['P']:,} profile "
            f"points (2·w_max_m / profile_spacing_m)), more than {room_text()}; raise "
            "profile_spacing_m or w_res_m, or lower future_grid_n or n_future")
    return need


#: Memory a sweep holds per sample (its design row, seed, Dask future and record, ~2–4 kB of
#: JSON as a Python dict) [B] — an upper estimate.
BYTES_PER_SWEEP_SAMPLE = 50_000
#: Most samples a sweep takes: the yield's 95 % Clopper–Pearson interval is ±0.1 pp there.
MAX_SWEEP_SAMPLES = 1_000_000


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
