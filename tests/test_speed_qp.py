"""Speed QP (paper §3, eq. 2): short-overspray gain, re-measured constraints, fallbacks."""

from __future__ import annotations

import numpy as np
import pytest

from planning.applicator import Applicator
from planning.errors import PaintcellError
from planning.speed_qp import (
    SpeedQPError,
    SpeedSettings,
    SubOffsetBand,
    build_speed_objective,
    knot_interpolation,
    optimize_pass_speed,
    optimize_speed_from_rates,
    sample_pass_profile,
)
from tests.helpers import FD_GRADIENT_RTOL, QP_CONSTRAINT_RTOL

H = 0.25  # standoff of the straight test pass [m]


def _plane_pass(panel_m: float = 0.8, over_m: float = 0.1, ds_m: float = 0.005,
                offsets_m: np.ndarray | None = None, dm_m: float = 0.005):
    """Straight pass along x over a flat panel (z = 0) at standoff H, overspray at both ends.

    Returns centres (n, 3), spray axes, travel dirs, segment lengths (n,), and the band: one
    sub-offset curve per y offset, sampled on the panel only (x in ±panel/2).
    """
    if offsets_m is None:
        offsets_m = np.linspace(-0.12, 0.12, 7)
    length = panel_m + 2 * over_m
    n = int(round(length / ds_m))
    s = np.full(n, length / n)
    xc = -length / 2 + (np.arange(n) + 0.5) * length / n
    centres = np.stack([xc, np.zeros(n), np.full(n, H)], axis=1)
    axes = np.tile([0.0, 0.0, -1.0], (n, 1))
    travel = np.tile([1.0, 0.0, 0.0], (n, 1))
    m = int(round(panel_m / dm_m))
    xm = -panel_m / 2 + (np.arange(m) + 0.5) * panel_m / m
    band = SubOffsetBand(
        points=tuple(np.stack([xm, np.full(m, y), np.zeros(m)], axis=1) for y in offsets_m),
        normals=tuple(np.tile([0.0, 0.0, 1.0], (m, 1)) for _ in offsets_m),
        lengths=tuple(np.full(m, panel_m / m) for _ in offsets_m),
    )
    return centres, axes, travel, s, band


def _gaussian_rates(centres: np.ndarray, band: SubOffsetBand, a0: float = 2e-5,
                    sx: float = 0.06, sy: float = 0.08) -> list[np.ndarray]:
    """Local closed-form rate model, independent of planning.deposition: a bivariate Gaussian of
    the in-plane offset between gun and point (valid for a gun normal to a flat panel)."""
    out = []
    for p in band.points:
        dx = p[:, None, 0] - centres[None, :, 0]
        dy = p[:, None, 1] - centres[None, :, 1]
        out.append(a0 * np.exp(-(dx**2 / (2 * sx**2) + dy**2 / (2 * sy**2))))
    return out


def _remeasure(result, s: np.ndarray, settings: SpeedSettings, rates, lengths) -> None:
    """Check every constraint of eq. 2 on the returned times, written out from the paper."""
    t = result.segment_times_s
    tol = QP_CONSTRAINT_RTOL
    assert np.all(t >= s / settings.v_max_m_s * (1 - tol))
    assert np.all(t <= s / settings.v_min_m_s * (1 + tol))
    np.testing.assert_allclose(result.speeds_m_s, s / t, rtol=1e-12)
    bound = settings.a_max_m_s2 * s[1:] * s[:-1] ** 2 / settings.v_max_m_s**3
    lin = s[1:] * t[:-1] - s[:-1] * t[1:]
    assert np.all(np.abs(lin) <= bound * (1 + tol))
    t_beg = s / settings.v_nominal_m_s
    ell = lengths[0]
    np.testing.assert_allclose(ell @ (rates[0] @ t), ell @ (rates[0] @ t_beg), rtol=tol)


