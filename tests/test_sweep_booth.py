"""Booth sweeps over the conveyor's speed error, the body's placement on the skid and the
one-robot cell's factors on every robot (`paintcell.sweeps.sweep_worker`, the worker of any
cell).

The slow test sends a small sweep of the two-robot roof booth through a real Dask cluster
(a `dask scheduler` and two `dask worker` processes on 127.0.0.1, started by the fixture of
`tests.test_sweep_dask`), and checks it against independent truth:
- MuJoCo's carrier really ran at the nominal + sampled speed (least-squares slope of its joint);
- the executed film equals the film of the reference TCPs against a body moved analytically by
  (v + δv)·(t − t_ref) along the line (kinematic execution: the TCP is the reference);
- the nominal sample has no conveyor loss, and a larger speed error loses more uniformity;
- a sample run in this process equals the cluster's record (timings and worker excluded).
A placement error on the skid (`part_offset_m`, in this process): the executed film equals the
film of the reference TCPs moved the other way against the nominal body. A flow error
(`flow_scale`) scales every robot's executed film by itself.
"""

from __future__ import annotations

import dataclasses
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from paintcell.sweeps.sweep import run_sweep
from paintcell.sweeps.sweep_worker import RUN_KEYS
from paintcell.validation.sweep_spec import SweepError, SweepSpec
from tests.sweep_cases import plate_scenario
from tests.test_booth import ROOF_BOOTH
from tests.test_sweep_dask import cluster  # noqa: F401 - the loopback cluster fixture

SPEC = SweepSpec.from_strings(["conveyor_speed_error_m_s=uniform(-0.01, 0.01)"], 2, seed=3)


@pytest.fixture(scope="module")
def roof_payload() -> Any:
    """The roof booth's programs and reference films for SPEC, kinematic (built once: ~5 s)."""
    from paintcell.sweeps.sweep import spec_digest
    from paintcell.sweeps.sweep_worker import booth_payload

    return booth_payload(ROOF_BOOTH, SPEC.names, spec_digest(ROOF_BOOTH, SPEC, True, "kinematic"),
                         True, "kinematic")


def test_factors_that_do_not_fit_the_scenario_are_refused(tmp_path: Path) -> None:
    """A line-speed error on the single-robot cell: a one-line error naming the fix, before
    anything is planned or written. A booth takes every factor (on every robot)."""
    from paintcell.app.scenario_files import load_scenario
    from paintcell.sweeps.sweep import check_factors_fit
    from paintcell.validation.sweep_names import FACTORS

    plate = load_scenario(plate_scenario(tmp_path / "case"))
    with pytest.raises(SweepError, match="no conveyor; sweep a booth scenario"):
        run_sweep(plate, SPEC, tmp_path / "a", progress=False)
    assert not (tmp_path / "a").exists()
    every = SweepSpec.from_strings([f"{n}=uniform(0, 0.001)" for n in FACTORS
                                    if n not in ("gain_scale", "flow_scale")]
                                   + ["gain_scale=uniform(0.9, 1.1)",
                                      "flow_scale=uniform(0.9, 1.1)"], 2)
    check_factors_fit(ROOF_BOOTH, every)


def test_booth_toml_takes_a_sweep_table(tmp_path: Path) -> None:
    import tomllib

    import tomli_w

    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth_data import BoothDataError

    b = load_scenario("scenarios/booth.toml")
    assert b.sweep["factors"] == {"conveyor_speed_error_m_s": "normal(0, 0.0025)"}
    data = tomllib.loads(Path("scenarios/booth.toml").read_text())
    data["sweep"] = {"factors": {"flow_scale": "normal(1, 0.05)"}}
    if "applicator" in data:                  # the bell file, relative to scenarios/
        data["applicator"] = str(Path("scenarios").resolve() / data["applicator"])
    flow = tmp_path / "booth.toml"
    flow.write_text(tomli_w.dumps(data))
    assert load_scenario(flow).sweep["factors"] == {"flow_scale": "normal(1, 0.05)"}
    data["sweep"] = {"factors": {"wobble": "normal(1, 0.05)"}}
    flow.write_text(tomli_w.dumps(data))
    with pytest.raises(BoothDataError, match=r"booth.toml.*unknown factor 'wobble'"):
        load_scenario(flow)


