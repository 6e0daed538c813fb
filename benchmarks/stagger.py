"""Benchmark: a booth's start-delay search between two arms that work near each other
(`paintcell.booth.booth_stagger.pair_offsets_ok`, measured once per pair of robots).

Two arms' points (5 per arm, every 20 ms, 60 s programs: 3000 samples) wander over the same
1.5 m wide patch, as two rail robots painting a hood from either side do, so most of their
samples come within the 0.6 m bell distance of some sample of the other. The search asks which
start offsets keep them apart: at the stagger's 0.25 s step (offsets every 12 samples), and, as
the baseline in this process, at every sample (offsets every 1 sample, where every close pair
of samples counts). Prints each wall time [s] (best of 3) and their ratio.

    .venv/bin/python benchmarks/stagger.py [--samples 3000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paintcell.booth.booth_stagger import STAGGER_MAX_S, STAGGER_STEP_S, pair_offsets_ok

DT_S = 0.02
BELL_DISTANCE_M = 0.6


def _arm(rng: np.random.Generator, k: int, side: float) -> np.ndarray:
    """(k, 5, 3) points of an arm reaching over a 1.5 m patch from one side [m]."""
    t = np.linspace(0.0, 1.0, k)
    tip = np.column_stack([0.75 * np.sin(2 * np.pi * 6 * t + side), side * 0.35
                           + 0.3 * np.sin(2 * np.pi * 1.3 * t), 1.0 + 0.05 * np.cos(9 * t)])
    tip += np.cumsum(rng.normal(0.0, 0.002, (k, 3)), axis=0)
    base = np.array([0.0, side * 1.4, 0.8])
    f = np.linspace(0.0, 1.0, 5)[None, :, None]
    return base + f * (tip[:, None, :] - base)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=3000, help="samples per arm (20 ms each)")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    p, q = _arm(rng, args.samples, 1.0), _arm(rng, args.samples, -1.0)
    step = int(round(STAGGER_STEP_S / DT_S))
    dmax = int(round(STAGGER_MAX_S / DT_S))
    times = {}
    for label, offsets in ((f"at the stagger's step (every {step} samples)",
                            np.arange(-(dmax // step), dmax // step + 1) * step),
                           ("baseline: every close pair (every sample)",
                            np.arange(-dmax, dmax + 1))):
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            ok = pair_offsets_ok(p, q, offsets, BELL_DISTANCE_M)
            best = min(best, time.perf_counter() - t0)
        times[label] = best
        print(f"{label:<45} {best:8.3f} s  ({int(ok.sum())} of {len(ok)} offsets keep apart)")
    a, b = times.values()
    print(f"{'ratio baseline ÷ stagger step':<45} {b / a:8.2f} ×")


if __name__ == "__main__":
    main()