def test_short_overspray_optimized_beats_constant_and_slows_at_ends() -> None:
    """Paper Table 1 'plane, 100 mm overspray': constant speed under-paints the panel ends."""
    c, _, _, s, band = _plane_pass()
    rates = _gaussian_rates(c, band)
    settings = SpeedSettings(v_nominal_m_s=0.5, v_min_m_s=0.2, v_max_m_s=1.0, a_max_m_s2=5.0)
    res = optimize_speed_from_rates(rates, band.lengths, s, settings)
    assert res.optimized, res.status
    assert res.nsd_optimized_pct < 0.8 * res.nsd_constant_pct
    n = len(s)
    mid = res.speeds_m_s[n // 2 - n // 10: n // 2 + n // 10].mean()
    assert res.speeds_m_s[0] < settings.v_nominal_m_s < mid
    assert res.speeds_m_s[-1] < settings.v_nominal_m_s
    _remeasure(res, s, settings, rates, band.lengths)
    # the reported per-curve figures re-measured from the times, as length-weighted σ/μ
    for j, D in enumerate(rates):
        film = D @ res.segment_times_s
        w = band.lengths[j] / band.lengths[j].sum()
        mu = w @ film
        np.testing.assert_allclose(res.nsd_optimized_per_curve_pct[j],
                                   100 * np.sqrt(w @ (film - mu) ** 2) / mu, rtol=1e-10)


def test_real_deposition_model_short_overspray() -> None:
    """Same situation through optimize_pass_speed and the project's ESRB bell model."""
    c, a, d, s, band = _plane_pass(offsets_m=np.linspace(-0.15, 0.15, 7))
    settings = SpeedSettings()
    res = optimize_pass_speed(Applicator.default(), c, a, d, s, band, settings)
    assert res.optimized, res.status
    assert res.nsd_optimized_pct < 0.8 * res.nsd_constant_pct
    from planning.deposition import deposition_rate
    rate = deposition_rate(Applicator.default(), c, a, d, np.concatenate(band.points),
                           np.concatenate(band.normals))
    rates = [r.T for r in np.split(rate, np.cumsum([len(p) for p in band.points])[:-1], axis=1)]
    _remeasure(res, s, settings, rates, band.lengths)


def test_constraints_hold_on_varied_passes() -> None:
    """Non-uniform segments, tight acceleration, few and many knots: every output re-measures."""
    rng = np.random.default_rng(7)
    for n_knots, a_max in ((5, 2.0), (25, 0.5), (1000, 8.0)):
        c, _, _, s, band = _plane_pass(over_m=0.05, ds_m=0.006)
        s = s * rng.uniform(0.7, 1.3, len(s))          # uneven segments, same centres is fine
        rates = _gaussian_rates(c, band)
        settings = SpeedSettings(v_nominal_m_s=0.4, v_min_m_s=0.15, v_max_m_s=0.9,
                                 a_max_m_s2=a_max, n_knots=n_knots)
        res = optimize_speed_from_rates(rates, band.lengths, s, settings)
        assert res.nsd_optimized_pct <= res.nsd_constant_pct
        _remeasure(res, s, settings, rates, band.lengths)


def test_tight_speed_window_gives_constant_profile() -> None:
    c, _, _, s, band = _plane_pass()
    rates = _gaussian_rates(c, band)
    closed = SpeedSettings(v_nominal_m_s=0.5, v_min_m_s=0.5, v_max_m_s=0.5)
    res = optimize_speed_from_rates(rates, band.lengths, s, closed)
    assert res.status.startswith("constant")
    np.testing.assert_array_equal(res.segment_times_s, s / 0.5)
    assert res.nsd_optimized_pct == res.nsd_constant_pct
    narrow = SpeedSettings(v_nominal_m_s=0.5, v_min_m_s=0.5 * (1 - 1e-4),
                           v_max_m_s=0.5 * (1 + 1e-4))
    res = optimize_speed_from_rates(rates, band.lengths, s, narrow)
    np.testing.assert_allclose(res.speeds_m_s, 0.5, rtol=1.01e-4)
    assert res.nsd_optimized_pct <= res.nsd_constant_pct


def _direct_objective(rates, lengths, s, settings, z, L) -> float:
    """Eq. 2 squared, written out per curve from its definition (no shared code with the module)."""
    t_beg = s / settings.v_nominal_m_s
    t = t_beg * (L @ z)
    k = np.array([(ell @ (D @ t_beg)) / ell.sum() for D, ell in zip(rates, lengths, strict=True)])
    w = k / k.sum()
    total = 0.0
    for D, ell, kj, wj in zip(rates, lengths, k, w, strict=True):
        film = D @ t
        mean = (ell @ film) / ell.sum()
        total += wj / kj**2 * (ell @ (film - mean) ** 2) / ell.sum()
    return total


def test_objective_and_gradient_match_direct_formula_and_finite_differences() -> None:
    c, _, _, s, band = _plane_pass(offsets_m=np.linspace(-0.1, 0.1, 5))
    rates = _gaussian_rates(c, band)
    settings = SpeedSettings(n_knots=12)
    obj = build_speed_objective(rates, band.lengths, s, settings)
    L, _ = knot_interpolation(s, settings.n_knots)
    z = np.random.default_rng(3).uniform(0.7, 1.4, L.shape[1])
    direct = _direct_objective(rates, band.lengths, s, settings, z, L)
    np.testing.assert_allclose(obj.value(z), direct, rtol=1e-10)
    h = 1e-5
    fd = np.array([(_direct_objective(rates, band.lengths, s, settings, z + h * e, L)
                    - _direct_objective(rates, band.lengths, s, settings, z - h * e, L)) / (2 * h)
                   for e in np.eye(len(z))])
    np.testing.assert_allclose(obj.gradient(z), fd, rtol=FD_GRADIENT_RTOL,
                               atol=FD_GRADIENT_RTOL * np.abs(fd).max())
    # constant speed (z = 1) is on the equality, and T(z = 1) is T_beg
    assert obj.eq_row @ np.ones(L.shape[1]) == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(obj.segment_times(np.ones(L.shape[1])), s / 0.5, rtol=1e-12)


def test_knot_interpolation_is_linear_in_arc_length() -> None:
    s = np.random.default_rng(1).uniform(0.003, 0.008, 57)
    L, idx = knot_interpolation(s, 9)
    assert idx[0] == 0 and idx[-1] == len(s) - 1
    np.testing.assert_allclose(L.sum(axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(L[idx], np.eye(len(idx)), atol=1e-15)
    centres = np.cumsum(s) - 0.5 * s
    line = 2.0 - 3.0 * centres                          # a linear slowness is reproduced exactly
    np.testing.assert_allclose(L @ line[idx], line, rtol=1e-12)


@pytest.mark.parametrize("kwargs", [
    {"v_min_m_s": 0.8, "v_max_m_s": 0.4, "v_nominal_m_s": 0.5},
    {"v_min_m_s": -0.1},
    {"v_nominal_m_s": -0.5},
    {"v_nominal_m_s": 1.5},
    {"a_max_m_s2": 0.0},
    {"n_knots": 1},
    {"v_max_m_s": float("nan")},
])
def test_invalid_settings_raise(kwargs: dict) -> None:
    with pytest.raises(SpeedQPError, match="SpeedSettings"):
        SpeedSettings(**kwargs)
    assert issubclass(SpeedQPError, PaintcellError)


def test_invalid_inputs_raise() -> None:
    c, _, _, s, band = _plane_pass()
    rates = _gaussian_rates(c, band)
    with pytest.raises(SpeedQPError, match="seg_lengths"):
        optimize_speed_from_rates(rates, band.lengths, -s, SpeedSettings())
    with pytest.raises(SpeedQPError, match="rate matrix"):
        optimize_speed_from_rates([r[:, :-1] for r in rates], band.lengths, s, SpeedSettings())
    with pytest.raises(SpeedQPError, match="no paint"):
        optimize_speed_from_rates([0 * r for r in rates], band.lengths, s, SpeedSettings())
    with pytest.raises(SpeedQPError, match="lengths"):
        SubOffsetBand(points=band.points, normals=band.normals,
                      lengths=tuple(-x for x in band.lengths))


def test_solver_failure_falls_back_to_constant() -> None:
    c, _, _, s, band = _plane_pass()
    rates = _gaussian_rates(c, band)
    res = optimize_speed_from_rates(rates, band.lengths, s, SpeedSettings(max_iter=1))
    assert res.status.startswith("constant") and not res.optimized
    np.testing.assert_array_equal(res.speeds_m_s, np.full(len(s), 0.5))
    assert res.nsd_optimized_pct == res.nsd_constant_pct


def test_deterministic() -> None:
    c, _, _, s, band = _plane_pass()
    rates = _gaussian_rates(c, band)
    a = optimize_speed_from_rates(rates, band.lengths, s, SpeedSettings())
    b = optimize_speed_from_rates(rates, band.lengths, s, SpeedSettings())
    np.testing.assert_array_equal(a.segment_times_s, b.segment_times_s)
    assert a.status == b.status and a.nsd_optimized_pct == b.nsd_optimized_pct


def test_sample_pass_profile_matches_segments() -> None:
    c, _, _, s, band = _plane_pass()
    res = optimize_speed_from_rates(_gaussian_rates(c, band), band.lengths, s, SpeedSettings())
    edges = np.concatenate([[0.0], np.cumsum(s)])
    v, t = sample_pass_profile(res, edges)
    np.testing.assert_allclose(t, np.concatenate([[0.0], np.cumsum(res.segment_times_s)]),
                               rtol=1e-12, atol=1e-15)
    v_c, _ = sample_pass_profile(res, edges[:-1] + 0.5 * s)
    np.testing.assert_allclose(v_c, res.speeds_m_s, rtol=1e-12)
    assert np.all(v >= 0.25 * (1 - 1e-9)) and np.all(v <= 1.0 * (1 + 1e-9))
    with pytest.raises(SpeedQPError, match="arc positions"):
        sample_pass_profile(res, [edges[-1] + 0.1])


def test_repair_moves_admm_points_onto_the_constraints() -> None:
    """The ADMM clean-up lands any nearby point exactly on the equality and acceleration rows."""
    from planning.speed_qp import _repair
    c, _, _, s, band = _plane_pass()
    settings = SpeedSettings(n_knots=15)
    obj = build_speed_objective(_gaussian_rates(c, band), band.lengths, s, settings)
    dL = obj.interp[:-1] - obj.interp[1:]
    acc_b = settings.a_max_m_s2 * s[:-1] * settings.v_nominal_m_s / settings.v_max_m_s**3
    rng = np.random.default_rng(11)
    for _ in range(20):
        x = 1.0 + rng.normal(0.0, 0.3, dL.shape[1])        # far outside the acceleration rows
        z = _repair(x, obj.eq_row, dL, acc_b, 0.5, 2.0)
        assert obj.eq_row @ z == pytest.approx(1.0, rel=1e-12)
        assert np.all(np.abs(dL @ z) <= acc_b * (1 + 1e-12))
        shift = abs(1.0 - obj.eq_row @ np.clip(x, 0.5, 2.0))
        assert np.all(z >= 0.5 - shift - 1e-12) and np.all(z <= 2.0 + shift + 1e-12)
