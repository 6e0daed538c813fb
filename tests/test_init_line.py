"""`paintcell init BODY --line --takt T`: a paint line laid out from a takt. The written file is
re-measured (its conveyor against the pitch of its own panel files; every robot's program, from a
fresh plan of the written file and its allocation, against the takt); the allocation is checked
against brute force; the count against tighter takts; a takt no line makes is refused in one line
with nothing written."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from paintcell.booth.booth import Job
from paintcell.booth.line_allocation import LinePanel, allocate_line, partition
from paintcell.booth.line_takt import LineTakt, return_home_s
from paintcell.motion.moves import APPROACH_RETRACT_S, TURN_S

# -- the takt arithmetic ---------------------------------------------------------------------

def test_return_home_is_the_rest_to_rest_move_at_the_rail_limits() -> None:
    """Against a simulated bang-coast-bang move (10 µs steps) at 1.5 m/s and 4 m/s²."""
    for d in (0.1, 0.5625, 2.0, 6.0):
        x, v, t, dt, brake = 0.0, 0.0, 0.0, 1e-5, False
        while t == 0.0 or v > 0.0:                            # until it is at rest
            brake = brake or v * v / (2 * 4.0) >= d - x      # once braking, to rest
            a = -4.0 if brake else (4.0 if v < 1.5 else 0.0)
            v_next = max(min(v + a * dt, 1.5), 0.0)
            x += 0.5 * (v + v_next) * dt
            v = v_next
            t += dt
        assert x == pytest.approx(d, abs=1e-4)
        assert return_home_s(d) == pytest.approx(t, abs=1e-3)
    takt = LineTakt(75.0, 4.5)
    assert takt.pitch_m == 5.5 and takt.conveyor_speed_m_s * 75.0 == pytest.approx(5.5)


def test_max_cycle_is_the_longest_whose_return_fits_the_takt() -> None:
    """`LineTakt.max_cycle_s` against bisection on the simulated return (the bang-coast-bang
    move of the test above, in closed form there): C + return(v · C) equals the takt at C, and
    exceeds it a millisecond later; both branches (a triangular return at a slow line, a
    trapezoidal one at a fast line) are met."""
    regimes = set()
    for takt_s, length, gap in ((75.0, 4.39, 1.0), (90.0, 4.39, 1.0), (30.0, 0.4, 1.0),
                                (10.0, 0.3, 0.0), (200.0, 9.0, 1.0)):
        t = LineTakt(takt_s, length, gap)
        c = t.max_cycle_s()
        lo, hi = 0.0, takt_s
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if mid + return_home_s(t.conveyor_speed_m_s * mid) <= takt_s \
                else (lo, mid)
        assert c == pytest.approx(lo, abs=1e-9)
        assert t.robot_cycle_s(c) == pytest.approx(takt_s, abs=1e-9)
        assert t.robot_cycle_s(c + 1e-3) > takt_s
        regimes.add(t.conveyor_speed_m_s * c * 4.0 >= 1.5 ** 2)    # reaches 1.5 m/s or not
    assert regimes == {True, False}


# -- the allocation ---------------------------------------------------------------------------

def _panel(name: str, side: tuple[float, float, float], x: float, n: int, s: float,
           y: float = 0.0) -> LinePanel:
    return LinePanel(name, side, (x, y, 1.0), np.full(n, s),
                     np.linspace(0.8, -0.8, n) if side[2] > 0.5 else np.full(n, y))


def _coverage(panels: list[LinePanel], shares: Any) -> None:
    """Every pass of every panel in exactly one job; a panel in at most two pieces, each piece
    on its own robot."""
    for p, panel in enumerate(panels):
        owned = np.zeros(len(panel.durations_s), int)
        robots = []
        for r, s in enumerate(shares):
            for j in s.jobs:
                if j.part == p:
                    owned[j.first:j.end] += 1
                    robots.append(r)
        assert (owned == 1).all(), (panel.name, owned)
        assert len(robots) <= 2 and len(set(robots)) == len(robots)


def _est(durations: np.ndarray) -> float:
    """The booth's estimate, written out: paint + turns + approach and retract."""
    return float(durations.sum()) + TURN_S * (len(durations) - 1) + APPROACH_RETRACT_S


