"""Disturbances in a booth (`Booth.disturbances`, `paintcell run BOOTH --disturb`): every robot
of the cell runs under them, as the one robot of a single-robot cell does.

The programs are built once (the roof booth of tests/test_booth.py, fast, kinematic) and each run
executes them under other disturbances; the checks are closed forms of what each disturbance
does: a flow factor scales every robot's executed film by itself, a standoff error moves every
robot's executed TCP along its own spray axis, a trigger delay shifts every robot's brush signal
by whole 1 ms steps, a part offset moves the body the executed film is measured on; and zero
amplitudes give back the plain run's numbers.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tests.test_booth import ROOF_BOOTH


@pytest.fixture(scope="module")
def runs():
    """run(disturbances) → the roof booth's `BoothResult` under them, on one set of programs."""
    from paintcell.booth import booth_run
    from paintcell.booth.booth_programs import booth_programs

    progs = booth_programs(ROOF_BOOTH, True)
    done = {}

    def run(**dist):
        key = tuple(sorted(dist.items()))
        if key not in done:
            mp = pytest.MonkeyPatch()
            mp.setattr(booth_run, "booth_programs", lambda booth, fast, tasks=None: progs)
            try:
                done[key] = booth_run.run_booth(
                    dataclasses.replace(ROOF_BOOTH, disturbances=dist), fast=True,
                    mode="kinematic", progress=False)
            finally:
                mp.undo()
        return done[key]

    return run


def test_zero_disturbances_give_the_plain_run(runs):
    """`--disturb` with every amplitude zero (a seed set) reproduces the plain run's films and
    figures exactly."""
    plain = runs()
    zero = runs(part_offset_m=0.0, part_rotation_rad=0.0, tcp_offset_m=0.0,
                standoff_error_m=0.0, trigger_delay_s=0.0, flow_drift=0.0, seed=7)
    assert zero.trace.meta["disturbances"]["seed"] == 7
    for k in ("plan", "trajectory", "servo", "executed"):
        np.testing.assert_array_equal(zero.films_m[k], plain.films_m[k])
    for k in ("executed_nsd_pct", "max_part_executed_nsd_pct", "loss_pp", "reachability_pct",
              "executed_mean_um", "executed_within_tolerance_pct"):
        assert zero.report.metrics[k] == plain.report.metrics[k], k


def test_flow_scale_scales_every_robots_executed_film(runs):
    """Film is linear in the flow: with flow_scale 1.1 each robot's servo and executed films are
    1.1 × the plain run's (the motion is the same: kinematic), its planned and trajectory films
    unchanged — on every robot, not only the first."""
    plain, more = runs(), runs(flow_scale=1.1)
    assert plain.films_m["executed"].shape[0] == 2
    for k in ("servo", "executed"):
        for i in range(2):
            assert plain.films_m[k][i].max() > 0
            np.testing.assert_allclose(more.films_m[k][i], 1.1 * plain.films_m[k][i],
                                       rtol=1e-12, atol=0)
    for k in ("plan", "trajectory"):
        np.testing.assert_array_equal(more.films_m[k], plain.films_m[k])
    mu = plain.report.metrics["executed_mean_um"]
    assert more.report.metrics["executed_mean_um"] == pytest.approx(1.1 * mu, rel=1e-12)


def test_standoff_and_trigger_move_every_robot(runs):
    """A standoff error of 20 mm puts every robot's executed spray point 20 mm behind the
    modelled one along its own spray axis (tool −z), and the executed film changes; a trigger
    delay of 12 ms shifts every robot's brush signal by 12 samples."""
    plain, far = runs(), runs(standoff_error_m=0.02)
    late = runs(trigger_delay_s=0.012)
    for i in range(2):
        p, f = plain.traces[i], far.traces[i]
        z = p.tcp_rot_world[:, :, 2]
        np.testing.assert_allclose(f.tcp_pos_world - p.tcp_pos_world, -0.02 * z, atol=1e-12)
        assert not np.allclose(far.films_m["executed"][i], plain.films_m["executed"][i])
        on, on_late = plain.traces[i].paint_on, late.traces[i].paint_on
        np.testing.assert_array_equal(on_late[12:], on[:-12])
        assert not on_late[:12].any()
    assert far.report.metrics["executed_nsd_pct"] != plain.report.metrics["executed_nsd_pct"]


def test_part_offset_moves_the_body_under_every_robot(runs):
    """A 10 mm part offset: the body really sat 10 mm off its nominal place (the trace's
    realized placement), the servo film (against the nominal body) is the plain run's, and the
    executed film differs on every robot."""
    plain, off = runs(), runs(part_offset_m=0.01, seed=3)
    T0 = np.asarray(off.trace.meta["T_world_part_planned"])
    T1 = np.asarray(off.trace.meta["T_world_part_actual"])
    assert np.linalg.norm(T1[:3, 3] - T0[:3, 3]) == pytest.approx(0.01, abs=1e-12)
    np.testing.assert_array_equal(off.films_m["servo"], plain.films_m["servo"])
    for i in range(2):
        assert not np.allclose(off.films_m["executed"][i], plain.films_m["executed"][i])


def test_cli_disturb_reaches_a_booth(monkeypatch, capsys):
    """`paintcell run scenarios/booth.toml --disturb KEY=VALUE` runs the booth under them (the
    values reach its `disturbances`); a key no disturbance has is one line naming it."""
    from paintcell.app import pipeline
    from paintcell.booth.booth import Booth
    from paintcell.cli.main import main

    got = []

    class Ran(Exception):
        pass

    def fake(scn, *a, **kw):
        got.append(scn)
        raise Ran

    monkeypatch.setattr(pipeline, "run_scenario", fake)
    booth = str(Path(__file__).resolve().parents[1] / "scenarios" / "booth.toml")
    main(["run", booth, "--fast", "--disturb", "flow_scale=1.05", "--disturb", "seed=4"])
    assert len(got) == 1 and isinstance(got[0], Booth)
    assert got[0].disturbances == {"flow_scale": 1.05, "seed": 4}
    capsys.readouterr()
    assert main(["run", booth, "--fast", "--disturb", "wobble=1"]) != 0
    assert len(got) == 1            # refused before the run
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "wobble" in err[0] and "flow_scale" in err[0]