@pytest.mark.slow
def test_conveyor_speed_sweep_on_a_loopback_cluster(
        tmp_path: Path, cluster: tuple[str, list[subprocess.Popen[bytes]]],  # noqa: F811
        roof_payload: Any) -> None:
    from paintcell.booth.booth_film import body_uniformity, gun_in_body
    from paintcell.paint.deposition import thickness
    from paintcell.sweeps.sweep_worker import run_sample

    address, _ = cluster
    res = run_sweep(ROOF_BOOTH, SPEC, tmp_path / "remote", fast=True, mode="kinematic",
                    scheduler=address, progress=False, report=False)
    assert res.ran == SPEC.samples and len(res.samples) == SPEC.samples
    assert len(list((tmp_path / "remote" / "samples").glob("*.json"))) == SPEC.samples
    v = ROOF_BOOTH.conveyor.speed_m_s
    recs = [res.nominal, *res.samples]
    dv = [r["factors"].get("conveyor_speed_error_m_s", 0.0) for r in recs]
    assert all(abs(x) > 1e-3 for x in dv[1:])   # the seed draws real errors
    for r, d in zip(recs, dv, strict=True):
        assert "error" not in r
        assert abs(r["metrics"]["carrier_speed_m_s"] - (v + d)) < 1e-9
    # no speed error, no conveyor loss; a larger error loses more (drift ∝ δv)
    assert abs(res.nominal["metrics"]["loss_conveyor_pp"]) < 1e-9
    loss = {abs(d): r["metrics"]["loss_conveyor_pp"] for r, d in zip(recs[1:], dv[1:],
                                                                       strict=True)}
    ordered = [loss[k] for k in sorted(loss)]
    assert ordered[0] > 0.01 and ordered == sorted(ordered)

    # the largest error again, in this process: same record; its film against the analytic body
    payload = roof_payload
    i = int(np.argmax(np.abs(dv[1:])))
    rec = res.samples[i]
    local = run_sample(payload, rec["index"], SPEC.design()[rec["index"]],
                             int(SPEC.sample_seeds()[rec["index"]]))
    assert ({k: w for k, w in local.items() if k not in RUN_KEYS}
            == {k: w for k, w in rec.items() if k not in RUN_KEYS})
    progs = payload.programs
    t = progs.trajs[0].t_s
    carrier = (v + dv[1 + i]) * (t - progs.t_ref_s)                # where the body really was
    app, body = progs.plans[0].applicator, progs.body
    film = sum(thickness(app, gun_in_body(t, tr.tcp_pos_world, tr.tcp_rot_world, tr.paint_on,
                                          ROOF_BOOTH.body_placement.matrix, carrier,
                                          ROOF_BOOTH.conveyor.unit, brush=tr.flow),
                         body.vertices, body.normals) for tr in progs.trajs)
    nsd = body_uniformity(film, body.vertex_areas)
    assert abs(nsd - rec["metrics"]["executed_nsd_pct"]) < 1e-9 * nsd
    assert abs(1e6 * film.min() - rec["metrics"]["executed_min_um"]) < 1e-9 * 1e6 * film.max()


