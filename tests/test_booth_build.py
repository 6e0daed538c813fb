"""One film build over the body (paintcell.booth.booth_build): each part's planned mean
re-measured on its
own surface equals the target, the film scales pointwise by one factor per part (the ESRB model
is linear in its rates), each part's σ/μ is unchanged, the default target keeps the paint on the
body, and an unreachable target is refused in one line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from paintcell.booth.booth import BoothError
from paintcell.booth.booth_build import common_film_build
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.surface import parts

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
    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth_data import BoothDataError

    head = 'name = "b"\n{}\n[[parts]]\npart = "door"\n[[robots]]\nname = "r"\n'
    f = tmp_path / "b.toml"
    f.write_text(head.format("film_target_um = 28.5\ncommon_film_build = false\n"
                             "film_refine_pace = true"))
    b = load_scenario(f)
    assert b.film_target_um == 28.5 and b.common_film_build is False and b.film_refine_pace
    assert load_scenario("scenarios/booth.toml").common_film_build is True
    for bad, msg in (("film_target_um = -1", "film_target_um must be a number > 0"),
                     ('common_film_build = "yes"', "common_film_build must be true or false"),
                     ("film_refine_pace = 1", "film_refine_pace must be true or false")):
        f.write_text(head.format(bad))
        with pytest.raises(BoothDataError, match=msg):
            load_scenario(f)


def _panels(gap_m: float):
    """Two library panels (1 m × 0.8 m, +z painted) side by side along x, `gap_m` apart."""
    from paintcell.booth.booth_film import merge_surfaces

    s = parts.get_part("panel", resolution_m=RES_M)
    plan = plan_coverage(s, Applicator.default(), PlannerSettings())
    Ts = []
    for x in (-(0.5 + gap_m / 2), 0.5 + gap_m / 2):
        T = np.eye(4)
        T[0, 3] = x
        Ts.append(T)
    return merge_surfaces([s, s], Ts, "two"), [plan, plan], Ts, [len(s.vertices)] * 2


def _body_film(body, plans, Ts):
    from paintcell.booth.booth_film import plan_gun_in_body

    return sum(thickness(p.applicator, plan_gun_in_body(p, T), body.vertices, body.normals)
               for p, T in zip(plans, Ts, strict=True))


def test_seams_between_adjacent_parts_are_blended():
    """Two panels 2 cm apart, each planned alone: their edge passes paint the seam twice. The
    blend switches paint off only (the motion is unchanged), the chosen share is the best of
    SEAM_SHARES re-measured by brute force, and the body's σ/μ falls well below the unblended
    one; panels 1 m apart have no seam and nothing is switched off."""
    from paintcell.booth.booth_seams import blend_part_seams, pass_in_body
    from paintcell.coverage.patches import SEAM_SHARES, ownership_brush_off, seam_volumes

    body, plans, Ts, counts = _panels(0.02)
    a = body.vertex_areas
    new, rec = blend_part_seams(body, plans, Ts, counts, ["a", "b"])
    before, after = _body_film(body, plans, Ts), _body_film(body, new, Ts)
    assert _nsd(after, a) * 100 == pytest.approx(rec["body_planned_nsd_pct"], rel=1e-9)
    assert _nsd(before, a) * 100 == pytest.approx(rec["unblended_planned_nsd_pct"], rel=1e-9)
    assert _nsd(after, a) < 0.6 * _nsd(before, a)
    assert sum(rec["samples_switched_off"].values()) > 0
    for p0, p1 in zip(plans, new, strict=True):
        for q0, q1 in zip(p0.passes, p1.passes, strict=True):
            assert np.array_equal(q0.positions, q1.positions)
            assert np.array_equal(q0.times_s, q1.times_s)
            assert not np.any(q1.paint_on & ~q0.paint_on)          # only switched off
    # Brute force over the shares (volumes per part on the body, films re-summed here).
    offs = np.cumsum([0, *counts])
    vols = []
    for k, (p, T) in enumerate(zip(plans, Ts, strict=True)):
        own = np.zeros(len(body.vertices), bool)
        own[offs[k]:offs[k + 1]] = True
        vols.append(seam_volumes(p.applicator, [pass_in_body(q, T) for q in p.passes], own,
                                 body))
    nsd = []
    for share in SEAM_SHARES:
        cand = [dataclasses.replace(p, passes=tuple(ownership_brush_off(list(p.passes), v,
                                                                        share)[0]))
                for p, v in zip(plans, vols, strict=True)]
        nsd.append(_nsd(_body_film(body, cand, Ts), a))
    assert rec["share"] == SEAM_SHARES[int(np.argmin(nsd))]
    # Far apart: no seam.
    body, plans, Ts, counts = _panels(1.0)
    new, rec = blend_part_seams(body, plans, Ts, counts, ["a", "b"])
    assert sum(rec["samples_switched_off"].values()) == 0
    assert all(n is p for n, p in zip(new, plans, strict=True))


def test_booth_refinement_evens_the_film_and_keeps_every_pass_duration():
    """`film_refine.refine_parts` on the door planned without refinement: the film re-measured on
    the part is more even than the plan's, every pass's duration (re-measured from its times)
    stays within 0.5 % of the plan's, while the free refinement (no duration term) moves some
    pass by more — the term is what holds the pace."""
    from paintcell.coverage.film_refine import refine_parts, refine_speeds
    from paintcell.paint.metrics import boundary_band_mask, boundary_vertices

    s = parts.get_part("door", resolution_m=0.05)           # coarse: the test's time
    st = PlannerSettings(film_refine=False)
    plan = plan_coverage(s, Applicator.default(), st)
    (out,), rec = refine_parts([s], [plan], [st], ["door"])
    assert rec["parts"]["door"]["applied"]
    a = s.vertex_areas
    assert _nsd(_film(out, s), a) < 0.95 * _nsd(_film(plan, s), a)

    def durations(pp):
        return np.array([p.times_s[-1] - p.times_s[0] for p in pp])

    held = durations(out.passes) / durations(plan.passes) - 1.0
    assert np.abs(held).max() < 0.005
    interior = boundary_band_mask(s.vertices, s.vertices[boundary_vertices(s.faces)],
                                  st.film_guard_band_m)
    free, info = refine_speeds(plan.applicator, s, list(plan.passes), st.v_min_m_s,
                               st.v_max_m_s, interior)
    assert info["applied"]
    assert np.abs(durations(free) / durations(plan.passes) - 1.0).max() > 2 * np.abs(held).max()


def _three_panels():
    """Three library panels in a row along x, 2 cm then 15 cm apart: two seams that want
    different shares."""
    from paintcell.booth.booth_film import merge_surfaces

    s = parts.get_part("panel", resolution_m=RES_M)
    plan = plan_coverage(s, Applicator.default(), PlannerSettings())
    Ts = []
    for x in (-1.02, 0.0, 1.15):
        T = np.eye(4)
        T[0, 3] = x
        Ts.append(T)
    return merge_surfaces([s] * 3, Ts, "three"), [plan] * 3, Ts, [len(s.vertices)] * 3


def test_per_seam_shares_bounded_by_brute_force_and_never_worse_than_one():
    """Per-seam shares on three panels (two seams): re-measured here by brute force over every
    pair of shares (nine shares or no blending each; each sample's volumes on every part from
    the literal deposition formula, its seam the part it paints most after its own, films
    summed part by part): the brute-force minimum ≤ the coordinate descent's σ/μ ≤ the single
    share's, the descent's shares are a coordinate-wise minimum of the brute-force table, its
    figure is the table's at its shares, and here it is strictly lower than one share. Only
    paint switches off; the body film is the sum of the parts' films."""
    from paintcell.booth.booth_film import plan_gun_in_body
    from paintcell.booth.booth_seams import MAX_SEAM_SWEEPS, blend_part_seams, pass_in_body
    from paintcell.coverage.patches import SEAM_SHARES
    from paintcell.paint.deposition import deposition_rate_reference
    from paintcell.paint.deposition_samples import GunSamples

    body, plans, Ts, counts = _three_panels()
    a, names = body.vertex_areas, ["a", "b", "c"]
    one, rec1 = blend_part_seams(body, plans, Ts, counts, names)
    new, rec = blend_part_seams(body, plans, Ts, counts, names, per_seam=True)
    assert rec1["seam_shares"] == "one" and "seams" not in rec1
    assert rec["seam_shares"] == "per seam" and set(rec["seams"]) == {"a|b", "b|c"}
    part_of = np.repeat(np.arange(3), counts)
    vol = []                                    # per part, per pass: (S, 3) volume on each part
    for p, T in zip(plans, Ts, strict=True):
        vol.append([deposition_rate_reference(p.applicator, q.positions, q.spray_axes,
                                              q.travel_dirs, body.vertices, body.normals)
                    @ (a[:, None] * (part_of[:, None] == np.arange(3)))
                    for q in (pass_in_body(q, T) for q in p.passes)])
    options = [*SEAM_SHARES, None]
    seam_of = {(0, 1): 0, (1, 0): 0, (1, 2): 1, (2, 1): 1}
    cache = {}

    def part_plan(k, pick):
        passes = []
        for q, v in zip(plans[k].passes, vol[k], strict=True):
            own, other = v[:, k], v.sum(axis=1) - v[:, k]
            o = v.copy()
            o[:, k] = -1.0
            nb = o.argmax(axis=1)
            sh = np.array([np.inf if options[pick[seam_of[(k, j)]]] is None
                           else options[pick[seam_of[(k, j)]]] if (k, j) in seam_of
                           else np.inf for j in nb])
            off = q.paint_on & (other > 0) & (other > np.where(np.isfinite(sh), sh, 0) * own) \
                & np.isfinite(sh)
            passes.append(dataclasses.replace(q, paint_on=q.paint_on & ~off))
        return dataclasses.replace(plans[k], passes=tuple(passes))

    def part_film(k, pick):
        key = (k, tuple(pick[i] for i in {0: (0,), 1: (0, 1), 2: (1,)}[k]))
        if key not in cache:
            p = part_plan(k, pick)
            cache[key] = thickness(p.applicator, plan_gun_in_body(p, Ts[k]), body.vertices,
                                   body.normals)
        return cache[key]

    table = np.array([[_nsd(sum(part_film(k, (i, j)) for k in range(3)), a) * 100
                       for j in range(len(options))] for i in range(len(options))])
    i, j = (options.index(rec["seams"][s]) for s in ("a|b", "b|c"))
    assert rec["body_planned_nsd_pct"] == pytest.approx(table[i, j], rel=1e-9)
    s0 = options.index(rec1["share"])
    assert rec1["body_planned_nsd_pct"] == pytest.approx(table[s0, s0], rel=1e-9)
    assert table.min() <= rec["body_planned_nsd_pct"] + 1e-9
    assert rec["converged"] and 1 <= rec["sweeps"] <= MAX_SEAM_SWEEPS   # a coordinate-wise min:
    assert rec["body_planned_nsd_pct"] <= table[i, :].min() + 1e-9
    assert rec["body_planned_nsd_pct"] <= table[:, j].min() + 1e-9
    assert rec["body_planned_nsd_pct"] < rec1["body_planned_nsd_pct"] - 0.05
    assert rec["single_share_planned_nsd_pct"] == rec1["body_planned_nsd_pct"]
    nsd_steps = [s["body_planned_nsd_pct"] for s in rec["steps"]]
    assert nsd_steps[0] == rec1["body_planned_nsd_pct"] and np.all(np.diff(nsd_steps) < 0)
    assert nsd_steps[-1] == pytest.approx(rec["body_planned_nsd_pct"], rel=1e-9)
    for p0, p1 in zip(plans, new, strict=True):
        for q0, q1 in zip(p0.passes, p1.passes, strict=True):
            assert np.array_equal(q0.positions, q1.positions)
            assert np.array_equal(q0.times_s, q1.times_s)
            assert not np.any(q1.paint_on & ~q0.paint_on)          # only switched off
    # Superposition: one deposition call over every part's samples = the sum of the parts'.
    guns = [plan_gun_in_body(p, T) for p, T in zip(new, Ts, strict=True)]
    whole = thickness(new[0].applicator, GunSamples(
        *(np.concatenate([getattr(g, f) for g in guns])
          for f in ("positions", "spray_axes", "travel_dirs", "dwell_s"))),
        body.vertices, body.normals)
    parts_sum = sum(thickness(new[0].applicator, g, body.vertices, body.normals) for g in guns)
    assert np.allclose(whole, parts_sum, rtol=1e-9, atol=1e-15)
    assert _nsd(whole, a) * 100 == pytest.approx(rec["body_planned_nsd_pct"], rel=1e-9)


