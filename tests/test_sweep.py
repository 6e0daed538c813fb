"""Sweeps end to end on the tiny plate (in this process; the Dask cluster has its own tests).

Independent truth: the film is linear in the paint flow, so under `flow_scale` alone every
sample's executed mean film is exactly flow_scale × the nominal one and its σ/μ is the nominal
one; the sampled quantiles of the mean film are then the nominal mean × the analytic normal
quantiles (within one Latin-hypercube stratum). A trigger delay of whole steps shifts the brush
signal by exactly that many steps. A sweep stopped after some samples resumes without rerunning
them (their files are untouched) and ends with the records of an uninterrupted sweep.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

from paintcell.app.scenario_files import load_scenario
from paintcell.cli.main import main
from paintcell.execution.execute import Disturbances
from paintcell.sweeps.sweep import run_sweep, sample_path
from paintcell.sweeps.sweep_worker import RUN_KEYS
from paintcell.validation.sweep_spec import SweepError, spec_from_scenario
from tests.sweep_cases import plate_scenario

pytestmark = pytest.mark.slow


def test_flow_scale_gives_analytic_film_quantiles(tmp_path: Path) -> None:
    n, sd = 8, 0.05
    scn = load_scenario(plate_scenario(tmp_path, {"factors": {"flow_scale": f"normal(1, {sd})"},
                                                  "samples": n, "seed": 2}))
    res = run_sweep(scn, spec_from_scenario(scn.sweep), tmp_path / "out", fast=True,
                    mode="kinematic", workers=0, progress=False, report=True)
    nom = res.nominal["metrics"]
    for r in res.samples:
        k = r["factors"]["flow_scale"]
        assert r["metrics"]["executed_mean_um"] == pytest.approx(k * nom["executed_mean_um"],
                                                                 rel=1e-9)
        assert r["metrics"]["executed_nsd_pct"] == pytest.approx(nom["executed_nsd_pct"],
                                                                 rel=1e-9)
    fig = res.summary["figures"]["executed_mean_um"]
    for p in (5, 50, 95):
        # type-7 quantile: between order statistics ⌊h⌋ and ⌈h⌉ (h = (n − 1)p), and the k-th
        # order statistic of a Latin hypercube lies in the image of the bin [k/n, (k + 1)/n)
        h = (n - 1) * p / 100
        lo = nom["executed_mean_um"] * stats.norm(1, sd).ppf(math.floor(h) / n)
        hi = nom["executed_mean_um"] * stats.norm(1, sd).ppf((math.ceil(h) + 1) / n)
        assert lo <= fig[f"p{p}"] <= hi
    assert res.summary["yield_pct"] == 100.0
    assert res.summary["sensitivity"]["flow_scale"]["executed_mean_um"]["rho"] == \
        pytest.approx(1.0)
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Clopper" in html and "sweep_histograms.png" in html
    assert (tmp_path / "out" / "sweep_histograms.png").stat().st_size > 1000


def test_trigger_delay_shifts_the_brush_by_whole_steps() -> None:
    on = np.array([0, 0, 1, 1, 1, 0, 0, 1, 0], bool)
    np.testing.assert_array_equal(Disturbances(trigger_delay_s=0.002).paint_on(on, 0.001),
                                  [0, 0, 0, 0, 1, 1, 1, 0, 0])
    np.testing.assert_array_equal(Disturbances(trigger_delay_s=-0.001).paint_on(on, 0.001),
                                  [0, 1, 1, 1, 0, 0, 1, 0, 0])
    assert not Disturbances(trigger_delay_s=1.0).paint_on(on, 0.001).any()


def test_a_stopped_sweep_resumes_without_redoing_samples(tmp_path: Path) -> None:
    sweep = {"factors": {"tcp_offset_m": "normal(0, 0.004)", "standoff_error_m":
                         "uniform(-0.02, 0.02)"}, "samples": 5, "seed": 11}
    scn = load_scenario(plate_scenario(tmp_path, sweep))
    spec = spec_from_scenario(scn.sweep)
    out = tmp_path / "out"

    class Stop(Exception):
        pass

    def stop_after_two(rec: dict[str, Any]) -> None:
        if len(list((out / "samples").glob("*.json"))) >= 2:
            raise Stop

    with pytest.raises(Stop):
        run_sweep(scn, spec, out, fast=True, mode="kinematic", workers=0, progress=False,
                  report=False, on_sample=stop_after_two)
    first = {p.name: p.stat().st_mtime_ns for p in (out / "samples").glob("*.json")}
    assert len(first) == 2
    res = run_sweep(scn, spec, out, fast=True, mode="kinematic", workers=0, progress=False,
                    report=False)
    assert res.ran == 3
    for name, mtime in first.items():
        assert (out / "samples" / name).stat().st_mtime_ns == mtime
    whole = run_sweep(scn, spec, tmp_path / "whole", fast=True, mode="kinematic", workers=0,
                      progress=False, report=False)
    strip = [{k: v for k, v in r.items() if k not in RUN_KEYS} for r in res.samples]
    assert strip == [{k: v for k, v in r.items() if k not in RUN_KEYS} for r in whole.samples]
    assert json.loads(sample_path(out, 4).read_text())["index"] == 4
    again = run_sweep(scn, spec, out, fast=True, mode="kinematic", workers=0, progress=False,
                      report=False)
    assert again.ran == 0 and again.samples == res.samples and again.prepare_s < 1.0
    # a different sweep in the same folder is refused, not mixed in
    other = spec_from_scenario({**sweep, "seed": 12})
    with pytest.raises(SweepError, match="different sweep"):
        run_sweep(scn, other, out, fast=True, mode="kinematic", workers=0, progress=False)


def test_check_holds_a_scenario_to_its_sweep_quantiles(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # one sweep (in this process: Dask has its own tests), two limits: the loose one passes,
    # the tight one fails
    path = plate_scenario(tmp_path, {"factors": {"tcp_offset_m": "normal(0, 0.004)"},
                                     "samples": 2, "seed": 1, "workers": 0,
                                     "limits": {"max_p95_executed_nsd_pct": 30.0,
                                                "min_p5_executed_within_tolerance_pct": 100.1}})
    assert main(["check", str(path), "--fast"]) == 1
    out = capsys.readouterr().out
    assert "sweep max_p95_executed_nsd_pct" in out and "sweep min_p5_executed_within" in out
    assert "1 failed" in out
    loose = [line for line in out.splitlines() if "plate" in line][0]
    assert "max_p95_executed_nsd_pct" in loose and "≥ 100.10 ✗" in loose
