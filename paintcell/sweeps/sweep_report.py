"""The sweep report: `report.html` with histograms, a sensitivity chart and scatter plots.

Reads only the results folder (sweep.json, summary.json, samples/*.json), so it can be rebuilt
from a finished or partial sweep: `write_sweep_report(folder)`.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_path, atomic_write_text

#: figures plotted as histograms (the headline ones).
HIST_FIGURES = ("executed_nsd_pct", "executed_within_tolerance_pct", "executed_min_um",
                "loss_pp", "executed_cycle_time_s", "tracking_error_max_mm")


def _records(out: Path) -> list[dict[str, Any]]:
    recs = []
    for f in sorted((out / "samples").glob("*.json")):
        try:
            recs.append(json.loads(f.read_text()))
        except (OSError, ValueError):
            continue
    return recs


def _savefig(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:  # a fixed temp name would be written through a planted link
        fig.savefig(tmp, dpi=90, format="png")


def make_sweep_figures(out: Path, summary: dict[str, Any],
                       records: list[dict[str, Any]]) -> list[str]:
    """Write the PNGs; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names: list[str] = []
    figs = summary["figures"]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    for ax, key in zip(axes.ravel(), HIST_FIGURES, strict=True):
        v = np.array([np.nan if r["metrics"].get(key) is None else r["metrics"][key]
                      for r in records], float)
        v = v[np.isfinite(v)]
        if len(v):
            ax.hist(v, bins=min(40, max(5, len(v) // 5)), color="#7a9cc6")
        for q, ls in (("p5", ":"), ("p50", "-"), ("p95", ":")):
            if figs[key].get(q) is not None:
                ax.axvline(figs[key][q], color="k", ls=ls, lw=1, label=q.upper())
        if figs[key].get("nominal") is not None:
            ax.axvline(figs[key]["nominal"], color="#d62728", lw=1.5, label="nominal")
        ax.set_xlabel(f"{key} [{figs[key]['unit']}]")
        ax.set_ylabel("samples")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"{summary['samples_done']} samples; yield {summary['yield_pct'] or 0:.1f} % "
                 f"(95 % CI {summary['yield_ci_pct'][0]:.1f}–{summary['yield_ci_pct'][1]:.1f} %)")
    fig.tight_layout()
    _savefig(fig, out / "sweep_histograms.png")
    plt.close(fig)
    names.append("sweep_histograms.png")

    sens = summary["sensitivity"]
    factors = list(sens)
    if factors:
        rho = [sens[f]["executed_nsd_pct"]["rho"] or 0.0 for f in factors]
        order = np.argsort(np.abs(rho))
        fig, ax = plt.subplots(figsize=(7, 0.5 * len(factors) + 1.5))
        ax.barh([factors[i] for i in order], [rho[i] for i in order], color="#c67a7a")
        ax.axvline(0, color="k", lw=0.8)
        ax.set_xlim(-1, 1)
        ax.set_xlabel("Spearman ρ with executed σ/μ")
        fig.tight_layout()
        _savefig(fig, out / "sweep_sensitivity.png")
        plt.close(fig)
        names.append("sweep_sensitivity.png")

        fig, axes = plt.subplots(1, len(factors), figsize=(4 * len(factors), 3.4), squeeze=False)
        y = np.array([np.nan if r["metrics"].get("executed_nsd_pct") is None
                      else r["metrics"]["executed_nsd_pct"] for r in records], float)
        ok = np.array([bool(r.get("passed")) for r in records])
        unit = summary["spec"]["units"]
        for ax, f in zip(axes[0], factors, strict=True):
            x = np.array([r["factors"].get(f, np.nan) for r in records], float)
            ax.scatter(x[ok], y[ok], s=8, c="#2ca02c", label="pass")
            ax.scatter(x[~ok], y[~ok], s=8, c="#d62728", label="fail")
            ax.set_xlabel(f"{f} [{unit.get(f, '')}]")
            ax.set_ylabel("executed σ/μ [%]")
        axes[0, 0].legend(fontsize=8)
        fig.tight_layout()
        _savefig(fig, out / "sweep_scatter.png")
        plt.close(fig)
        names.append("sweep_scatter.png")
    return names


def write_sweep_report(out: str | Path) -> Path:
    """Build `report.html` (and its PNGs) of the sweep in `out`; returns its path."""
    out = Path(out)
    summary = json.loads((out / "summary.json").read_text())
    header = json.loads((out / "sweep.json").read_text())
    records = _records(out)
    pngs = make_sweep_figures(out, summary, records) if records else []
    e = html.escape
    rows = "".join(
        f"<tr><td>{e(k)}</td><td>{e(v['unit'])}</td>"
        + "".join(f"<td>{_fmt(v.get(q))}</td>" for q in ("nominal", "p5", "p50", "p95", "min",
                                                         "max"))
        + "</tr>" for k, v in summary["figures"].items())
    sens = summary["sensitivity"]
    srows = "".join(
        f"<tr><td>{e(f)} [{e(summary['spec']['units'].get(f, ''))}]</td><td>"
        f"{e(summary['spec']['factors'].get(f, ''))}</td>"
        + "".join(f"<td>{_fmt(sens[f][k]['rho'])}</td>" for k in summary["figures"]) + "</tr>"
        for f in sens)
    lim = "".join(f"<tr><td>{e(c['name'])}</td><td>{_fmt(c['value'])}</td><td>{c['kind']} "
                  f"{_fmt(c['limit'])}</td><td>{'PASS' if c['passed'] else 'FAIL'}</td></tr>"
                  for c in summary["limit_checks"])
    fails = ", ".join(f"{e(k)}: {v}" for k, v in summary["failed_checks"].items()) or "none"
    imgs = "".join(f'<p><img src="{e(p)}" alt="{e(p)}"></p>' for p in pngs)
    y = summary["yield_pct"]
    doc = f"""<!doctype html><html><head><meta charset="utf-8">
<title>sweep {e(header['scenario']['name'])}</title>
<style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:2px 8px;text-align:right}}
table{{border-collapse:collapse}}tr:nth-child(even){{background:#f3f3f3}}</style></head><body>
<h1>Robustness sweep: {e(header['scenario']['name'])}</h1>
<p>{summary['samples_done']} of {summary['samples_planned']} samples ({e(header['spec']['method'])},
seed {header['spec']['seed']}, {'fast' if header['fast'] else 'full'} resolution,
{e(header['mode'])} execution); {summary['errors']} could not be simulated.</p>
<h2>Yield</h2><p><b>{_fmt(y)} %</b> of samples pass every threshold
(95 % Clopper–Pearson interval {_fmt(summary['yield_ci_pct'][0])}–{_fmt(summary['yield_ci_pct'][1])}
%). Failed checks: {fails}.</p>
<h2>Figures</h2><table><tr><th>figure</th><th>unit</th><th>nominal</th><th>P5</th><th>P50</th>
<th>P95</th><th>min</th><th>max</th></tr>{rows}</table>
<h2>Sensitivity (Spearman ρ)</h2><table><tr><th>factor</th><th>distribution</th>
{''.join(f'<th>{e(k)}</th>' for k in summary["figures"])}</tr>{srows}</table>
<h2>Limits</h2><table><tr><th>limit</th><th>value</th><th>required</th><th></th></tr>{lim}</table>
{imgs}</body></html>"""
    path = out / "report.html"
    atomic_write_text(path, doc)
    return path


def _fmt(v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return str(v)
    v = float(v)
    return f"{v:.4g}"