def test_whole_jobs_partition_is_the_brute_force_best() -> None:
    """Contiguous runs of whole jobs: the bisection's longest program is the least over every
    way of cutting the run (brute force over the cut positions)."""
    rng = np.random.default_rng(3)
    for _ in range(12):
        n_jobs, k = int(rng.integers(3, 7)), int(rng.integers(2, 4))
        # one pass per job: a job cannot be cut, so only whole jobs are placed
        panels = [_panel(f"p{i}", (0.0, 1.0, 0.0), -float(i), 1, float(rng.uniform(2, 30)))
                  for i in range(n_jobs)]
        jobs = [Job(i, 0, 1) for i in range(n_jobs)]
        got = max(sum(_est(panels[j.part].durations_s) for j in g)
                  for g in partition(panels, jobs, k, float))
        best = min(max(sum(_est(panels[i].durations_s) for i in range(a, b))
                       for a, b in itertools.pairwise((0, *cuts, n_jobs)))
                   for m in range(k) for cuts in itertools.combinations(range(1, n_jobs), m))
        assert got == pytest.approx(best, rel=1e-9)


def test_every_pass_is_allocated_once_and_zones_are_kept() -> None:
    panels = [_panel("fender_l", (0.0, 1.0, 0.0), 1.2, 5, 3.2, 0.9),
              _panel("door_l", (0.0, 1.0, 0.0), 0.0, 6, 3.0, 0.9),
              _panel("quarter_l", (0.0, 1.0, 0.0), -1.3, 5, 3.1, 0.9),
              _panel("fender_r", (0.0, -1.0, 0.0), 1.2, 5, 3.2, -0.9),
              _panel("door_r", (0.0, -1.0, 0.0), 0.0, 6, 3.0, -0.9),
              _panel("hood", (0.0, 0.0, 1.0), 1.5, 6, 3.9),
              _panel("roof", (0.0, 0.0, 1.0), -0.2, 6, 4.1),
              _panel("bumper_f", (1.0, 0.0, 0.0), 2.2, 4, 3.0)]
    for n in range(4, 11):
        shares = allocate_line(panels, n)
        assert len(shares) <= n
        _coverage(panels, shares)
        for s in shares:
            for j in s.jobs:
                side = panels[j.part].side
                if s.zone == "left":
                    assert side[1] > 0 or abs(side[0]) > 0.5
                elif s.zone == "right":
                    assert side[1] < 0 or abs(side[0]) > 0.5
                else:
                    assert side[2] > 0.5
            assert s.program_s == pytest.approx(sum(_est(panels[j.part].durations_s[
                j.first:j.end]) for j in s.jobs))
    # more robots never lengthen the longest program
    worst = [max(s.program_s for s in allocate_line(panels, n)) for n in range(4, 11)]
    assert all(b <= a + 1e-9 for a, b in itertools.pairwise(worst))


# -- the line, laid out, verified and written ---------------------------------------------