def test_booth_toml_seam_shares_key(tmp_path):
    """`seam_shares` reads "one" (the default, scenarios/booth.toml's) or "per seam"; anything
    else is refused in one line."""
    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth_data import BoothDataError

    assert load_scenario("scenarios/booth.toml").seam_shares == "one"
    head = 'name = "b"\n{}\n[[parts]]\npart = "door"\n[[robots]]\nname = "r"\n'
    f = tmp_path / "b.toml"
    f.write_text(head.format('seam_shares = "per seam"'))
    assert load_scenario(f).seam_shares == "per seam"
    f.write_text(head.format('seam_shares = "each"'))
    with pytest.raises(BoothDataError, match="seam_shares = 'each' must be 'one' or 'per seam'"):
        load_scenario(f)


def test_parts_refined_together_beat_each_part_refined_alone():
    """`film_refine.refine_together` on two panels 2 cm apart (seam blended, the second at 1.3×
    the bell's flow, one pass of the first capped by its robot at 0.3 m/s): the body's film
    re-measured here from every part's plan at its own flow is the recorded one, more even
    than before and than each panel refined alone on its own surface (`refine_parts`), and no
    worse away from the seam; only the timing changes; the recorded duration changes are the
    passes' re-measured ones; every speed stays within the planner's bounds and the cap. With
    the durations held (`PASS_TIME_WEIGHT`) every pass keeps its duration within 0.5 % and the
    film still gains."""
    from paintcell.booth.booth_seams import blend_part_seams, pass_in_body, seam_band
    from paintcell.coverage.film_refine import PASS_TIME_WEIGHT, refine_parts, refine_together
    from paintcell.coverage.plan import times_from_speeds

    body, plans, Ts, counts = _panels(0.02)
    plans = [plans[0], dataclasses.replace(plans[1], applicator=plans[1].applicator.scaled(1.3))]
    plans, _ = blend_part_seams(body, plans, Ts, counts, ["a", "b"])
    moved = [dataclasses.replace(p, passes=tuple(pass_in_body(q, T) for q in p.passes))
             for p, T in zip(plans, Ts, strict=True)]
    st = PlannerSettings()
    interior = ~seam_band(body.vertices, counts)
    caps = [[None] * len(plans[0].passes), None]
    caps[0][2] = np.full(len(plans[0].passes[2].speeds_m_s), 0.3)
    out, rec = refine_together(body, moved, [st, st], interior, caps)
    assert rec["applied"]
    a = body.vertex_areas
    eye = [np.eye(4)] * 2
    before, after = _body_film(body, moved, eye), _body_film(body, out, eye)
    assert _nsd(after, a) * 100 == pytest.approx(rec["nsd_after_pct"], rel=1e-9)
    assert _nsd(after, a) < 0.9 * _nsd(before, a)
    assert _nsd(after[interior], a[interior]) <= _nsd(before[interior], a[interior])
    panel = parts.get_part("panel", resolution_m=RES_M)
    alone, _ = refine_parts([panel, panel], plans, [st, st], ["a", "b"], caps)
    assert _nsd(after, a) < _nsd(_body_film(body, alone, Ts), a)
    held, rec_held = refine_together(body, moved, [st, st], interior, caps,
                                     pass_time_weight=PASS_TIME_WEIGHT)
    assert rec_held["applied"]
    assert _nsd(_body_film(body, held, eye), a) < 0.95 * _nsd(before, a)
    changes = []
    for k, (p0, p1, p2) in enumerate(zip(moved, out, held, strict=True)):
        assert p1.applicator is p0.applicator
        for i, (q0, q1, q2) in enumerate(zip(p0.passes, p1.passes, p2.passes, strict=True)):
            assert np.array_equal(q0.positions, q1.positions)
            assert np.array_equal(q0.paint_on, q1.paint_on)
            v0 = q0.speeds_m_s if (k, i) != (0, 2) else np.minimum(q0.speeds_m_s, 0.3)
            t0 = times_from_speeds(q0.positions, v0)     # the cap is what the robot paints
            d0, d2 = t0[-1] - t0[0], q2.times_s[-1] - q2.times_s[0]
            assert abs(d2 / d0 - 1.0) < 0.005
            changes.append((q1.times_s[-1] - q1.times_s[0]) - (q0.times_s[-1] - q0.times_s[0]))
            for q in (q1, q2):
                assert q.speeds_m_s.min() >= st.v_min_m_s - 1e-12
                assert q.speeds_m_s.max() <= st.v_max_m_s + 1e-12
    assert rec["max_pass_duration_change_s"] == pytest.approx(np.abs(changes).max(), rel=1e-9)
    assert rec["pass_duration_change_s"] == pytest.approx(sum(changes), rel=1e-9)
    assert max(out[0].passes[2].speeds_m_s.max(), held[0].passes[2].speeds_m_s.max()) \
        <= 0.3 + 1e-12


