"""Where the compiled film kernel's time goes, in one process.

Variants of `paintcell.paint.deposition_cpu` are compiled from its own source with one
change each (cache off) and timed on the door problem of `benchmarks/deposition.py` (door at
5 mm under a raster of 2,140 gun samples, the same evaluated pairs for every variant), one
thread, round-robin, best CPU time of --rounds rounds (other jobs share this machine: CPU time,
not wall). Printed per variant: CPU time, evaluated pairs per CPU-second, ratio against the
shipped kernel, agreement with the numpy kernel relative to the peak film.

- shipped: the kernel as it is (four samples side by side; 2^y: exact split y = k + f, 2^f by
  a degree-10 Chebyshev polynomial in Horner's form, amplitudes folded into the exponents);
- profile, 1 exp / 0 exp: the rings' exps (and then the core's) replaced by their argument —
  wrong films, only to show the share of the exps in the time (their agreement is not a
  result).

    PYTHONPATH=$PWD .venv/bin/python benchmarks/film_kernel_profile.py [--rounds 6]
"""

from __future__ import annotations

import argparse
import inspect
import os
import sys
import time
import types

import numpy as np

from paintcell.paint import deposition as dep
from paintcell.paint import deposition_cpu as cpu
from paintcell.paint import deposition_jit as jit
from paintcell.paint.applicator import Applicator

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from deposition import door_points, evaluated_pairs, raster  # noqa: E402

_RINGS = ("h0, h1, h2, h3 = exp2_x4(l1 - x0 * x0, l1 - x1 * x1, l1 - x2 * x2, l1 - x3 * x3,\n"
          "                                             lo1)")
_RINGS2 = ("e0, e1, e2, e3 = exp2_x4(l2 - x0 * x0, l2 - x1 * x1, l2 - x2 * x2, l2 - x3 * x3,\n"
           "                                             lo2)")
_CORE = ("g0, g1, g2, g3 = exp2_x4(l0 - x0 * y0, l0 - x1 * y1, l0 - x2 * y2,\n"
         "                                             l0 - x3 * y3, lo0)")
_NO_RINGS = [(_RINGS, "h0, h1, h2, h3 = l1 - x0 * x0, l1 - x1 * x1, l1 - x2 * x2, l1 - x3 * x3"),
             (_RINGS2, "e0, e1, e2, e3 = l2 - x0 * x0, l2 - x1 * x1, l2 - x2 * x2, l2 - x3 * x3")]
VARIANTS: dict[str, list[tuple[str, str]]] = {
    "shipped": [],
    "profile: 1 exp (rings off)": _NO_RINGS,
    "profile: 0 exp": _NO_RINGS + [(_CORE, "g0, g1, g2, g3 = l0 - x0 * y0, l0 - x1 * y1, "
                                            "l0 - x2 * y2, l0 - x3 * y3")],
}


def compile_variant(name: str, subs: list[tuple[str, str]]) -> types.ModuleType:
    """`paintcell.paint.deposition_cpu` from its source with `subs` applied (no on-disk
    cache)."""
    src = inspect.getsource(cpu).replace("cache=True", "cache=False")
    for old, new in subs:
        if old not in src:
            raise SystemExit(f"variant {name!r}: the kernel source changed; update this script")
        src = src.replace(old, new)
    mod = types.ModuleType(f"deposition_cpu_{len(name)}")
    mod.__file__ = cpu.__file__
    exec(compile(src, mod.__name__, "exec"), mod.__dict__)  # noqa: S102 - our own source
    return mod


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=6, help="round-robin rounds (best CPU time)")
    args = ap.parse_args()
    print(f"load average (1 min) {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    app = Applicator.default()
    label, p, n = door_points()
    gun = raster()
    pairs = evaluated_pairs(app, gun, p, n)
    print(f"problem: {label}, {len(p)} points x {len(gun.dwell_s)} samples; evaluated pairs "
          f"{pairs / 1e6:.1f} M")
    ref = dep.thickness(app, gun, p, n, backend="numpy")
    mods = {k: compile_variant(k, v) for k, v in VARIANTS.items()}
    best = {k: np.inf for k in mods}
    err = {}
    shipped = jit.cpu
    try:
        for rnd in range(args.rounds + 1):           # round 0 compiles
            for k, mod in mods.items():
                jit.cpu = mod
                c0 = time.process_time()
                out = dep.thickness(app, gun, p, n, backend="numba", threads=1)
                c = time.process_time() - c0
                if rnd == 0:
                    err[k] = float(np.abs(out - ref).max() / ref.max())
                else:
                    best[k] = min(best[k], c)
    finally:
        jit.cpu = shipped
    base = best["shipped"]
    for k in mods:
        print(f"{k:<34} CPU {best[k] * 1e3:7.1f} ms  {pairs / best[k] / 1e6:6.1f} M evaluated "
              f"pairs per CPU-s  {base / best[k]:5.2f}x shipped  max|Δ|/peak vs numpy kernel "
              f"{err[k]:.1e}")
    no_exp, one_exp = best["profile: 0 exp"], best["profile: 1 exp (rings off)"]
    print(f"share of the three exps in the shipped kernel's time: {1 - no_exp / base:.0%} "
          f"(the rings' two: {1 - one_exp / base:.0%})")


if __name__ == "__main__":
    main()
