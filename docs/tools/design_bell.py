"""Re-run the design of the default bell (`paintcell/paint/data/default_bell.toml`).

The bell's eight shape parameters (σx, σy, the two rings' amplitude ratios to A0, radii and
widths) are searched by Nelder-Mead (scipy) with the emitted flow held at the start bell's. The
objective is the worst, over a plane and convex cylinders of the given radii (passes along the
axis, bell at standoff along the normal), of the smallest "robust" σ/μ of equally spaced passes:
the largest σ/μ over a ±25 mm window of index widths (the planner's `width_tolerance_m`),
minimised over window centres ≥ --min-centre; the plane's figure is weighted by --plane-weight,
and a footprint radius above --max-footprint costs 10 per metre. The film of one pass on a
cylinder is the line integral of `paintcell.paint.deposition.deposition_rate` along the
pass (on the plane: `paintcell.coverage.index_width.nsd_vs_index_width`).

The shipped bell: `--radii 1.0,0.5,0.38 --widths 0.20,0.45 --min-centre 0.30 --plane-weight 1.5
--max-footprint 0.46 --iterations 1500`, started from the result of the same search with
`--radii 1.0,0.5 --min-centre 0.28 --max-footprint 0.40` (rounded to 4 digits).
Run: `PYTHONPATH=$PWD .venv/bin/python docs/tools/design_bell.py --help` (about a minute).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import minimize

from paintcell.coverage.index_width import nsd_vs_index_width
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate


def cylinder_pass_film(app: Applicator, radius_m: float, arc_m: np.ndarray) -> np.ndarray:
    """(P,) film [m] of one straight pass at 1 m/s along a convex cylinder's axis at the arc
    lengths `arc_m` (P,) [m] across it (0: under the bell)."""
    r = 1.25 * app.footprint_radius_m
    dx = 0.4 * min([app.sigma_x_m, app.sigma_y_m, *app.ring_sigmas_m])
    x = np.arange(-r, r + 0.5 * dx, dx)
    h = app.standoff_m
    gun = np.stack([x, np.zeros_like(x), np.full_like(x, radius_m + h)], axis=1)
    th = arc_m / radius_m
    nrm = np.stack([np.zeros_like(th), np.sin(th), np.cos(th)], axis=1)
    out = np.zeros(len(arc_m))
    ok = np.abs(th) < np.pi / 2
    rate = deposition_rate(app, gun, np.tile([0.0, 0.0, -1.0], (len(x), 1)),
                           np.tile([1.0, 0.0, 0.0], (len(x), 1)), radius_m * nrm[ok], nrm[ok])
    out[ok] = rate.sum(axis=0) * dx
    return out


def nsd_equal_passes(app: Applicator, radius_m: float, widths_m: np.ndarray) -> np.ndarray:
    """(W,) σ/μ (fraction) of equally spaced passes on a convex cylinder of `radius_m` [m]."""
    reach = 1.6 * app.footprint_radius_m
    s = np.arange(-reach, reach + 1e-4, 1e-3)
    g = cylinder_pass_film(app, radius_m, s)
    out = []
    for w in widths_m:
        k = np.arange(-int(np.ceil(reach / w)) - 1, int(np.ceil(reach / w)) + 2)
        q = (np.arange(100) + 0.5) / 100 * w
        f = np.interp(q[None, :] - k[:, None] * w, s, g, left=0, right=0).sum(axis=0)
        out.append(f.std() / f.mean())
    return np.array(out)


def bell(p: np.ndarray, flow_m3_s: float, standoff_m: float) -> Applicator:
    """The bell of shape parameters p = (σx, σy, A1/A0, A2/A0, μ1, μ2, σ1, σ2) at `flow_m3_s`."""
    sx, sy, r1, r2, m1, m2, s1, s2 = (float(v) for v in p)
    unit = Applicator(standoff_m=standoff_m, a0_m_s=1.0, sigma_x_m=sx, sigma_y_m=sy,
                      ring_amplitudes_m_s=[r1, r2], ring_radii_m=[m1, m2],
                      ring_sigmas_m=[s1, s2], name="default_bell")
    k = flow_m3_s / unit.emitted_flow_m3_s
    return Applicator(standoff_m=standoff_m, a0_m_s=k, sigma_x_m=sx, sigma_y_m=sy,
                      ring_amplitudes_m_s=[k * r1, k * r2], ring_radii_m=[m1, m2],
                      ring_sigmas_m=[s1, s2], name="default_bell")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--radii", default="1.0,0.5,0.38", help="cylinder radii [m], comma-separated")
    ap.add_argument("--widths", default="0.20,0.45", help="index widths searched, min,max [m]")
    ap.add_argument("--min-centre", type=float, default=0.30,
                    help="smallest centre of the ±25 mm robust window [m]")
    ap.add_argument("--plane-weight", type=float, default=1.5, help="weight of the plane's σ/μ")
    ap.add_argument("--max-footprint", type=float, default=0.46, help="footprint radius bound [m]")
    ap.add_argument("--iterations", type=int, default=1500, help="Nelder-Mead iterations")
    args = ap.parse_args()
    start = Applicator.default()
    flow = start.emitted_flow_m3_s
    a0 = start.a0_m_s
    x0 = np.array([start.sigma_x_m, start.sigma_y_m, start.ring_amplitudes_m_s[0] / a0,
                   start.ring_amplitudes_m_s[1] / a0, *start.ring_radii_m, *start.ring_sigmas_m])
    radii = [float(r) for r in args.radii.split(",")]
    lo, hi = (float(v) for v in args.widths.split(","))
    widths = np.arange(lo, hi + 1e-9, 0.01)

    def curves(app: Applicator) -> np.ndarray:
        return np.array([nsd_vs_index_width(app, widths)]
                        + [nsd_equal_passes(app, r, widths) for r in radii])

    def robust(n: np.ndarray) -> float:
        return min(float(n[np.abs(widths - c) <= 0.025 + 1e-9].max())
                   for c in widths if c >= args.min_centre - 1e-9)

    def objective(p: np.ndarray) -> float:
        if np.any(p[[0, 1, 4, 5, 6, 7]] <= 0.005) or np.any(p[2:4] < 0):
            return 10.0
        app = bell(p, flow, start.standoff_m)
        rob = [robust(n) for n in curves(app)]
        return max(args.plane_weight * rob[0], *rob[1:]) \
            + 10.0 * max(0.0, app.footprint_radius_m - args.max_footprint)

    res = minimize(objective, x0, method="Nelder-Mead",
                   options={"maxiter": args.iterations, "xatol": 1e-5, "fatol": 1e-6})
    app = bell(res.x, flow, start.standoff_m)
    print(f"objective {res.fun:.5f}; footprint radius {app.footprint_radius_m:.3f} m")
    for name, n in zip(["plane"] + [f"R {r:g} m" for r in radii], curves(app), strict=True):
        print(f"{name:>8}: " + " ".join(f"{1000 * w:.0f}:{100 * v:.2f}"
                                        for w, v in zip(widths, n, strict=True)) + "  (mm:%)")
    print({k: (round(v, 7) if isinstance(v, float) else v) for k, v in app.to_dict().items()})


if __name__ == "__main__":
    main()