def _turned_panels():
    """Two library panels 2 cm apart, the second turned half a turn about z (its part frame is
    not the body's), blended at their seam; (body, plans, placements, vertex counts, panel)."""
    from paintcell.booth.booth_film import merge_surfaces
    from paintcell.booth.booth_seams import blend_part_seams

    _, plans, Ts, counts = _panels(0.02)
    Ts[1][:3, :3] = np.diag([-1.0, -1.0, 1.0])
    panel = parts.get_part("panel", resolution_m=RES_M)
    body = merge_surfaces([panel, panel], Ts, "two")
    plans, _ = blend_part_seams(body, plans, Ts, counts, ["a", "b"])
    return body, plans, Ts, counts, panel


def test_refine_body_re_times_the_part_frame_plans_against_the_body_film():
    """`booth_plans.refine_body` on two panels, the second turned half a turn and planned with a
    lower top speed (0.55 m/s, its own `[parts.planner]`), one pass of the first capped at 0.3
    m/s: the recorded σ/μ before and after are the body films re-measured here from the plans
    as the robots would paint them (slowed to the bounds and the cap) and from the returned
    part-frame plans, both placed on the body; lower by a tenth at least; positions, spray axes
    and paint switches are the planner's; every pass's times follow its speeds along its own
    positions; each part keeps its own speed bounds and the cap; a part whose planner says
    film_refine = false holds every part's film."""
    from types import SimpleNamespace

    from paintcell.booth.booth_plans import refine_body
    from paintcell.coverage.plan import times_from_speeds

    body, plans, Ts, _, panel = _turned_panels()
    booth = SimpleNamespace(planner={}, parts=[SimpleNamespace(planner={}, part="a"),
                                               SimpleNamespace(planner={"v_max_m_s": 0.55},
                                                               part="b")])
    pp = SimpleNamespace(surfaces=[panel, panel], T_body_parts=Ts)
    caps = [[None] * len(plans[0].passes), None]
    caps[0][2] = np.full(len(plans[0].passes[2].speeds_m_s), 0.3)
    out, rec = refine_body(booth, pp, plans, body, caps)
    assert rec["applied"]
    a = body.vertex_areas
    after = _body_film(body, out, Ts)
    assert 100 * _nsd(after, a) == pytest.approx(rec["nsd_after_pct"], rel=1e-9)

    def slowed(q, top):               # what the robot paints: the plan under its caps
        v = np.minimum(q.speeds_m_s, top)
        return dataclasses.replace(q, speeds_m_s=v, times_s=times_from_speeds(q.positions, v))

    start = [dataclasses.replace(plans[0], passes=tuple(
                 slowed(q, 0.3 if i == 2 else 1.0) for i, q in enumerate(plans[0].passes))),
             dataclasses.replace(plans[1], passes=tuple(slowed(q, 0.55) for q in plans[1].passes))]
    before = _body_film(body, start, Ts)
    assert 100 * _nsd(before, a) == pytest.approx(rec["nsd_before_pct"], rel=1e-9)
    assert _nsd(after, a) < 0.9 * _nsd(before, a)
    for k, (p0, p1) in enumerate(zip(plans, out, strict=True)):
        assert p1.applicator is p0.applicator
        for q0, q1 in zip(p0.passes, p1.passes, strict=True):
            for key in ("positions", "spray_axes", "paint_on"):
                assert np.array_equal(getattr(q0, key), getattr(q1, key))
            assert np.abs(times_from_speeds(q1.positions, q1.speeds_m_s)
                          - q1.times_s).max() < 1e-12
            assert q1.speeds_m_s.max() <= (1.0 if k == 0 else 0.55) + 1e-12
    assert max(q.speeds_m_s.max() for q in plans[1].passes) > 0.55   # the bound did bind
    assert out[0].passes[2].speeds_m_s.max() <= 0.3 + 1e-12
    held = SimpleNamespace(planner={}, parts=[SimpleNamespace(planner={}, part="a"),
                                              SimpleNamespace(planner={"film_refine": False},
                                                              part="b")])
    same, why = refine_body(held, pp, plans, body, caps)
    assert same is plans and not why["applied"] and "film_refine = false" in why["reason"]


