"""One film build over the body (sim.booth_build): each part's planned mean re-measured on its
own surface equals the target, the film scales pointwise by one factor per part (the ESRB model
is linear in its rates), each part's σ/μ is unchanged, the default target keeps the paint on the
body, and an unreachable target is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

from planning import parts
from planning.applicator import Applicator
from planning.coverage import PlannerSettings, plan_coverage
from planning.deposition import thickness
from sim.booth import BoothError
from sim.booth_build import common_film_build

RES_M = 0.03


@pytest.fixture(scope="module")
def two_parts():
    out = []
    for name, kw in (("roof", {"first_side": "left"}), ("door", {})):
        s = parts.get_part(name, resolution_m=RES_M)
        out.append((s, plan_coverage(s, Applicator.default(), PlannerSettings(**kw))))
    return out


def _film(plan, s):
    return thickness(plan.applicator, plan.gun_samples(), s.vertices, s.normals)


def _nsd(f, a):
    mu = np.average(f, weights=a)
    return np.sqrt(np.average((f - mu) ** 2, weights=a)) / mu


@pytest.mark.parametrize("target_um", [None, 30.0])
def test_every_part_reaches_the_common_film_build(two_parts, target_um):
    surfaces = [s for s, _ in two_parts]
    plans = [p for _, p in two_parts]
    before = [_film(p, s) for s, p in two_parts]
    areas = [s.vertex_areas for s in surfaces]
    means = [np.average(f, weights=a) for f, a in zip(before, areas, strict=True)]
    # The library parts really differ (the reason for the common build).
    assert max(means) / min(means) > 1.3
    new, rec = common_film_build(surfaces, plans, ["roof", "door"], target_um)
    after = [_film(p, s) for s, p in zip(surfaces, new, strict=True)]
    target = rec["target_um"] * 1e-6
    if target_um is None:     # paint on the body unchanged: Σ A μ before = after
        vol = sum(f @ a for f, a in zip(before, areas, strict=True))
        assert sum(f @ a for f, a in zip(after, areas, strict=True)) == pytest.approx(vol,
                                                                                    rel=1e-12)
    else:
        assert target == pytest.approx(30e-6, rel=1e-15)
    for name, f0, f1, a in zip(("roof", "door"), before, after, areas, strict=True):
        assert np.average(f1, weights=a) == pytest.approx(target, rel=1e-12)
        on = f0 > 1e-3 * f0.max()
        k = f1[on] / f0[on]
        assert np.ptp(k) <= 1e-12 * k.mean() and k.mean() == pytest.approx(
            rec["parts"][name]["flow_factor"], rel=1e-12)
        assert _nsd(f1, a) == pytest.approx(_nsd(f0, a), rel=1e-12)
    # The trajectories are untouched: same passes, same timing.
    assert all(n.passes is p.passes for n, p in zip(new, plans, strict=True))


def test_an_unreachable_film_build_is_refused_in_one_line(two_parts):
    with pytest.raises(BoothError, match=r"needs .*× the bell flow, outside 0.2–5.0×; set "
                                         r"film_target_um") as exc:
        common_film_build([s for s, _ in two_parts], [p for _, p in two_parts],
                          ["roof", "door"], 500.0)
    assert "\n" not in str(exc.value)


def test_booth_toml_film_build_keys(tmp_path):
    from sim.booth_data import BoothDataError
    from sim.scenario import load_scenario

    head = 'name = "b"\n{}\n[[parts]]\npart = "door"\n[[robots]]\nname = "r"\n'
    f = tmp_path / "b.toml"
    f.write_text(head.format("film_target_um = 28.5\ncommon_film_build = false"))
    b = load_scenario(f)
    assert b.film_target_um == 28.5 and b.common_film_build is False
    assert load_scenario("scenarios/booth.toml").common_film_build is True
    for bad, msg in (("film_target_um = -1", "film_target_um must be a number > 0"),
                     ('common_film_build = "yes"', "common_film_build must be true or false")):
        f.write_text(head.format(bad))
        with pytest.raises(BoothDataError, match=msg):
            load_scenario(f)
