"""Applicator: validation, closed-form emitted flow, footprint radius, TOML/dict round trips and
the shipped default bell's realism claims."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import integrate

from paintcell.core.errors import ApplicatorError
from paintcell.paint.applicator import FOOTPRINT_REL, Applicator
from paintcell.paint.deposition import deposition_rate_reference

from .helpers import DEPOSITION_EXACT_RTOL


def _app(**kw: object) -> Applicator:
    d = dict(standoff_m=0.25, a0_m_s=2e-5, sigma_x_m=0.04, sigma_y_m=0.06,
             ring_amplitudes_m_s=[1.5e-5, 1e-5], ring_radii_m=[0.1, 0.18],
             ring_sigmas_m=[0.025, 0.03], name="t")
    d.update(kw)
    return Applicator(**d)  # type: ignore[arg-type]


def test_emitted_flow_closed_form_matches_quadrature() -> None:
    app = _app()
    # central part in Cartesian, rings in polar: independent of the erf closed form
    gauss, _ = integrate.dblquad(lambda y, x: float(app.a0_m_s * math.exp(
        -x * x / (2 * app.sigma_x_m**2) - y * y / (2 * app.sigma_y_m**2))), -1, 1, -1, 1,
        epsabs=0, epsrel=1e-11)
    rings = sum(integrate.quad(lambda r, a=a, m=m, s=s: 2 * math.pi * r * a * math.exp(
        -(r - m) ** 2 / (2 * s * s)), 0, 2, epsabs=0, epsrel=1e-12, points=[m])[0]
        for a, m, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                           strict=True))
    assert app.emitted_flow_m3_s == pytest.approx(gauss + rings, rel=1e-9)


def test_emitted_flow_ring_near_center() -> None:
    # μ small against σ: the erf term matters (the ring is cut at r = 0)
    app = _app(a0_m_s=0.0, ring_amplitudes_m_s=[1e-5], ring_radii_m=[0.01], ring_sigmas_m=[0.05])
    ref, _ = integrate.quad(lambda r: 2 * math.pi * r * 1e-5 * math.exp(
        -(r - 0.01) ** 2 / (2 * 0.05**2)), 0, 1, epsabs=0, epsrel=1e-12)
    assert app.emitted_flow_m3_s == pytest.approx(ref, rel=1e-10)


def test_footprint_radius_bounds_flux_in_every_direction() -> None:
    app = _app()
    r_fp = app.footprint_radius_m
    ang = np.linspace(0, 2 * np.pi, 721)
    rr = r_fp * np.linspace(1.0, 3.0, 200)
    f = app.flux(rr[:, None] * np.cos(ang), rr[:, None] * np.sin(ang))
    assert f.max() <= FOOTPRINT_REL * app.peak_rate_m_s * (1 + 1e-9)
    # and it is tight: just inside, along the wide (y) axis, the flux is above the threshold
    assert app.flux(0.0, 0.999 * r_fp) > FOOTPRINT_REL * app.peak_rate_m_s
    # the peak is the true maximum over the plane
    g = np.linspace(-0.4, 0.4, 801)
    assert app.flux(g[:, None], g[None, :]).max() <= app.peak_rate_m_s * (1 + 1e-6)


def test_flux_broadcasts_and_matches_formula() -> None:
    app = _app()
    x = np.linspace(-0.2, 0.2, 5)[:, None]
    y = np.linspace(-0.3, 0.3, 7)[None, :]
    f = app.flux(x, y)
    assert f.shape == (5, 7)
    r = np.hypot(x, y)
    ref = 2e-5 * np.exp(-x**2 / (2 * 0.04**2) - y**2 / (2 * 0.06**2)) \
        + 1.5e-5 * np.exp(-(r - 0.1) ** 2 / (2 * 0.025**2)) \
        + 1e-5 * np.exp(-(r - 0.18) ** 2 / (2 * 0.03**2))
    np.testing.assert_allclose(f, ref, rtol=DEPOSITION_EXACT_RTOL)


def test_dict_json_and_toml_round_trip(tmp_path) -> None:
    app = _app(a0_m_s=1.2345678901234567e-5)
    assert Applicator.from_dict(json.loads(json.dumps(app.to_dict()))) == app
    path = tmp_path / "bell.toml"
    app.to_toml(path)
    back = Applicator.from_toml(path)
    assert back == app and back.to_dict() == app.to_dict()
    assert back.emitted_flow_m3_s == app.emitted_flow_m3_s


@pytest.mark.parametrize("kw", [
    {"sigma_x_m": 0.0}, {"sigma_y_m": -0.1}, {"standoff_m": 0.0}, {"standoff_m": float("nan")},
    {"a0_m_s": -1e-6}, {"a0_m_s": float("inf")}, {"ring_amplitudes_m_s": [-1e-6, 1e-6]},
    {"ring_sigmas_m": [0.0, 0.02]}, {"ring_radii_m": [-0.1, 0.2]},
    {"ring_radii_m": [0.1, 0.2, 0.3]}, {"a0_m_s": 0.0, "ring_amplitudes_m_s": [0.0, 0.0]},
    {"sigma_x_m": "wide"}, {"name": 3},
])
def test_bad_parameters_raise(kw: dict) -> None:
    with pytest.raises(ApplicatorError, match="valid|name"):
        _app(**kw)


def test_bad_files_and_keys_raise(tmp_path) -> None:
    with pytest.raises(ApplicatorError, match="does not exist"):
        Applicator.from_toml(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("standoff_m = [")
    with pytest.raises(ApplicatorError, match="not valid TOML"):
        Applicator.from_toml(bad)
    d = _app().to_dict()
    with pytest.raises(ApplicatorError, match="unknown"):
        Applicator.from_dict({**d, "flow": 1.0})
    d.pop("sigma_x_m")
    with pytest.raises(ApplicatorError, match="missing"):
        Applicator.from_dict(d)


def test_arrays_are_read_only() -> None:
    app = _app()
    with pytest.raises(ValueError):
        app.ring_radii_m[0] = 1.0


def test_default_bell_matches_its_documented_properties() -> None:
    """The TOML's claims, re-measured independently of paintcell.coverage.index_width: the
    stripe from the
    quadrature of f over x, the raster σ/μ by periodic summation of that stripe."""
    app = Applicator.default()
    assert app.name == "default_bell"
    assert 0.2 <= app.standoff_m <= 0.3
    y = np.linspace(-0.6, 0.6, 2401)
    x = np.linspace(-0.6, 0.6, 2401)
    prof = np.trapezoid(app.flux(x[None, :], y[:, None]), x, axis=1)
    wide = y[prof > 0.02 * prof.max()]
    assert 0.7 <= wide.max() - wide.min() <= 0.8          # stripe 0.7-0.8 m wide at 2 % of peak
    assert app.footprint_radius_m == pytest.approx(0.46, abs=0.001)
    flow = np.trapezoid(prof, y)
    assert flow == pytest.approx(app.emitted_flow_m3_s, rel=1e-4)
    # 0.5 m/s passes 0.32 m apart build 20 µm (mean film = flow / (v · w))
    assert flow / (0.5 * 0.32) == pytest.approx(20e-6, rel=0.01)

    def nsd(w: float) -> float:
        q = (np.arange(400) + 0.5) / 400 * w
        k = np.arange(-5, 6)
        film = np.interp(q[None, :] - k[:, None] * w, y, prof, left=0, right=0).sum(axis=0)
        return float(film.std() / film.mean())

    assert nsd(0.35) < 0.012                               # the sweet spot, σ/μ < 1.2 %
    assert max(nsd(w) for w in np.arange(0.33, 0.3701, 0.005)) <= 0.0264
    assert nsd(0.39) == pytest.approx(0.0427, abs=0.001)
    assert nsd(0.40) > 0.05


def test_default_bell_keeps_a_sweet_spot_on_a_convex_cylinder() -> None:
    """The reason for the bell's shape (its TOML): parallel passes along a 1 m-radius cylinder
    still meet σ/μ < 1 % at 330 mm and ≤ 2.8 % over 300-350 mm (the previous default: 7.25 % at
    300 mm). Film by the deposition model written literally from DESIGN.md
    (`deposition_rate_reference`) integrated along the pass by the trapezoid rule, summed over
    equally spaced passes in arc length (the cylinder is symmetric about its axis)."""
    app = Applicator.default()
    r_m, h = 1.0, app.standoff_m
    x = np.linspace(-0.6, 0.6, 241)                        # gun travel along the axis [m]
    s = np.linspace(-0.7, 0.7, 1401)                       # arc length across the axis [m]
    pts = np.stack([np.zeros_like(s), r_m * np.sin(s / r_m), r_m * np.cos(s / r_m)], axis=1)
    gun = np.stack([x, np.zeros_like(x), np.full_like(x, r_m + h)], axis=1)
    rate = deposition_rate_reference(app, gun, np.tile([0.0, 0.0, -1.0], (len(x), 1)),
                                     np.tile([1.0, 0.0, 0.0], (len(x), 1)), pts, pts / r_m)
    prof = np.trapezoid(rate, x, axis=0)

    def nsd(w: float) -> float:
        q = (np.arange(400) + 0.5) / 400 * w
        k = np.arange(-5, 6)
        film = np.interp(q[None, :] - k[:, None] * w, s, prof, left=0, right=0).sum(axis=0)
        return float(film.std() / film.mean())

    assert nsd(0.33) < 0.01
    assert max(nsd(w) for w in np.arange(0.30, 0.3501, 0.01)) <= 0.028
    assert nsd(0.36) > 0.035                               # a sweet spot, not a plateau
