"""Robot-aware re-plans with and without the kept pass geometry
(`paintcell.coverage.family_geometry`): byte-identical plans, and the time saved.

For each single-robot scenario: the --fast (or full) plan, its joint program, the program's
speed caps (`paintcell.motion.speed_caps.speed_caps`; where the program slows no pose,
0.9 × the speeds it reaches, so the caps still bind) and bell x axes (`tool_axes`); then the
capped re-plan twice — with the geometry kept from the first plan, and planned anew (kept geometry
dropped) — both saved with `CoveragePlan.save` and compared file by file (plan.json, plan.npz).
Prints one row per scenario: passes, capped samples, identical or not, CPU s of both re-plans,
and the width searches each ran. For a booth, each part as its booth plans it, under caps at
0.9 × its planned speeds (no program: a booth's is built for all its robots together).

    python benchmarks/replan_cache.py               # reach_hood_panel and roof
    python benchmarks/replan_cache.py scenarios/door.toml scenarios/cad_hood.toml
    python benchmarks/replan_cache.py --all        # every scenario in scenarios/ (booths too)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _count_searches() -> list[int]:
    """Count calls of the eq. 3 width search (patched where the planner looks it up)."""
    import paintcell.coverage.coverage_planner as cp

    n = [0]
    orig = cp.search_widths

    def counted(*a: object, **k: object) -> object:
        n[0] += 1
        return orig(*a, **k)

    cp.search_widths = counted  # type: ignore[assignment]
    return n


def check(path: Path, fast: bool, n: list[int]) -> dict[str, object]:
    from paintcell.app.pipeline import (
        load_applicator,
        load_robot_for,
        load_surface,
        make_plan,
        make_trajectory,
        planner_settings,
    )
    from paintcell.app.scenario_files import load_scenario
    from paintcell.coverage import family_geometry
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.motion.speed_caps import achieved_speeds, speed_caps, tool_axes

    scn = load_scenario(path)
    surface = load_surface(scn, fast)
    plan = make_plan(scn, surface, fast)
    traj = make_trajectory(scn, load_robot_for(scn), plan)
    caps, n_caps, _ = speed_caps(plan, traj)
    source = "program's slowdowns"
    if not caps:        # the program slows nothing: cap at 0.9 × what it reaches
        v = achieved_speeds(plan, traj)
        caps = {p.side: 0.9 * (v[i][::-1] if i % 2 else v[i]) for i, p in enumerate(plan.passes)}
        n_caps, source = sum(len(c) for c in caps.values()), "0.9 × reached"
    caps = {k: np.where(np.isfinite(c), c, 10.0) for k, c in caps.items()}
    tx = tool_axes(plan, traj, scn.part_placement.matrix)
    skin, st = surface.region_surface(("skin",)), planner_settings(scn, fast)
    out = {}
    for mode in ("kept", "anew"):
        if mode == "anew":
            family_geometry.forget()
        n[0] = 0
        t0 = time.process_time()
        got = plan_coverage(skin, load_applicator(scn), st, speed_caps_m_s=caps, tool_x=tx)
        out[mode] = (got, time.process_time() - t0, n[0])
    files = {mode: _files(out[mode][0]) for mode in out}
    moved = max(float(np.max(np.abs(a.speeds_m_s - b.speeds_m_s)))
                for a, b in zip(plan.passes, out["kept"][0].passes, strict=True))
    return dict(scenario=path.stem, passes=len(plan.passes), capped=n_caps, caps=source,
                identical=files["kept"] == files["anew"], speeds_moved_m_s=moved,
                kept_s=out["kept"][1], anew_s=out["anew"][1],
                searches_kept=out["kept"][2], searches_anew=out["anew"][2])


def check_booth(path: Path, fast: bool, n: list[int]) -> list[dict[str, object]]:
    """The booth's parts as `paintcell.booth.booth_plans.plan_parts` plans them, each
    re-planned under caps at 0.9 × its planned speeds (a booth's program is built for all its
    robots together: left out here), kept vs anew."""
    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth_plans import plan_parts
    from paintcell.coverage import family_geometry
    from paintcell.coverage.algorithm import plan_coverage

    booth = load_scenario(path)
    pp = plan_parts(booth, fast)
    caps = [{p.side: 0.9 * (p.speeds_m_s[::-1] if i % 2 else p.speeds_m_s)
             for i, p in enumerate(plan.passes)} for plan in pp.plans]
    got: dict[str, list[tuple[object, float, int]]] = {"kept": [], "anew": []}
    for mode in got:
        if mode == "anew":
            family_geometry.forget()
        for k in range(len(pp.plans)):
            n[0] = 0
            t0 = time.process_time()
            plan = plan_coverage(pp.skins[k], pp.applicator, pp.settings[k], speed_caps_m_s=caps[k])
            got[mode].append((plan, time.process_time() - t0, n[0]))
    rows = []
    for k, plan in enumerate(pp.plans):
        (a, ta, na), (b, tb, nb) = got["kept"][k], got["anew"][k]
        same = _files(a) == _files(b)
        moved = max(float(np.max(np.abs(x.speeds_m_s - y.speeds_m_s)))
                    for x, y in zip(plan.passes, a.passes, strict=True))
        rows.append(dict(scenario=f"{path.stem}#{k}", passes=len(plan.passes),
                         capped=sum(len(c) for c in caps[k].values()), caps="0.9 × planned",
                         identical=same, speeds_moved_m_s=moved, kept_s=ta, anew_s=tb,
                         searches_kept=na, searches_anew=nb))
    return rows


def _files(plan: object) -> list[bytes]:
    with tempfile.TemporaryDirectory() as d:
        plan.save(Path(d) / "plan.json")  # type: ignore[attr-defined]
        return [(Path(d) / f).read_bytes() for f in ("plan.json", "plan.npz")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenarios", nargs="*", type=Path,
                    help="scenario TOML files (default: reach_hood_panel and roof)")
    ap.add_argument("--all", action="store_true",
                    help="every scenario in scenarios/ (booths: each part, caps at 0.9 × "
                    "its planned speeds)")
    ap.add_argument("--full", action="store_true", help="full resolution (default: --fast)")
    a = ap.parse_args(argv)
    paths = list(a.scenarios)
    if a.all:
        paths += sorted((ROOT / "scenarios").glob("*.toml"))
    if not paths:               # `make bench`: a scanned part with slowdowns, a spin fed back
        paths = [ROOT / "scenarios" / "reach_hood_panel.toml", ROOT / "scenarios" / "roof.toml"]
    n = _count_searches()
    bad = 0
    print(f"{'scenario':24s} {'passes':>6s} {'capped':>7s} {'identical':>9s} {'Δv m/s':>7s} "
          f"{'kept s':>7s} {'anew s':>7s} {'searches kept/anew':>18s}  caps")
    from paintcell.app.scenario import Scenario
    from paintcell.app.scenario_files import load_scenario

    for p in paths:
        one = isinstance(load_scenario(p), Scenario)
        for r in ([check(p, not a.full, n)] if one else check_booth(p, not a.full, n)):
            bad += not r["identical"]
            print(f"{r['scenario']:24s} {r['passes']:6d} {r['capped']:7d} "
                  f"{str(r['identical']):>9s} {r['speeds_moved_m_s']:7.3f} {r['kept_s']:7.1f} "
                  f"{r['anew_s']:7.1f} {r['searches_kept']:>8d}/{r['searches_anew']:<9d}  "
                  f"{r['caps']}", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