def test_refine_together_is_the_same_with_shared_or_copied_deposition_models():
    """Plans made on Dask workers come back with their own (equal) copy of the deposition
    model, plans made here share one object: `refine_together` re-times both alike, bit for
    bit."""
    import pickle

    from paintcell.booth.booth_seams import pass_in_body, seam_band
    from paintcell.coverage.film_refine import refine_together

    body, plans, Ts, counts, _ = _turned_panels()
    moved = [dataclasses.replace(p, passes=tuple(pass_in_body(q, T) for q in p.passes))
             for p, T in zip(plans, Ts, strict=True)]
    assert moved[0].applicator is moved[1].applicator
    copied = [pickle.loads(pickle.dumps(p)) for p in moved]
    assert copied[0].applicator is not copied[1].applicator
    st, interior = PlannerSettings(), ~seam_band(body.vertices, counts)
    here, rec_here = refine_together(body, moved, [st, st], interior)
    there, rec_there = refine_together(body, copied, [st, st], interior)
    assert rec_here["applied"] and rec_here == rec_there
    for p, q in zip(here, there, strict=True):
        for a, b in zip(p.passes, q.passes, strict=True):
            assert np.array_equal(a.speeds_m_s, b.speeds_m_s)


def test_a_pass_switched_off_at_a_seam_is_painted_again_only_where_the_film_wants_it():
    """`refine_together` with `restorable`: on two panels, the first panel's middle pass
    switched off entirely (as a seam's blending would) leaves a thin stripe, and a copy of a
    pass lifted 2 m over the panels (it paints nothing there) is switched off too. The relaxed
    fit wants most of the middle pass back and none of the lifted one; the result paints those
    samples of the middle pass again (and only samples it painted before), its σ/μ is the body
    film re-measured here, lower than the fit without giving back and no worse on the interior
    than the start; the lifted pass stays off."""
    from paintcell.booth.booth_seams import pass_in_body, seam_band
    from paintcell.coverage.film_refine import RESTORE_SHARE, refine_together

    body, plans, Ts, counts, _ = _turned_panels()
    moved = [dataclasses.replace(p, passes=tuple(pass_in_body(q, T) for q in p.passes))
             for p, T in zip(plans, Ts, strict=True)]
    mid = len(moved[0].passes) // 2
    p_mid = moved[0].passes[mid]
    lifted = dataclasses.replace(p_mid, positions=p_mid.positions + [0.0, 0.0, 2.0])
    a_passes = list(moved[0].passes)
    a_passes[mid] = dataclasses.replace(p_mid, paint_on=np.zeros_like(p_mid.paint_on))
    a_passes.append(dataclasses.replace(lifted, paint_on=np.zeros_like(lifted.paint_on)))
    start = [dataclasses.replace(moved[0], passes=tuple(a_passes)), moved[1]]
    restorable = [[None] * len(a_passes), [None] * len(moved[1].passes)]
    restorable[0][mid] = p_mid.paint_on.copy()
    restorable[0][-1] = lifted.paint_on.copy()
    st, interior = PlannerSettings(), ~seam_band(body.vertices, counts)
    plain, rec_plain = refine_together(body, start, [st, st], interior)
    out, rec = refine_together(body, start, [st, st], interior, restorable=restorable)
    shares = rec["paint_shares"]
    assert shares[f"0:{mid}"] >= RESTORE_SHARE > shares[f"0:{len(a_passes) - 1}"]
    again = out[0].passes[mid].paint_on
    assert rec["passes_painted_again"] == {f"0:{mid}": int(again.sum())}
    assert not np.any(again & ~p_mid.paint_on) and again.sum() > 0.5 * p_mid.paint_on.sum()
    assert not out[0].passes[-1].paint_on.any()
    a, eye = body.vertex_areas, [np.eye(4)] * 2
    after = _body_film(body, out, eye)
    assert 100 * _nsd(after, a) == pytest.approx(rec["nsd_after_pct"], rel=1e-9)
    assert rec["nsd_before_pct"] == pytest.approx(100 * _nsd(_body_film(body, start, eye), a))
    assert _nsd(after, a) < _nsd(_body_film(body, plain, eye), a)
    before = _body_film(body, start, eye)
    assert _nsd(after[interior], a[interior]) <= _nsd(before[interior], a[interior])


