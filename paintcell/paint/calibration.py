"""Fit an `Applicator` to a measured flat-panel test: a stripe cross profile or a static pattern.

This is how painters calibrate commercial simulators: spray one constant-speed straight pass over
a flat panel at the reference standoff, measure the film across the stripe, and fit the model.

The cross profile of an (infinitely long) pass at speed v is the line integral of f along travel:

    t(y) = (1/v) ∫ f(x, y) dx
         = (1/v) [ A0 σx √(2π) e^{-y²/2σy²}  +  Σ_k Ak ∫ e^{-(√(x²+y²) − μk)²/2σk²} dx ]

The bivariate part integrates in closed form; the ring part by Gauss–Legendre quadrature over
|x| ≤ √((μk + 9σk)² − y²) (vectorized over all y). One cross profile fixes A0·σx, not A0 and σx
apart: the single-stripe fit holds σx/σy at the initial guess's ratio (1 unless `initial` says).
Two stripes crossing at right angles (one pass along x, one along y, on the same panel or two
panels) give ∫ f dx (y) and ∫ f dy (x): the central Gaussian contributes A0 σx √(2π) e^{-y²/2σy²}
to the first and A0 σy √(2π) e^{-x²/2σx²} to the second (the rings are round and contribute the
same function to both), so `fit_applicator_from_crossing_stripes` determines A0, σx and σy.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import OptimizeResult, least_squares

from paintcell.core.errors import ApplicatorError
from paintcell.paint.applicator import Applicator

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(128)
_RING_SPAN = 9.0  # ring integrand e^{-(r-μ)²/2σ²} < 3e-18 beyond r = μ + 9σ


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of a fit.

    applicator: the fitted model (at the given standoff).
    residual_rms_m: RMS of (model − data) in the data's unit (m for thickness, m/s for a rate).
    residual_rel: residual_rms_m ÷ the data's peak (a fraction).
    center_offset_m: fitted position of the pattern centre in the data's coordinates [m]: (y0,)
        for a stripe, (x0, y0) for a grid.
    success: the optimizer's convergence flag; message: its message.
    """

    applicator: Applicator
    residual_rms_m: float
    residual_rel: float
    center_offset_m: tuple[float, ...] = ()
    success: bool = True
    message: str = ""


def ring_line_integral(y_m: npt.ArrayLike, radius_m: float, sigma_m: float) -> np.ndarray:
    """∫ exp(−(√(x²+y²) − μ)² / 2σ²) dx over all x [m], for each y (P,) [m].

    Gauss–Legendre (128 nodes) on [0, X(y)], X = √((μ + 9σ)² − y²), doubled by symmetry.
    """
    y = np.abs(np.asarray(y_m, float))
    reach = radius_m + _RING_SPAN * sigma_m
    xmax = np.sqrt(np.maximum(reach * reach - y * y, 0.0))           # (P,)
    x = 0.5 * xmax[:, None] * (_GL_NODES[None, :] + 1.0)             # (P, Q)
    r = np.sqrt(x * x + (y * y)[:, None])
    vals = np.exp(-((r - radius_m) ** 2) / (2.0 * sigma_m * sigma_m))
    return xmax * (vals @ _GL_WEIGHTS)                               # 2 · (xmax/2) · Σ w g


def stripe_profile(app: Applicator, y_m: npt.ArrayLike, speed_m_s: float) -> np.ndarray:
    """Film thickness (P,) [m] across one infinitely long straight pass at `speed_m_s` [m/s] over
    a flat panel at the reference standoff, at lateral offsets y_m (P,) [m] from the pass."""
    if not speed_m_s > 0:
        raise ApplicatorError(f"speed_m_s = {speed_m_s} must be > 0 [m/s]")
    y = np.asarray(y_m, float)
    out = app.a0_m_s * app.sigma_x_m * math.sqrt(2 * math.pi) * np.exp(
        -(y * y) / (2 * app.sigma_y_m**2))
    for a, mu, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                        strict=True):
        if a > 0:
            out = out + a * ring_line_integral(y.reshape(-1), mu, s).reshape(y.shape)
    return out / speed_m_s


def stripe_profile_across_x(app: Applicator, x_m: npt.ArrayLike, speed_m_s: float) -> np.ndarray:
    """Film (P,) [m] across a pass that travels along the tool y axis (the crossing stripe), at
    offsets x_m (P,) [m]: (1/v) ∫ f(x, y) dy."""
    swapped = Applicator(standoff_m=app.standoff_m, a0_m_s=app.a0_m_s, sigma_x_m=app.sigma_y_m,
                         sigma_y_m=app.sigma_x_m, ring_amplitudes_m_s=app.ring_amplitudes_m_s,
                         ring_radii_m=app.ring_radii_m, ring_sigmas_m=app.ring_sigmas_m)
    return stripe_profile(swapped, x_m, speed_m_s)


