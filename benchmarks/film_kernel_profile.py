"""Where the compiled film kernel's time goes, and what a change of it buys, in one process.

Variants of `paintcell.planning.paint.deposition_jit` are compiled from its own source with one
change each
(cache off) and timed on the door problem of `benchmarks/deposition.py` (door at 5 mm under a
raster of 2,140 gun samples, the same evaluated pairs for every variant), one thread,
round-robin, best CPU time of --rounds rounds (other jobs share this machine: CPU time, not
wall). Printed per variant: CPU time, evaluated pairs per CPU-second, ratio against the shipped
kernel, agreement with the numpy kernel relative to the peak film.

- shipped: the kernel as it is (2^y: exact split y = k + f, 2^f by a degree-10 Chebyshev
  polynomial evaluated by Estrin's scheme, exponents pre-scaled by log2 e);
- exp as before: e^x by Cody–Waite reduction and the degree-11 Taylor polynomial by Horner's
  rule (the kernel up to this change);
- 2^f Chebyshev by Horner: the shipped polynomial evaluated by Horner's rule (10 dependent
  multiply-adds instead of 4 levels);
- profile, 1 exp / 0 exp: the rings' exps (and then the core's) replaced by a multiply — wrong
  films, only to show the share of the exps in the time (their agreement is not a result).

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

import paintcell.planning
from paintcell.planning.paint import deposition as dep
from paintcell.planning.paint import deposition_jit as jit
from paintcell.planning.paint.applicator import Applicator

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from deposition import door_points, evaluated_pairs, raster  # noqa: E402

_F = ("                        f = (amp0 * _exp2_neg(-(u2 * cx2 + v2 * cy2))\n"
      "                             + ra1 * _exp2_neg(-t1 * t1) + ra2 * _exp2_neg(-t2 * t2))")
#: the exp of the kernel before this profile's last change: e^x by range reduction with ln 2
#: (Cody–Waite) and the degree-11 Taylor polynomial of e^r by Horner's rule, constants as they
#: were (the kernel then called it with the unscaled exponents: rescaled here by 1/log2 e).
_OLD_EXP = """        x = max(y, _Y_FLOOR) * 0.6931471805599453
        k = math.floor(x * 1.4426950408889634 + 0.5)
        r = (x - k * 0.693145751953125) - k * 1.4286068203094173e-06
        p = 1.0 / 39916800.0
        p = p * r + 1.0 / 3628800.0
        p = p * r + 1.0 / 362880.0
        p = p * r + 1.0 / 40320.0
        p = p * r + 1.0 / 5040.0
        p = p * r + 1.0 / 720.0
        p = p * r + 1.0 / 120.0
        p = p * r + 1.0 / 24.0
        p = p * r + 1.0 / 6.0
        p = p * r + 0.5
        p = p * r + 1.0
        p = p * r + 1.0
        bits = np.int64((np.int64(k) + 1023) << 52)
        return p * bits.view(np.float64)
"""
_NEW_EXP_START = "        y = max(y, _Y_FLOOR)\n"
_NEW_EXP_END = "        return p * bits.view(np.float64)\n"
_HORNER = """        y = max(y, _Y_FLOOR)
        t = y + _ROUND
        k = t - _ROUND
        f = y - k
        p = 7.072585949269223e-09
        p = p * f + 1.0208690299958306e-07
        p = p * f + 1.321544258792169e-06
        p = p * f + 1.5252657260200837e-05
        p = p * f + 0.0001540353044173605
        p = p * f + 0.0013333558230164974
        p = p * f + 0.009618129107606888
        p = p * f + 0.05550410866444772
        p = p * f + 0.24022650695910097
        p = p * f + 0.69314718055995
        p = p * f + 1.0
        bits = np.int64((np.float64(t).view(np.int64) + 1023) << 52)
        return p * bits.view(np.float64)
"""
VARIANTS: dict[str, list[tuple[str, str]]] = {
    "shipped": [],
    "exp as before (e^r Taylor, Horner)": [("EXP", _OLD_EXP)],
    "2^f Chebyshev by Horner (no Estrin)": [("EXP", _HORNER)],
    "profile: 1 exp (rings off)": [(_F, "                        f = amp0 * _exp2_neg(-(u2 "
                                          "* cx2 + v2 * cy2)) + ra1 * t1 * t1 + ra2 * t2 * t2")],
    "profile: 0 exp": [(_F, "                        f = amp0 * (u2 * cx2 + v2 * cy2) + ra1 * "
                        "t1 * t1 + ra2 * t2 * t2")],
}


def compile_variant(name: str, subs: list[tuple[str, str]]) -> types.ModuleType:
    """`paintcell.planning.paint.deposition_jit` from its source with `subs` applied (no on-disk
    cache)."""
    src = inspect.getsource(jit).replace("cache=True", "cache=False")
    for old, new in subs:
        if old == "EXP":  # the body of _exp2_neg
            i = src.index(_NEW_EXP_START)
            old = src[i:src.index(_NEW_EXP_END, i) + len(_NEW_EXP_END)]
        if old not in src:
            raise SystemExit(f"variant {name!r}: the kernel source changed; update this script")
        src = src.replace(old, new)
    mod = types.ModuleType(f"deposition_jit_{len(name)}")
    mod.__file__ = jit.__file__
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
    shipped = sys.modules["paintcell.planning.paint.deposition_jit"]
    try:
        for rnd in range(args.rounds + 1):           # round 0 compiles
            for k, mod in mods.items():
                sys.modules["paintcell.planning.paint.deposition_jit"] = mod
                paintcell.planning.paint.deposition_jit = mod  # type: ignore[attr-defined]
                c0 = time.process_time()
                out = dep.thickness(app, gun, p, n, backend="numba", threads=1)
                c = time.process_time() - c0
                if rnd == 0:
                    err[k] = float(np.abs(out - ref).max() / ref.max())
                else:
                    best[k] = min(best[k], c)
    finally:
        sys.modules["paintcell.planning.paint.deposition_jit"] = shipped
        paintcell.planning.paint.deposition_jit = shipped  # type: ignore[attr-defined]
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