def test_refine_body_paints_again_in_the_part_frame_a_pass_the_blend_switched_off():
    """`booth_plans.refine_body` given the plans before the blend (`unblended`): the turned
    second panel's middle pass, switched off entirely as a seam's blending would, comes back
    in the part-frame plan it returns (paint on only where it painted before, more than half of
    it), the record names it, and the film re-measured from the returned plans is the
    recorded one and lower than without `unblended`."""
    from types import SimpleNamespace

    from paintcell.booth.booth_plans import refine_body, samples_off

    body, plans, Ts, _, panel = _turned_panels()
    mid = len(plans[1].passes) // 2
    p_mid = plans[1].passes[mid]
    b_passes = list(plans[1].passes)
    b_passes[mid] = dataclasses.replace(p_mid, paint_on=np.zeros_like(p_mid.paint_on))
    blended = [plans[0], dataclasses.replace(plans[1], passes=tuple(b_passes))]
    booth = SimpleNamespace(planner={}, parts=[SimpleNamespace(planner={}, part="p")] * 2)
    pp = SimpleNamespace(surfaces=[panel, panel], T_body_parts=Ts)
    plain, _ = refine_body(booth, pp, blended, body, None)
    out, rec = refine_body(booth, pp, blended, body, None, unblended=plans)
    again = out[1].passes[mid].paint_on
    assert rec["passes_painted_again"] == {f"1:{mid}": int(again.sum())}
    # what stays off: the pass switched off here less what came back (the seams record's count)
    assert samples_off(out, plans) == [0, int(p_mid.paint_on.sum() - again.sum())]
    assert not np.any(again & ~p_mid.paint_on) and again.sum() > 0.5 * p_mid.paint_on.sum()
    assert np.array_equal(out[1].passes[mid].positions, p_mid.positions)
    a = body.vertex_areas
    after = _body_film(body, out, Ts)
    assert 100 * _nsd(after, a) == pytest.approx(rec["nsd_after_pct"], rel=1e-9)
    assert _nsd(after, a) < _nsd(_body_film(body, plain, Ts), a)


