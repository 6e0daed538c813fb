"""Statistics of a sweep that a process engineer reads: quantiles, yield, sensitivity, limits.

- Quantiles P5 / P50 / P95 of every per-sample figure (numpy's default linear interpolation
  between order statistics, Hyndman–Fan type 7), over the samples that ran.
- Yield: the share of samples that pass every threshold of the scenario (a sample whose
  disturbance could not be simulated counts as failed), with its 95 % Clopper–Pearson interval
  (exact binomial, `scipy.stats.binomtest(...).proportion_ci(method="exact")`): it never claims
  more confidence than the sample count gives, also at 0 or n passes where Wald intervals collapse.
- Sensitivity: Spearman rank correlation ρ of each factor with each figure
  (`scipy.stats.spearmanr`). Chosen over SALib's variance-based (Sobol) indices because it works
  on the sweep's own Monte-Carlo or Latin-hypercube design — Sobol needs a Saltelli design of
  n·(2d + 2) runs built for it — and it says the direction of the effect (a tighter placement
  helps or hurts), which is what a tolerance decision needs. It measures monotone effects: a
  factor that hurts in both directions (a symmetric standoff error) shows a weak ρ; the report's
  scatter plots show such shapes.
- Limits: `Scenario.sweep["limits"]` holds the sweep to quantiles and yield, e.g.
  ``{"max_p95_executed_nsd_pct": 12.0, "min_p5_executed_within_tolerance_pct": 80.0,
  "min_yield_pct": 95.0}``: keys `max_pNN_<figure>`, `min_pNN_<figure>`, `min_yield_pct` and
  `min_yield_lower_pct` (the interval's lower bound).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from paintcell.validation.sweep_names import record_metrics
from paintcell.validation.sweep_spec import LIMIT_RE, SweepSpec, check_limits

QUANTILES = (5, 50, 95)
CONFIDENCE = 0.95


def yield_interval(passed: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Clopper–Pearson interval of a pass share (passed of n) as fractions [0, 1]."""
    if n == 0:
        return 0.0, 1.0
    ci = stats.binomtest(int(passed), int(n)).proportion_ci(confidence_level=confidence,
                                                           method="exact")
    return float(ci.low), float(ci.high)


def quantiles(values: np.ndarray, qs: tuple[int, ...] = QUANTILES) -> dict[str, float | None]:
    """{"p5": …, "p50": …, "p95": …} of the finite values (None when there are none)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return {f"p{q}": (float(np.percentile(v, q)) if len(v) else None) for q in qs}


def summarize(spec: SweepSpec, nominal: dict[str, Any] | None, records: list[dict[str, Any]],
              limits: dict[str, Any] | None = None) -> dict[str, Any]:
    """summary.json: counts, yield with interval, quantiles, sensitivity, limit checks."""
    n = len(records)
    n_pass = sum(bool(r.get("passed")) for r in records)
    n_err = sum("error" in r for r in records)
    lo, hi = yield_interval(n_pass, n)
    fig: dict[str, Any] = {}
    for key, unit in record_metrics(records).items():
        v = np.array([_f(r["metrics"].get(key)) for r in records], float)
        ok = v[np.isfinite(v)]
        fig[key] = {"unit": unit, **quantiles(v),
                    "mean": float(ok.mean()) if len(ok) else None,
                    "min": float(ok.min()) if len(ok) else None,
                    "max": float(ok.max()) if len(ok) else None,
                    "nominal": None if nominal is None else nominal["metrics"].get(key)}
    fails: dict[str, int] = {}
    for r in records:
        for c in r.get("failed_checks", []):
            fails[c] = fails.get(c, 0) + 1
    summary: dict[str, Any] = {
        "samples_done": n, "samples_planned": spec.samples, "errors": n_err,
        "passed": n_pass, "yield_pct": 100.0 * n_pass / n if n else None,
        "yield_ci_pct": [100.0 * lo, 100.0 * hi], "yield_ci_method": "Clopper-Pearson, 95 %",
        "figures": fig, "failed_checks": fails,
        "sensitivity": sensitivity(spec, records),
        "sensitivity_method": "Spearman rank correlation (scipy.stats.spearmanr)",
        "spec": spec.to_dict(),
        "nominal": None if nominal is None else {"passed": nominal.get("passed"),
                                                 "metrics": nominal.get("metrics")},
        "mean_sample_s": _mean([r.get("timing_s", {}).get("total") for r in records]),
        "mean_execute_s": _mean([r.get("timing_s", {}).get("execute") for r in records]),
        "mean_validate_s": _mean([r.get("timing_s", {}).get("validate") for r in records]),
    }
    summary["limit_checks"] = limit_checks(summary, records, limits)
    summary["limits_passed"] = all(c["passed"] for c in summary["limit_checks"])
    return summary


def sensitivity(spec: SweepSpec, records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """{factor: {figure: {"rho": ρ, "p": p-value}}} over samples with finite values; ρ is None
    where a column is constant (a figure: to 1e-9 relative) or fewer than 3 samples are finite."""
    out: dict[str, dict[str, Any]] = {}
    for name in spec.names:
        x = np.array([_f(r["factors"].get(name)) for r in records], float)
        row: dict[str, Any] = {}
        for key in record_metrics(records):
            y = np.array([_f(r["metrics"].get(key)) for r in records], float)
            ok = np.isfinite(x) & np.isfinite(y)
            # a figure that varies only by round-off (σ/μ under a pure flow scaling) is constant
            if ok.sum() < 3 or np.ptp(x[ok]) == 0 \
                    or np.ptp(y[ok]) <= 1e-9 * max(float(np.abs(y[ok]).max()), 1e-300):
                row[key] = {"rho": None, "p": None}
                continue
            res = stats.spearmanr(x[ok], y[ok])
            row[key] = {"rho": _f(res.statistic), "p": _f(res.pvalue)}
        out[name] = row
    return out


def limit_checks(summary: dict[str, Any], records: list[dict[str, Any]],
                 limits: dict[str, Any] | None) -> list[dict[str, Any]]:
    """One check a limit: name, value, limit, kind (max/min), passed (a quantile of no finite
    value fails)."""
    out = []
    for key, limit in check_limits(limits).items():
        if key == "min_yield_pct":
            value, kind = summary["yield_pct"], "min"
        elif key == "min_yield_lower_pct":
            value, kind = summary["yield_ci_pct"][0], "min"
        else:
            m = LIMIT_RE.match(key)
            assert m is not None
            kind, q, fig = m.group(1), int(m.group(2)), m.group(3)
            vals = np.array([_f(r["metrics"].get(fig)) for r in records], float)
            value = quantiles(vals, (q,))[f"p{q}"]
        ok = value is not None and (value <= limit if kind == "max" else value >= limit)
        out.append({"name": key, "value": value, "limit": limit, "kind": kind,
                    "passed": bool(ok)})
    return out


def _f(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _mean(v: list[Any]) -> float | None:
    a = np.array([_f(x) for x in v], float)
    a = a[np.isfinite(a)]
    return float(a.mean()) if len(a) else None