def fit_applicator_from_crossing_stripes(y_m: npt.ArrayLike, thickness_y_m: npt.ArrayLike,
                                         x_m: npt.ArrayLike, thickness_x_m: npt.ArrayLike,
                                         speed_m_s: float, standoff_m: float,
                                         initial: Applicator | None = None) -> CalibrationResult:
    """Fit every model parameter (A0, σx, σy apart, and the rings) to two crossing stripes.

    y_m, thickness_y_m: (P,) cross profile of a pass along the tool x axis (travel), sampled
        across it [m]; x_m, thickness_x_m: (Q,) cross profile of a pass along the tool y axis,
        sampled across it [m] (the bell turned by 90° relative to its path, or the panel);
    speed_m_s: speed of both passes [m/s]; standoff_m: the test standoff [m];
    initial: starting model (default: the shipped bell's shape scaled to the stripes).
    Both stripes are centred at 0 (fit each centre first with `fit_applicator_from_stripe` if
    needed). The residual is reported over both profiles together [m].
    """
    y = np.asarray(y_m, float).reshape(-1)
    ty = np.asarray(thickness_y_m, float).reshape(-1)
    x = np.asarray(x_m, float).reshape(-1)
    tx = np.asarray(thickness_x_m, float).reshape(-1)
    if len(y) != len(ty) or len(x) != len(tx):
        raise ApplicatorError(f"stripe samples and thicknesses differ in length ({len(y)}/"
                              f"{len(ty)}, {len(x)}/{len(tx)}); give one thickness per position")
    _check_data(y, ty)
    _check_data(x, tx)
    if not (speed_m_s > 0 and standoff_m > 0):
        raise ApplicatorError("speed_m_s and standoff_m must be > 0")
    peak = float(max(np.max(np.abs(ty)), np.max(np.abs(tx))))
    if peak <= 0:
        raise ApplicatorError("the stripes have no paint (all thickness zero); check the data")
    w = np.clip(ty, 0.0, None)
    width = float(np.sqrt(np.sum(w * y * y) / np.sum(w)))
    order = np.argsort(y)
    volume_rate = float(np.sum(w[order] * np.gradient(y[order]))) * speed_m_s
    init = _initial_guess(initial, standoff_m, width, volume_rate)
    app, rms, _, res = _fit(
        init, standoff_m, None, (), np.concatenate([ty, tx]), peak,
        lambda app, c: np.concatenate([stripe_profile(app, y, speed_m_s),
                                       stripe_profile_across_x(app, x, speed_m_s)]))
    return CalibrationResult(app, rms, rms / peak, (0.0, 0.0), bool(res.success),
                             str(res.message))