def test_refine_body_weighs_its_most_uneven_part_and_keeps_only_a_better_fit():
    """`booth_plans.refine_body` on two turned panels, a pass of the first capped by its robot
    at 0.4 m/s (its film the more uneven): the worst part, its weight (its σ/μ over the
    body's) and every σ/μ of the record are the body films re-measured here, part by part,
    from the body fitted without the weight (`refine_together` alone) and from the plans
    returned; the weighted fit was kept because it lowered the worst part's σ/μ by more than
    it raised the body's."""
    from types import SimpleNamespace

    from paintcell.booth.booth_plans import SEAM_FIT_WEIGHT, refine_body
    from paintcell.booth.booth_seams import pass_in_body, seam_band
    from paintcell.coverage.film_refine import refine_together

    body, plans, Ts, counts, panel = _turned_panels()
    booth = SimpleNamespace(planner={}, parts=[SimpleNamespace(planner={}, part="a"),
                                               SimpleNamespace(planner={}, part="b")])
    pp = SimpleNamespace(surfaces=[panel, panel], T_body_parts=Ts)
    caps = [[None] * len(plans[0].passes), None]
    caps[0][2] = np.full(len(plans[0].passes[2].speeds_m_s), 0.4)
    out, rec = refine_body(booth, pp, plans, body, caps)
    worst = rec["worst_part"]
    a = body.vertex_areas
    offs = np.cumsum([0, *counts])

    def by_part(film):
        return [_nsd(film[offs[k]:offs[k + 1]], a[offs[k]:offs[k + 1]]) for k in range(2)]

    interior = ~seam_band(body.vertices, counts)
    moved = [dataclasses.replace(p, passes=tuple(pass_in_body(q, T) for q in p.passes))
             for p, T in zip(plans, Ts, strict=True)]
    first, _ = refine_together(body, moved, [PlannerSettings()] * 2, interior, caps,
                               edge_weight=SEAM_FIT_WEIGHT)
    eye = [np.eye(4)] * 2
    f0, f1 = _body_film(body, first, eye), _body_film(body, out, Ts)
    parts0, parts1 = by_part(f0), by_part(f1)
    assert worst["part"] == "0:a" and parts0[0] > parts0[1]
    assert 100 * parts0[0] == pytest.approx(worst["worst_nsd_before_pct"], rel=1e-9)
    assert 100 * _nsd(f0, a) == pytest.approx(worst["body_nsd_before_pct"], rel=1e-9)
    assert worst["weight"] == pytest.approx(parts0[0] / _nsd(f0, a), abs=1e-4)
    assert worst["applied"]
    assert 100 * max(parts1) == pytest.approx(worst["worst_nsd_after_pct"], rel=1e-9)
    assert 100 * _nsd(f1, a) == pytest.approx(worst["body_nsd_after_pct"], rel=1e-9)
    assert 0 < parts0[0] - max(parts1) and _nsd(f1, a) - _nsd(f0, a) < parts0[0] - max(parts1)
    assert 100 * _nsd(f1, a) == pytest.approx(rec["nsd_after_pct"], rel=1e-9)