@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """`paintcell init BODY --line --takt 30` on two left panels of a generated body (its front
    fender and rear door: a manifest of the generator's panel folder, read by `load_body`),
    which one robot cannot paint in the takt: two floor robots on the left rail line. Kept:
    the plans it made and the programs its booth build made (so the other tests do not plan or
    build them again)."""
    import json

    import paintcell.booth.booth_plans as booth_plans
    import paintcell.booth.booth_programs as booth_programs
    from paintcell.cli.main import main

    tmp = tmp_path_factory.mktemp("line")
    assert main(["generate", "body", "--out", str(tmp / "car.stl")]) == 0
    manifest = json.loads((tmp / "car_panels" / "body.json").read_text())
    manifest["panels"] = [p for p in manifest["panels"]
                          if p["name"] in ("front_fender_left", "rear_door_left")]
    assert len(manifest["panels"]) == 2
    body = tmp / "car_panels" / "two_left.json"
    body.write_text(json.dumps(manifest))
    made: dict[str, Any] = {}
    real, real_programs = booth_plans.plan_parts, booth_programs.booth_programs

    def keep(booth: Any, fast: bool) -> Any:
        made["pp"] = real(booth, fast)
        made["booth"] = booth
        return made["pp"]

    builds: list[tuple[Any, Any]] = []

    def keep_programs(booth: Any, fast: bool, pp: Any = None, tasks: Any = None) -> Any:
        builds.append((booth, real_programs(booth, fast, pp, tasks)))
        return builds[-1][1]

    booth_plans.plan_parts = keep
    booth_programs.booth_programs = keep_programs
    try:
        out = tmp / "line.toml"
        assert main(["init", str(body), "--line", "--takt", "30", "--out", str(out)]) == 0
    finally:
        booth_plans.plan_parts = real
        booth_programs.booth_programs = real_programs
    # the build of the written robots (init builds again when it moves a robot's home)
    from paintcell.booth.booth_data import load_toml_booth

    homes = [r.home for r in load_toml_booth(out).robots]
    made["built"], made["progs"] = next((b, progs) for b, progs in builds[::-1]
                                        if [r.home for r in b.robots] == homes)
    return {"out": out, "body": body, **made}


def test_written_line_meets_the_takt_remeasured(written: dict[str, Any]) -> None:
    """Conveyor × takt = pitch of the written panel files (read back by trimesh); every robot's
    program, estimated from a fresh plan of the written file and its [allocation], plus the
    carriage's return over the distance the line carried it, is within the takt. The line
    blends each seam at its own share (`seam_shares = "per seam"`) and re-plans the passes a
    robot ran slower than asked (`robot_aware_speeds`), as its verification did."""
    from paintcell.booth.booth_data import load_toml_booth
    from paintcell.booth.booth_plans import plan_parts

    out: Path = written["out"]
    booth = load_toml_booth(out)
    assert booth.seam_shares == "per seam"
    assert booth.robot_aware_speeds and written["built"].robot_aware_speeds
    assert "\nrobot_aware_speeds = true\n" in out.read_text()
    xs = np.concatenate([trimesh.load(bp.mesh.file, force="mesh").vertices[:, 0]
                         for bp in booth.parts])
    pitch = float(xs.max() - xs.min()) + 1.0
    v = booth.conveyor.speed_m_s
    assert v * 30.0 == pytest.approx(pitch, rel=1e-6)   # STL stores float32 coordinates
    assert booth.allocation is not None and len(booth.robots) == len(booth.allocation)
    plans = plan_parts(booth, fast=True).plans
    passes = [np.zeros(len(pl.passes), int) for pl in plans]
    for triples in booth.allocation.values():
        program = 0.0
        for p, a, b in triples:
            passes[p][a:b] += 1
            program += _est(np.array([ps.duration_s for ps in plans[p].passes[a:b]]))
        d = v * program                          # the carriage runs back at 1.5 m/s, 4 m/s²
        back = d / 1.5 + 1.5 / 4.0 if d >= 1.5 ** 2 / 4.0 else 2 * math.sqrt(d / 4.0)
        assert program + back <= 30.0
    assert all((c == 1).all() for c in passes)   # every pass of the written file, once