def _check_data(*arrays: np.ndarray) -> None:
    for arr in arrays:
        if arr.size < 12:
            raise ApplicatorError(f"calibration needs at least 12 samples, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise ApplicatorError("calibration data contain NaN or inf; clean the measurement")


def _initial_guess(initial: Applicator | None, standoff_m: float, width_m: float,
                   volume_rate: float) -> Applicator:
    """The initial model: `initial`, or the default bell's shape scaled to the measured width
    (second moment) and emitted flow."""
    if initial is not None:
        return initial
    base = Applicator.default()
    base_width = _default_width(base)
    k = width_m / base_width if width_m > 0 else 1.0
    d = base.to_dict()
    d["standoff_m"] = standoff_m
    for key in ("sigma_x_m", "sigma_y_m"):
        d[key] *= k
    d["ring_radii_m"] = [v * k for v in d["ring_radii_m"]]
    d["ring_sigmas_m"] = [v * k for v in d["ring_sigmas_m"]]
    app = Applicator.from_dict(d)
    scale = volume_rate / app.emitted_flow_m3_s if volume_rate > 0 else 1.0
    d["a0_m_s"] *= scale
    d["ring_amplitudes_m_s"] = [v * scale for v in d["ring_amplitudes_m_s"]]
    d["name"] = "calibrated"
    return Applicator.from_dict(d)


def _default_width(app: Applicator) -> float:
    y = np.linspace(-app.footprint_radius_m, app.footprint_radius_m, 801)
    prof = stripe_profile(app, y, 1.0)
    return float(np.sqrt(np.sum(prof * y * y) / np.sum(prof)))


def _unpack(theta: np.ndarray, standoff_m: float, ratio_x_y: float | None,
            name: str) -> Applicator:
    """θ = [A0, σx (grid only), σy, A1, A2, μ1, μ2, σ1, σ2, centre…]."""
    if ratio_x_y is None:
        a0, sx, sy = theta[0], theta[1], theta[2]
        rest = theta[3:]
    else:
        a0, sy = theta[0], theta[1]
        sx = ratio_x_y * sy
        rest = theta[2:]
    return Applicator(standoff_m=standoff_m, a0_m_s=a0, sigma_x_m=sx, sigma_y_m=sy,
                      ring_amplitudes_m_s=rest[0:2], ring_radii_m=rest[2:4],
                      ring_sigmas_m=rest[4:6], name=name)


def _pack(app: Applicator, stripe: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θ0 and its lower/upper bounds; amplitudes scaled by `amp_scale` outside."""
    if len(app.ring_amplitudes_m_s) != 2:
        raise ApplicatorError("calibration fits exactly two rings; give an initial with two")
    head = [app.a0_m_s] + ([] if stripe else [app.sigma_x_m]) + [app.sigma_y_m]
    theta = np.array(head + list(app.ring_amplitudes_m_s) + list(app.ring_radii_m)
                     + list(app.ring_sigmas_m))
    n_head = len(head)
    lo = np.zeros_like(theta)
    lo[1:n_head] = 1e-4                          # σ > 0
    lo[n_head + 4:n_head + 6] = 1e-4             # ring σ > 0
    hi = np.full_like(theta, np.inf)
    return theta, lo, hi


def _fit(init: Applicator, standoff_m: float, ratio_x_y: float | None,
         center0: tuple[float, ...], data: np.ndarray, peak: float,
         predict: Callable[[Applicator, np.ndarray], np.ndarray],
         ) -> tuple[Applicator, float, tuple[float, ...], OptimizeResult]:
    """Least-squares fit of the model parameters (σx tied to σy by `ratio_x_y` unless None) and,
    when `center0` is not empty, of a centre offset starting there, so that
    `predict(applicator, centre)` matches `data` (residual scaled by `peak`).

    Returns (fitted applicator named "calibrated", RMS residual in the unit of `data`, the fitted
    centre (empty when none was fitted), the optimizer's result).
    """
    theta0, lo, hi = _pack(init, stripe=ratio_x_y is not None)
    n = len(theta0)
    amp_idx = np.array([0, 2, 3]) if ratio_x_y is not None else np.array([0, 3, 4])
    amp_scale = max(float(np.max(theta0[amp_idx])), 1e-30)
    theta0[amp_idx] /= amp_scale
    if center0:
        theta0 = np.append(theta0, center0)
        lo = np.append(lo, [-np.inf] * len(center0))
        hi = np.append(hi, [np.inf] * len(center0))

    def model(theta: np.ndarray) -> np.ndarray:
        th = theta.copy()
        th[amp_idx] *= amp_scale
        return predict(_unpack(th[:n], standoff_m, ratio_x_y, init.name), th[n:])

    res = least_squares(lambda th: (model(th) - data) / peak, theta0, bounds=(lo, hi),
                        x_scale="jac", method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12,
                        max_nfev=2000)
    th = res.x.copy()
    th[amp_idx] *= amp_scale
    app = _unpack(th[:n], standoff_m, ratio_x_y, "calibrated")
    rms = float(np.sqrt(np.mean((model(res.x) - data) ** 2)))
    return app, rms, tuple(float(c) for c in th[n:]), res


def fit_applicator_from_stripe(y_m: npt.ArrayLike, thickness_m: npt.ArrayLike, speed_m_s: float,
                               standoff_m: float, initial: Applicator | None = None,
                               fit_center: bool = True) -> CalibrationResult:
    """Fit the model to the cross profile of one constant-speed straight pass on a flat panel.

    y_m: (P,) lateral positions across the stripe [m]; thickness_m: (P,) measured film [m];
    speed_m_s: pass speed [m/s]; standoff_m: the standoff of the test [m];
    initial: starting model (its σx/σy ratio is kept, see the module note); default: the shipped
    bell's shape scaled to the stripe's width and volume;
    fit_center: also fit the stripe's centre line y0 (reported in `center_offset_m`).
    """
    y = np.asarray(y_m, float).reshape(-1)
    t = np.asarray(thickness_m, float).reshape(-1)
    if len(y) != len(t):
        raise ApplicatorError(f"y_m has {len(y)} samples but thickness_m {len(t)}")
    _check_data(y, t)
    if not (speed_m_s > 0 and standoff_m > 0):
        raise ApplicatorError("speed_m_s and standoff_m must be > 0")
    peak = float(np.max(np.abs(t)))
    if peak <= 0:
        raise ApplicatorError("the stripe has no paint (all thickness zero); check the data")
    w = np.clip(t, 0.0, None)
    y0_guess = float(np.sum(w * y) / np.sum(w))
    width = float(np.sqrt(np.sum(w * (y - y0_guess) ** 2) / np.sum(w)))
    dy = np.gradient(np.sort(y))
    volume_rate = float(np.sum(w[np.argsort(y)] * dy)) * speed_m_s   # ∫ t dy · v = emitted flow
    init = _initial_guess(initial, standoff_m, width, volume_rate)
    app, rms, center, res = _fit(
        init, standoff_m, init.sigma_x_m / init.sigma_y_m, (y0_guess,) if fit_center else (),
        t, peak, lambda app, c: stripe_profile(app, y - (c[0] if len(c) else 0.0), speed_m_s))
    return CalibrationResult(app, rms, rms / peak, center or (0.0,), bool(res.success),
                             str(res.message))


def fit_applicator_from_grid(x_m: npt.ArrayLike, y_m: npt.ArrayLike, values: npt.ArrayLike,
                             standoff_m: float, exposure_s: float | None = None,
                             initial: Applicator | None = None,
                             fit_center: bool = True) -> CalibrationResult:
    """Fit all model parameters to a 2-D static spray pattern on a flat panel at the standoff.

    x_m, y_m: positions [m] (x along the later travel direction), either the grid's 1-D axes,
        x of length nx and y of length ny for `values` of shape (ny, nx) (`np.meshgrid(x, y)`,
        indexing "xy"), or 2-D arrays of `values`' shape;
    values: (ny, nx) the measured rate [m/s], or thickness [m] after a static exposure of
        `exposure_s` [s];
    initial: starting model (default: the shipped bell's shape scaled to the pattern);
    fit_center: also fit the pattern centre (x0, y0) (reported in `center_offset_m`).
    The residual is reported in the unit of `values`.
    """
    xg, yg, vals = _grid_points(x_m, y_m, values)
    x, y, vals = xg.reshape(-1), yg.reshape(-1), vals.reshape(-1)
    _check_data(x, y, vals)
    if not standoff_m > 0:
        raise ApplicatorError("standoff_m must be > 0")
    if exposure_s is not None and not exposure_s > 0:
        raise ApplicatorError(f"exposure_s = {exposure_s} must be > 0 [s]")
    scale_t = 1.0 if exposure_s is None else float(exposure_s)
    rate = vals / scale_t
    peak = float(np.max(np.abs(rate)))
    if peak <= 0:
        raise ApplicatorError("the pattern has no paint (all zero); check the data")
    w = np.clip(rate, 0.0, None)
    c0 = (float(np.sum(w * x) / np.sum(w)), float(np.sum(w * y) / np.sum(w)))
    r2 = (x - c0[0]) ** 2 + (y - c0[1]) ** 2
    # the grid's cell area from the point count and the bounding box (a regular grid)
    area = float((np.ptp(x) * np.ptp(y)) / max(len(x), 1))
    volume_rate = float(np.sum(w) * area)
    width = float(np.sqrt(np.sum(w * r2) / np.sum(w) / 2.0))
    init = _initial_guess(initial, standoff_m, width, volume_rate)
    app, rms, center, res = _fit(
        init, standoff_m, None, c0 if fit_center else (), rate, peak,
        lambda app, c: app.flux(x - c[0], y - c[1]) if len(c) else app.flux(x, y))
    rms *= scale_t
    return CalibrationResult(app, rms, rms / (peak * scale_t), center or (0.0, 0.0),
                             bool(res.success), str(res.message))


def _grid_points(x_m: npt.ArrayLike, y_m: npt.ArrayLike,
                 values: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ny, nx) x, y and values of a measured grid from 1-D axes or equal-shape 2-D arrays.

    Plain broadcasting is refused: 1-D axes of equal length would pair points along the
    diagonal instead of spanning the grid.
    """
    x = np.asarray(x_m, float)
    y = np.asarray(y_m, float)
    v = np.asarray(values, float)
    if v.ndim != 2:
        raise ApplicatorError(f"values must be a 2-D grid (ny, nx), got shape {v.shape}; "
                              "reshape the measurement to rows of constant y")
    ny, nx = v.shape
    if x.ndim == 1 and y.ndim == 1 and x.shape == (nx,) and y.shape == (ny,):
        xg, yg = np.meshgrid(x, y, indexing="xy")
        return xg, yg, v
    if x.shape == v.shape and y.shape == v.shape:
        return x, y, v
    raise ApplicatorError(
        f"grid axes of shapes x {x.shape}, y {y.shape} do not match values {v.shape}; give 1-D "
        f"x ({nx},) and y ({ny},) axes or 2-D x and y of shape {v.shape}")
