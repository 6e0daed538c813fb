"""Sweep specification and statistics against independent truth (no simulation here).

- Clopper–Pearson bounds at 0 and n passes have closed forms: (α/2)^(1/n) and 1 − (α/2)^(1/n).
- A Latin-hypercube design puts exactly one sample in each of n equal-probability bins of every
  factor, so its sample quantiles lie within one bin of the analytic ones.
- Per-sample seeds depend on (seed, index) only: the first samples of a longer sweep have the
  same seeds and values under Monte Carlo.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from paintcell.sweeps.sweep_stats import (
    check_limits,
    limit_checks,
    quantiles,
    sensitivity,
    yield_interval,
)
from paintcell.validation.sweep_spec import Distribution, SweepError, SweepSpec, spec_from_scenario


def test_clopper_pearson_matches_closed_forms() -> None:
    a = 0.05
    for n in (1, 7, 50, 1000):
        lo, hi = yield_interval(n, n)
        assert hi == 1.0 and math.isclose(lo, (a / 2) ** (1 / n), rel_tol=1e-9)
        lo, hi = yield_interval(0, n)
        assert lo == 0.0 and math.isclose(hi, 1 - (a / 2) ** (1 / n), rel_tol=1e-9)
    # interior: the bounds are the Beta quantiles that define the interval
    lo, hi = yield_interval(37, 50)
    assert math.isclose(lo, stats.beta.ppf(a / 2, 37, 14), rel_tol=1e-7)
    assert math.isclose(hi, stats.beta.ppf(1 - a / 2, 38, 13), rel_tol=1e-7)


@pytest.mark.parametrize("text, q", [("normal(0.002, 0.005)", stats.norm(0.002, 0.005).ppf),
                                     ("uniform(-0.02, 0.04)", stats.uniform(-0.02, 0.06).ppf),
                                     ("triangular(0.5, 1.0, 2.0)",
                                      stats.triang(0.5 / 1.5, loc=0.5, scale=1.5).ppf)])
def test_lhs_quantiles_within_one_stratum_of_analytic(text: str, q: object) -> None:
    n = 200
    spec = SweepSpec.from_strings([f"standoff_error_m={text}"], n, "lhs", seed=3)
    x = np.sort(spec.design()[:, 0])
    u = np.arange(n) / n
    # one sample in each bin [k/n, (k+1)/n): the k-th order statistic lies in that bin's image
    assert np.all(x >= q(u) - 1e-12) and np.all(x <= q(u + 1 / n) + 1e-12)  # type: ignore
    got = quantiles(x)
    for p in (5, 50, 95):
        lo, hi = q(p / 100 - 1 / n), q(p / 100 + 1 / n)  # type: ignore[operator]
        assert lo <= got[f"p{p}"] <= hi


def test_design_and_seeds_depend_on_seed_and_index_only() -> None:
    a = SweepSpec.from_strings(["gain_scale=uniform(0.8, 1.2)", "part_offset_m=normal(0, 0.01)"],
                               10, "mc", seed=5)
    b = SweepSpec.from_strings(["gain_scale=uniform(0.8, 1.2)", "part_offset_m=normal(0, 0.01)"],
                               25, "mc", seed=5)
    np.testing.assert_array_equal(a.sample_seeds(), b.sample_seeds()[:10])
    np.testing.assert_array_equal(a.design(), b.design()[:10])
    np.testing.assert_array_equal(a.design(), a.design())
    assert len(set(b.sample_seeds().tolist())) == 25
    # magnitudes: a placement offset is a length in a random direction, |draw|
    assert np.all(b.design()[:, b.names.index("part_offset_m")] >= 0)
    c = SweepSpec.from_strings(["gain_scale=uniform(0.8, 1.2)"], 10, "mc", seed=6)
    assert not np.array_equal(c.design()[:, 0], a.design()[:, 0])


def test_spearman_sensitivity_sees_a_monotone_effect_and_not_noise() -> None:
    spec = SweepSpec.from_strings(["gain_scale=uniform(0.5, 1.5)", "flow_scale=normal(1, 0.1)"],
                                  40, "lhs", seed=1)
    x = spec.design()
    recs = [{"factors": dict(zip(spec.names, row, strict=True)),
             "metrics": {"executed_nsd_pct": 5.0 + math.exp(row[spec.names.index("gain_scale")]),
                         "executed_mean_um": 40.0}} for row in x]
    s = sensitivity(spec, recs)
    assert s["gain_scale"]["executed_nsd_pct"]["rho"] == pytest.approx(1.0)
    assert abs(s["flow_scale"]["executed_nsd_pct"]["rho"]) < 0.5
    assert s["gain_scale"]["executed_mean_um"]["rho"] is None  # a constant figure


def test_limits_hold_quantiles_and_yield() -> None:
    recs = [{"metrics": {"executed_nsd_pct": float(v)}, "passed": v < 9} for v in range(1, 11)]
    summary = {"yield_pct": 80.0, "yield_ci_pct": [44.4, 97.5]}
    checks = {c["name"]: c for c in limit_checks(summary, recs, {
        "max_p95_executed_nsd_pct": 9.0, "max_p50_executed_nsd_pct": 6.0,
        "min_yield_pct": 75.0, "min_yield_lower_pct": 50.0})}
    assert checks["max_p95_executed_nsd_pct"]["value"] == pytest.approx(np.percentile(
        np.arange(1, 11), 95)) and not checks["max_p95_executed_nsd_pct"]["passed"]
    assert checks["max_p50_executed_nsd_pct"]["passed"]
    assert checks["min_yield_pct"]["passed"] and not checks["min_yield_lower_pct"]["passed"]


@pytest.mark.parametrize("bad, match", [
    ({"factors": {"conveyor_speed_m_s": "normal(0, 1)"}}, "conveyor"),
    ({"factors": {"part_ofset_m": "normal(0, 1)"}}, "unknown factor"),
    ({"factors": {"part_offset_m": "normal(0)"}}, "2 finite numbers"),
    ({"factors": {"part_offset_m": "gauss(0, 1)"}}, "unknown distribution"),
    ({"factors": {"part_offset_m": "normal(0, -1)"}}, "sd > 0"),
    ({"factors": {"part_offset_m": "uniform(1, 0)"}}, "low < high"),
    ({"factors": {"part_offset_m": "wide"}}, "not a distribution"),
    ({"factors": {}}, "at least one factor"),
    ({"factors": {"gain_scale": "1.1"}, "samples": 0}, "samples"),
    ({"factors": {"gain_scale": "1.1"}, "method": "sobol"}, "method"),
    ({"factors": {"gain_scale": "1.1"}, "sample": 3}, "unknown sweep setting"),
])
def test_bad_specs_raise_one_line_errors(bad: dict[str, object], match: str) -> None:
    with pytest.raises(SweepError, match=match) as exc:
        spec_from_scenario(bad)
    assert "\n" not in str(exc.value)


def test_bad_limits_name_the_valid_forms() -> None:
    with pytest.raises(SweepError, match="max_pNN_<figure>"):
        check_limits({"p95_executed_nsd_pct": 3.0})
    with pytest.raises(SweepError, match="finite"):
        check_limits({"min_yield_pct": "high"})
    assert Distribution.parse("0.25").kind == "const"


def test_scenario_files_check_their_sweep_table_on_load(tmp_path: object) -> None:
    from pathlib import Path

    import tomli_w

    from paintcell.app.scenario_data import load_toml_scenario
    from paintcell.core.errors import ScenarioDataError
    from tests.sweep_cases import SCENARIO

    folder = Path(str(tmp_path))
    good = folder / "good.toml"
    good.write_text(tomli_w.dumps({**SCENARIO, "sweep": {
        "samples": 20, "factors": {"flow_drift": "normal(0, 0.02)"},
        "limits": {"max_p95_executed_nsd_pct": 9.0}}}))
    scn = load_toml_scenario(good)
    assert spec_from_scenario(scn.sweep).factors["flow_drift"].params == (0.0, 0.02)
    for sweep, words in (({"factors": {"flow_drift": "normal(0)"}}, "2 finite numbers"),
                         ({"limits": {"p95_executed_nsd_pct": 9.0}}, "max_pNN_<figure>"),
                         ({"samples": -3}, "samples = -3"), ({"sampels": 3}, "unknown sweep")):
        bad = folder / "bad.toml"
        bad.write_text(tomli_w.dumps({**SCENARIO, "sweep": sweep}))
        with pytest.raises(ScenarioDataError, match=words) as exc:
            load_toml_scenario(bad)
        assert "bad.toml: [sweep]" in str(exc.value) and "\n" not in str(exc.value)