def test_the_built_line_meets_the_takt_and_keeps_its_carriages_apart(
        written: dict[str, Any]) -> None:
    """Re-measured on the programs the booth built for the written line (tracking the conveyor,
    staggered, on one clock): its cycle plus every carriage's return over the distance the line
    carried it (the bang-coast-bang move, written out) fits the takt, and is within the written
    file's max_cycle_time_s; the two floor robots' carriages, in world x from their rail frames,
    keep their order and at least `CARRIAGE_GAP_M` apart at every sample; and each planned
    carriage stays inside its written stretch."""
    from paintcell.app.init_line_robots import CARRIAGE_GAP_M
    from paintcell.booth.booth_data import load_toml_booth

    progs, built = written["progs"], written["built"]
    booth = load_toml_booth(written["out"])
    assert [r.carriage_m for r in booth.robots] == [r.carriage_m for r in built.robots]
    assert [r.name for r in booth.robots] == ["left_1", "left_2"]
    dt = progs.trajs[0].dt_s
    cycle = (max(len(tr.t_s) for tr in progs.trajs) - 1) * dt
    d = booth.conveyor.speed_m_s * cycle
    back = d / 1.5 + 1.5 / 4.0 if d >= 1.5 ** 2 / 4.0 else 2 * math.sqrt(d / 4.0)
    assert cycle + back <= 30.0
    assert cycle <= booth.thresholds.max_cycle_time_s
    x = []
    for r, tr, st in zip(booth.robots, progs.trajs, progs.static, strict=True):
        T = r.base.matrix
        x.append(T[0, 3] + T[0, 1] * tr.q[:, 0])
        assert r.carriage_m is not None
        assert st.q[:, 0].min() >= r.carriage_m[0] - 1e-9
        assert st.q[:, 0].max() <= r.carriage_m[1] + 1e-9
    n = min(len(a) for a in x)
    gap = x[0][:n] - x[1][:n]                    # left_1 ahead of left_2 along the line
    assert gap.min() >= CARRIAGE_GAP_M - 1e-6, gap.min()
    # the line moved them: every carriage travelled with the body
    assert all(np.ptp(a) > 0.5 * d for a in x)


def _least_cycle_s(robots: list[Any], trajs: list[Any], min_distance_m: float) -> float:
    """Brute force over every start offset of two robots' programs (the booth's stagger steps,
    up to its largest delay either way): the shortest cycle [s] (the later one's offset +
    program) at which their arm points keep `min_distance_m` apart at every 20 ms, a robot
    holding its first pose before its start and its last after its end."""
    from paintcell.booth.booth import arm_points
    from paintcell.booth.booth_stagger import STAGGER_MAX_S, STAGGER_STEP_S

    dt = trajs[0].dt_s
    sub = max(1, round(0.02 / dt))
    p, q = (arm_points(r, tr.q[::sub]) for r, tr in zip(robots, trajs, strict=True))
    step = max(1, round(STAGGER_STEP_S / (sub * dt)))
    most = round(STAGGER_MAX_S / (sub * dt)) // step * step
    best = np.inf
    for o in range(-most, most + 1, step):
        n = max(len(p) + max(o, 0), len(q) + max(-o, 0))
        t = np.arange(n)
        a = p[np.clip(t - max(o, 0), 0, len(p) - 1)]
        b = q[np.clip(t - max(-o, 0), 0, len(q) - 1)]
        gap = np.linalg.norm(a[:, :, None] - b[:, None], axis=-1).min()
        if gap >= min_distance_m:
            best = min(best, (n - 1) * sub * dt)
    return float(best)


def test_a_robot_parked_away_from_its_work_is_parked_where_the_cycle_is_shorter(
        written: dict[str, Any]) -> None:
    """The verified two-robot line with its rear robot's home moved 2 m further from its
    station, along its carriage's stretch: `shorter_parks` moves it (to its station), and the
    booth built again with the homes it returns has a cycle shorter by at least a stagger step,
    both cycles re-measured by brute force over the start offsets on the programs the booth
    built; each program starts and ends at its robot's home, inside its carriage's stretch."""
    from paintcell.app.init_line_robots import shorter_parks
    from paintcell.booth.booth_programs import booth_programs
    from paintcell.booth.booth_stagger import STAGGER_STEP_S

    built, pp = written["built"], written["pp"]
    rear = built.robots[1]
    assert rear.carriage_m is not None
    far = round(rear.home[0] + 2.0 * float(np.sign(rear.home[0])), 3)   # 2 m further out
    assert rear.carriage_m[0] < far < rear.carriage_m[1]
    away = replace(built, robots=(built.robots[0], replace(rear, home=(far, *rear.home[1:]))))
    before = booth_programs(away, True, pp)
    got = shorter_parks(away, before, say=lambda _: None)
    assert got is not None
    parked, why = got
    assert rear.name in why and parked.robots[1].home[0] != far
    after = booth_programs(parked, True, pp)
    dist = built.thresholds.min_bell_distance_m
    was = _least_cycle_s(before.robots, before.static, dist)
    now = _least_cycle_s(after.robots, after.static, dist)
    assert now <= was - STAGGER_STEP_S + 0.02, (was, now)
    for r, tr in zip(parked.robots, after.static, strict=True):
        lo, hi = r.carriage_m if r.carriage_m is not None else r.rail_m
        assert lo - 1e-9 <= r.home[0] <= hi + 1e-9
        assert tr.q[0, 0] == pytest.approx(r.home[0], abs=1e-6)
        assert tr.q[-1, 0] == pytest.approx(r.home[0], abs=1e-6)


