"""Calibration: the stripe model against adaptive quadrature, and recovery of known parameters
from noisy synthetic stripes and static patterns."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from paintcell.core.errors import ApplicatorError
from paintcell.paint.applicator import Applicator
from paintcell.paint.calibration import (
    fit_applicator_from_crossing_stripes,
    fit_applicator_from_grid,
    fit_applicator_from_stripe,
    ring_line_integral,
    stripe_profile,
    stripe_profile_across_x,
)

from .helpers import CALIBRATION_PARAM_RTOL

BELLS = Path(__file__).resolve().parents[1] / "scenarios" / "bells"
TRUE = Applicator(standoff_m=0.25, a0_m_s=2.0e-5, sigma_x_m=0.055, sigma_y_m=0.055,
                  ring_amplitudes_m_s=[2.5e-5, 1.6e-5], ring_radii_m=[0.11, 0.21],
                  ring_sigmas_m=[0.028, 0.033])


def _rel_errors(fit: Applicator, true: Applicator, stripe: bool) -> dict[str, float]:
    d, e = fit.to_dict(), true.to_dict()
    out = {"sigma_y_m": d["sigma_y_m"] / e["sigma_y_m"] - 1}
    if stripe:   # a cross profile fixes A0·σx only (module note)
        out["a0_sigma_x"] = d["a0_m_s"] * d["sigma_x_m"] / (e["a0_m_s"] * e["sigma_x_m"]) - 1
    else:
        out["a0_m_s"] = d["a0_m_s"] / e["a0_m_s"] - 1
        out["sigma_x_m"] = d["sigma_x_m"] / e["sigma_x_m"] - 1
    for k in ("ring_amplitudes_m_s", "ring_radii_m", "ring_sigmas_m"):
        for i in range(2):
            out[f"{k}[{i}]"] = d[k][i] / e[k][i] - 1
    return out


@pytest.mark.parametrize("mu,sigma", [(0.11, 0.028), (0.0, 0.05), (0.2, 0.01)])
def test_ring_line_integral_matches_quad(mu: float, sigma: float) -> None:
    ys = np.array([0.0, 0.05, mu, mu + 0.5 * sigma, mu + 3 * sigma, mu + 20 * sigma])
    got = ring_line_integral(ys, mu, sigma)
    for y, g in zip(ys, got, strict=True):
        def g_x(x: float, y: float = y) -> float:
            return math.exp(-(math.hypot(x, y) - mu) ** 2 / (2 * sigma**2))
        ref = integrate.quad(g_x, -1, 1, points=[0.0], epsabs=1e-14, epsrel=1e-12, limit=400)[0]
        assert g == pytest.approx(ref, rel=1e-8, abs=1e-13)


def test_stripe_profile_integrates_to_flow() -> None:
    y = np.linspace(-0.6, 0.6, 2401)
    prof = stripe_profile(TRUE, y, 0.4)
    assert np.trapezoid(prof, y) * 0.4 == pytest.approx(TRUE.emitted_flow_m3_s, rel=1e-9)


@pytest.mark.parametrize("initial", [None, "narrow_bell.toml"])
def test_noise_free_stripe_is_recovered_exactly(initial: str | None) -> None:
    # from the shipped bell's shape scaled to the stripe (the default start), and from a given
    # model (the narrow bell, whose rings lie near TRUE's; a local fit needs a start of the
    # right shape: the unscaled default bell, rings at 0.13 / 0.31 m, does not converge here)
    y = np.linspace(-0.4, 0.4, 401)
    start = None if initial is None else Applicator.from_toml(BELLS / initial)
    res = fit_applicator_from_stripe(y, stripe_profile(TRUE, y, 0.5), 0.5, 0.25, initial=start)
    errs = _rel_errors(res.applicator, TRUE, stripe=True)
    assert max(abs(v) for v in errs.values()) < 1e-5, errs
    assert res.residual_rel < 1e-8 and res.success


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_stripe_recovers_parameters(seed: int) -> None:
    # 801 samples, σ_noise = 0.2 % of the peak (0.04 µm on 20 µm), stripe off-centre by 12 mm
    rng = np.random.default_rng(seed)
    y = np.linspace(-0.4, 0.4, 801)
    clean = stripe_profile(TRUE, y - 0.012, 0.5)
    noisy = clean + rng.normal(0.0, 0.002 * clean.max(), clean.shape)
    res = fit_applicator_from_stripe(y, noisy, 0.5, 0.25)
    errs = _rel_errors(res.applicator, TRUE, stripe=True)
    assert max(abs(v) for v in errs.values()) < CALIBRATION_PARAM_RTOL, errs
    assert res.center_offset_m[0] == pytest.approx(0.012, abs=1e-3)
    # the residual is the noise: nothing systematic is left
    assert res.residual_rel == pytest.approx(0.002, rel=0.15)
    assert res.residual_rms_m == pytest.approx(res.residual_rel * noisy.max(), rel=1e-12)


def test_noisy_grid_recovers_all_parameters() -> None:
    true = Applicator(standoff_m=0.25, a0_m_s=2.0e-5, sigma_x_m=0.045, sigma_y_m=0.065,
                      ring_amplitudes_m_s=[2.5e-5, 1.6e-5], ring_radii_m=[0.11, 0.21],
                      ring_sigmas_m=[0.028, 0.033])
    rng = np.random.default_rng(7)
    x = np.linspace(-0.35, 0.35, 71)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    exposure = 2.0
    film = true.flux(xx - 0.005, yy + 0.003) * exposure
    film = film + rng.normal(0.0, 0.01 * film.max(), film.shape)
    res = fit_applicator_from_grid(xx, yy, film, 0.25, exposure_s=exposure)
    errs = _rel_errors(res.applicator, true, stripe=False)
    assert max(abs(v) for v in errs.values()) < CALIBRATION_PARAM_RTOL, errs
    assert res.center_offset_m == pytest.approx((0.005, -0.003), abs=5e-4)
    assert res.residual_rel == pytest.approx(0.01, rel=0.15)


def test_bad_calibration_data_raise() -> None:
    y = np.linspace(-0.3, 0.3, 50)
    with pytest.raises(ApplicatorError, match="samples"):
        fit_applicator_from_stripe(y[:5], y[:5], 0.5, 0.25)
    with pytest.raises(ApplicatorError, match="NaN"):
        fit_applicator_from_stripe(y, np.full(50, np.nan), 0.5, 0.25)
    with pytest.raises(ApplicatorError, match="no paint"):
        fit_applicator_from_stripe(y, np.zeros(50), 0.5, 0.25)
    with pytest.raises(ApplicatorError, match="> 0"):
        fit_applicator_from_stripe(y, np.ones(50), 0.0, 0.25)
    with pytest.raises(ApplicatorError, match="exposure"):
        fit_applicator_from_grid(y, y, np.ones((50, 50)), 0.25, exposure_s=-1.0)


@pytest.mark.parametrize("nx,ny", [(41, 41), (61, 41)])
def test_grid_from_1d_axes_recovers_parameters(nx: int, ny: int) -> None:
    # 1-D axes span the grid (meshgrid, indexing "xy": values[iy, ix]); broadcasting equal-length
    # axes would pair the points along the diagonal and fit the wrong pattern
    true = Applicator(standoff_m=0.25, a0_m_s=2.0e-5, sigma_x_m=0.045, sigma_y_m=0.065,
                      ring_amplitudes_m_s=[2.5e-5, 1.6e-5], ring_radii_m=[0.11, 0.21],
                      ring_sigmas_m=[0.028, 0.033])
    x = np.linspace(-0.35, 0.35, nx)
    y = np.linspace(-0.35, 0.35, ny)
    rate = true.flux(x[None, :], y[:, None])                 # (ny, nx)
    res = fit_applicator_from_grid(x, y, rate, 0.25)
    errs = _rel_errors(res.applicator, true, stripe=False)
    assert max(abs(v) for v in errs.values()) < 1e-5, errs
    assert res.success and res.residual_rel < 1e-8


def test_grid_shape_mismatch_names_expected_shapes() -> None:
    x = np.linspace(-0.3, 0.3, 41)
    with pytest.raises(ApplicatorError, match=r"give 1-D x \(41,\) and y \(31,\)"):
        fit_applicator_from_grid(x, x[:30], np.ones((31, 41)), 0.25)
    with pytest.raises(ApplicatorError, match="2-D grid"):
        fit_applicator_from_grid(x, x, np.ones(41), 0.25)


def test_crossing_stripe_is_the_quadrature_of_f_along_y() -> None:
    x = np.array([0.0, 0.04, 0.13, 0.25])
    v = 0.4
    want = [integrate.quad(lambda yy, xx=xx: float(TRUE.flux(xx, yy)), -1.0, 1.0,
                           points=[0.0], limit=200)[0] / v for xx in x]
    np.testing.assert_allclose(stripe_profile_across_x(TRUE, x, v), want, rtol=1e-8)


@pytest.mark.parametrize("seed", [0, 1])
def test_crossing_stripes_determine_sigma_x_and_sigma_y(seed: int) -> None:
    """Two noisy stripes crossing at right angles recover A0, σx and σy apart (one stripe only
    fixes A0·σx), and the rings, within the calibration tolerance."""
    true = Applicator(standoff_m=0.25, a0_m_s=3e-5, sigma_x_m=0.05, sigma_y_m=0.08,
                      ring_amplitudes_m_s=[1e-5, 6e-6], ring_radii_m=[0.12, 0.21],
                      ring_sigmas_m=[0.04, 0.035])
    rng = np.random.default_rng(seed)
    y = np.linspace(-0.4, 0.4, 161)
    ty = stripe_profile(true, y, 0.5) * (1 + 0.005 * rng.standard_normal(len(y)))
    tx = stripe_profile_across_x(true, y, 0.5) * (1 + 0.005 * rng.standard_normal(len(y)))
    res = fit_applicator_from_crossing_stripes(y, ty, y, tx, 0.5, 0.25)
    assert res.success
    d, e = res.applicator.to_dict(), true.to_dict()
    for key in ("a0_m_s", "sigma_x_m", "sigma_y_m"):
        assert d[key] == pytest.approx(e[key], rel=CALIBRATION_PARAM_RTOL), key
    for key in ("ring_amplitudes_m_s", "ring_radii_m", "ring_sigmas_m"):
        np.testing.assert_allclose(d[key], e[key], rtol=CALIBRATION_PARAM_RTOL, err_msg=key)
    assert res.residual_rel < 0.01


def test_crossing_stripes_bad_data_raise() -> None:
    y = np.linspace(-0.3, 0.3, 40)
    t = stripe_profile(TRUE, y, 0.5)
    with pytest.raises(ApplicatorError):
        fit_applicator_from_crossing_stripes(y, t[:-1], y, t, 0.5, 0.25)
    with pytest.raises(ApplicatorError):
        fit_applicator_from_crossing_stripes(y, np.zeros(40), y, np.zeros(40), 0.5, 0.25)
    with pytest.raises(ApplicatorError):
        fit_applicator_from_crossing_stripes(y, t, y, t, 0.0, 0.25)
