"""Surface construction speed: every library part at 5 mm and 10 mm, and discrete curvature.

Run: .venv/bin/python benchmarks/surface.py   (prints one figure per line with label and unit)
"""

from __future__ import annotations

import time

import numpy as np

from paintcell.surface.curvature import discrete_curvature
from paintcell.surface.parts import PART_NAMES, get_part
from paintcell.surface.surface_data import Surface


def best_of(fn, repeats: int = 3) -> float:
    """Best wall time of `repeats` calls [s]."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    for res in (0.005, 0.010):
        for name in PART_NAMES:
            s = get_part(name, res)
            dt = best_of(lambda n=name, r=res: get_part(n, r))
            print(f"build {name} @ {res * 1e3:.0f} mm: {dt * 1e3:.1f} ms "
                  f"({len(s.vertices)} vertices)")
    door = get_part("door", 0.005)
    dt = best_of(lambda: discrete_curvature(door.vertices, door.faces))
    print(f"discrete curvature, door @ 5 mm: {dt * 1e3:.1f} ms ({len(door.vertices)} vertices)")
    dt = best_of(lambda: Surface.from_mesh(door.mesh), repeats=2)
    print(f"Surface.from_mesh, door @ 5 mm: {dt * 1e3:.1f} ms")
    d = discrete_curvature(door.vertices, door.faces)
    err = np.abs(d.mean - door.mean_curvature)[~d.boundary].max()
    print(f"door @ 5 mm: max |H_discrete - H_analytic| interior: {err:.2e} 1/m")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