def test_the_written_line_holds_the_film_spec(written: dict[str, Any]) -> None:
    """The written line's [thresholds] hold a paint line's film spec (panel σ/μ ≤ 8 %, body
    ≤ 7 %) as read back from the file, so `paintcell check` fails a line whose film falls short
    of it; the seams' check (≤ 1.5× the interiors) is left out here, where the two panels (the
    front fender and the rear door, the front door between them) are farther apart than the
    seam band: measured on their planned surfaces, nearest vertices."""
    import tomllib

    from scipy.spatial import cKDTree

    from paintcell.booth.booth_data import load_toml_booth
    from paintcell.booth.booth_seams import SEAM_BAND_M

    a, b = (np.asarray(s.vertices) for s in written["pp"].surfaces)
    assert cKDTree(a).query(b)[0].min() > SEAM_BAND_M
    text = Path(written["out"]).read_text()
    table = tomllib.loads(text)["thresholds"]
    assert (table["max_executed_nsd_pct"], table["max_body_nsd_pct"]) == (8.0, 7.0)
    assert "max_seam_nsd_ratio" not in table and "no two panels meet" in text
    th = load_toml_booth(written["out"]).thresholds
    assert (th.max_executed_nsd_pct, th.max_body_nsd_pct, th.max_seam_nsd_ratio) == \
        (8.0, 7.0, None)


def test_tighter_takt_never_gives_fewer_robots(written: dict[str, Any]) -> None:
    from paintcell.app.init_line import choose_line

    counts = []
    length = written["booth"].conveyor.speed_m_s * 30.0 - 1.0       # pitch less the gap
    for takt_s in (60.0, 40.0, 25.0):
        takt = LineTakt(takt_s, length)
        line = choose_line(written["booth"], written["pp"], takt, 10, verify=False,
                           say=lambda s: None)
        counts.append(len(line.booth.robots))
        assert max(takt.robot_cycle_s(s.program_s) for s in line.shares) <= takt_s
    assert counts == sorted(counts) and counts[-1] > counts[0], counts
    # deterministic: the same inputs give the same line
    again = choose_line(written["booth"], written["pp"], LineTakt(25.0, length),
                        10, verify=False, say=lambda s: None)
    assert again.booth == line.booth


def test_a_takt_no_line_makes_is_refused_in_one_line(
        written: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import paintcell.booth.booth_plans as booth_plans
    from paintcell.cli.common import EXIT_USAGE
    from paintcell.cli.main import main

    monkeypatch.setattr(booth_plans, "plan_parts", lambda booth, fast: written["pp"])
    out = tmp_path / "fast.toml"
    body = str(written["body"])
    assert main(["init", body, "--line", "--takt", "8", "--out", str(out)]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "every 8 s" in err and "--takt" in err, err
    assert "10: " in err, err                # each count up to --max-robots said
    assert not out.exists() and not (tmp_path / "fast_panels").exists()
    # the options: a takt out of range, --takt without --line, an existing file without --force
    with pytest.raises(SystemExit) as usage:               # argparse's range check
        main(["init", body, "--line", "--takt", "0", "--out", str(out)])
    assert usage.value.code == EXIT_USAGE
    assert main(["init", body, "--takt", "40", "--out", str(out)]) == EXIT_USAGE
    assert main(["init", body, "--line", "--takt", "40", "--out",
                 str(written["out"])]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "--force" in err and "--line and --takt go together" in err