@pytest.mark.slow
def test_part_offset_on_the_skid_moves_the_body_the_films_see(roof_payload: Any) -> None:
    """`part_offset_m` on a booth (kinematic execution, in this process): the executed film is
    the film of the reference TCPs moved by −o against the nominal body — a body moved by o
    seen from the TCPs, a different path than the sample's (which moves the body), with o the
    sample's seeded direction (the single-robot sweep's convention: the first normal draw of
    the sample's seed, normalized, in the part frame) times |x|. The servo film is the
    nominal body's (the TCPs did not change), so the loss it counts as the body's misplacement
    (executed − servo) is exactly the executed film's change."""
    from paintcell.booth.booth_film import body_uniformity, gun_in_body
    from paintcell.paint.deposition import thickness
    from paintcell.sweeps.sweep_worker import run_sample

    # the same programs and reference films (no factor changes them), another factor
    payload = dataclasses.replace(roof_payload, names=("part_offset_m",),
                                  digest="part-offset-test")
    nominal = run_sample(payload, -1, None, 0)
    x, seed = -0.02, 11    # a 20 mm placement error (the sign of a draw does not matter)
    rec = run_sample(payload, 0, np.array([x]), seed)
    assert "error" not in rec and rec["factors"] == {"part_offset_m": x}
    d = np.random.default_rng(seed).normal(size=3)
    T0 = ROOF_BOOTH.body_placement.matrix
    o = T0[:3, :3] @ (abs(x) * d / np.linalg.norm(d))            # world offset of the body
    progs = payload.programs
    t = progs.trajs[0].t_s
    carrier = ROOF_BOOTH.conveyor.position_m(t, progs.t_ref_s)
    body = progs.body
    film = np.zeros(len(body.vertices))
    for i, tr in enumerate(progs.trajs):
        (job,) = progs.jobs[i]                   # one job per robot here
        app = progs.plans[job.part].applicator   # robot i's part, at its own flow
        film += thickness(app, gun_in_body(t, tr.tcp_pos_world - o, tr.tcp_rot_world,
                                           tr.paint_on, T0, carrier, ROOF_BOOTH.conveyor.unit,
                                           brush=tr.flow),
                          body.vertices, body.normals)
    nsd = body_uniformity(film, body.vertex_areas)
    m, m0 = rec["metrics"], nominal["metrics"]
    assert abs(nsd - m["executed_nsd_pct"]) < 1e-9 * nsd
    assert abs(1e6 * film.min() - m["executed_min_um"]) < 1e-9 * 1e6 * film.max()
    # the TCPs are the reference's: the servo film is the nominal run's executed one (no
    # offset, the line at its speed: no conveyor loss there), so the loss is the move's
    assert abs(m0["loss_conveyor_pp"]) < 1e-9
    assert m["loss_conveyor_pp"] == pytest.approx(
        m["executed_nsd_pct"] - m0["executed_nsd_pct"], abs=1e-9)
    assert abs(m["loss_conveyor_pp"]) > 1e-3


def test_flow_scale_on_a_booth_scales_every_robots_executed_film(roof_payload: Any) -> None:
    """`flow_scale` (a one-robot factor) on a booth sample: every robot paints 1.1 × the flow, so
    the executed mean film is 1.1 × the nominal sample's (film is linear in the flow; kinematic:
    the same motion) and its σ/μ and conveyor loss are the nominal's."""
    from paintcell.sweeps.sweep_worker import run_sample

    payload = dataclasses.replace(roof_payload, names=("flow_scale",), digest="flow-test")
    nominal = run_sample(payload, -1, None, 0)
    rec = run_sample(payload, 0, np.array([1.1]), 5)
    m, m0 = rec["metrics"], nominal["metrics"]
    assert "error" not in rec and rec["factors"] == {"flow_scale": 1.1}
    assert m["executed_mean_um"] == pytest.approx(1.1 * m0["executed_mean_um"], rel=1e-12)
    assert m["executed_min_um"] == pytest.approx(1.1 * m0["executed_min_um"], rel=1e-12)
    assert m["executed_nsd_pct"] == pytest.approx(m0["executed_nsd_pct"], rel=1e-9)
    assert m["loss_conveyor_pp"] == pytest.approx(m0["loss_conveyor_pp"], abs=1e-9)
