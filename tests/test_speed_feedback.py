"""Robot-aware speeds (paintcell.motion.speed_caps, paintcell.motion.speed_feedback): caps
measured from a joint program's TCP speeds, mapped onto the plan's samples in each pass's
generation direction, and obeyed by the re-plan."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.motion.speed_caps import SLOW_REL, achieved_speeds, speed_caps, tool_axes
from paintcell.motion.speed_feedback import with_targets
from paintcell.paint.applicator import Applicator
from paintcell.surface import parts
from tests.helpers import stand_in_program

APP = Applicator.default()
ST = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=8, film_guard=False)


def _program(plan, slow: dict[int, tuple[float, float, float]], dt: float = 0.002):
    """A stand-in joint program of the whole plan (`tests.helpers.stand_in_program`)."""
    return stand_in_program(plan.passes, slow, dt=dt)


def test_caps_follow_the_slowdown_in_generation_direction_and_the_replan_obeys_them() -> None:
    s = parts.panel(0.04)
    plan = plan_coverage(s, APP, ST)
    # an unslowed program reaches the plan's speeds: no caps
    free = _program(plan, {})
    for p, v in zip(plan.passes, achieved_speeds(plan, free), strict=True):
        np.testing.assert_allclose(v, p.speeds_m_s, rtol=1e-2)   # one-sided ds/dt at the ends
    caps, n_new, _ = speed_caps(plan, free)
    assert caps == {} and n_new == 0
    # pass 1 (run reversed) slowed to 70 % over 0.3-0.5 m of its executed arc
    prog = _program(plan, {1: (0.3, 0.5, 0.7)})
    caps, n_new, worst = speed_caps(plan, prog)
    assert set(caps) == {plan.passes[1].side} and n_new > 0
    assert 25.0 <= worst <= 31.0
    p = plan.passes[1]
    cap_exec = caps[p.side][::-1]                       # back to execution order
    s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                             axis=1))])
    inside = (s_plan > 0.34) & (s_plan < 0.46)
    assert np.all(cap_exec[inside] < 0.75 * p.speeds_m_s[inside])
    outside = (s_plan < 0.2) | (s_plan > 0.6)
    assert np.all(np.isinf(cap_exec[outside]))
    assert SLOW_REL < 0.3
    # the re-plan keeps the geometry and meets the caps at every sample
    finite = {k: np.where(np.isfinite(v), v, ST.v_max_m_s) for k, v in caps.items()}
    again = plan_coverage(s, APP, ST, speed_caps_m_s=finite)
    q = again.passes[1]
    np.testing.assert_allclose(q.positions, p.positions)
    assert np.all(q.speeds_m_s <= finite[p.side][::-1] * (1 + 1e-6))
    # caps that do not fit the plan are refused with the reason
    try:
        plan_coverage(s, APP, replace(ST, sample_spacing_m=0.05), speed_caps_m_s=finite)
    except Exception as e:  # noqa: BLE001 - the planner's PlanError
        assert "do not fit" in str(e)
    else:
        raise AssertionError("caps of another plan were accepted")


def test_fed_back_bell_axes_follow_a_spin_past_90_degrees_without_a_half_turn() -> None:
    # a free-spin program that turns the bell steadily to 150° off the travel along every pass
    # (the roof's robot turns it to ~90-146°): the fed-back x axes are the program's own, sign
    # and all — a sample-wise "nearest the travel" sign flips them by 180° at 90°
    s = parts.panel(0.04)
    plan = plan_coverage(s, APP, ST)
    prog = _program(plan, {})
    rot = np.empty((len(prog.t_s), 3, 3))
    want = {}
    for i, p in enumerate(plan.passes):
        idx = np.flatnonzero(prog.pass_index == i)
        frac = prog.s_pass_m[idx] / prog.s_pass_m[idx].max()
        th = np.radians(150.0) * frac
        z = p.spray_axes[0]
        t0 = p.travel_dirs[0]
        x = np.cos(th)[:, None] * t0 + np.sin(th)[:, None] * np.cross(z, t0)
        rot[idx] = np.stack([x, np.cross(z, x), np.broadcast_to(z, x.shape)], axis=2)
        s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                                 axis=1))])
        th_p = np.radians(150.0) * s_plan / s_plan[-1]
        want[i] = np.cos(th_p)[:, None] * t0 + np.sin(th_p)[:, None] * np.cross(z, t0)
    prog.tcp_rot_world = rot
    got = tool_axes(plan, prog, np.eye(4))
    for i, p in enumerate(plan.passes):
        x = got[p.side][::-1] * -1 if i % 2 == 1 else got[p.side]     # execution order
        assert np.all(np.einsum("ij,ij->i", x[1:], x[:-1]) > 0.9)      # no half turn
        np.testing.assert_allclose(x, want[i], atol=2e-3)
    # the spin-fed plan keeps its own x axes for the film; its program gets the first targets
    again = plan_coverage(s, APP, ST, tool_x=got)
    motion = with_targets(again, plan)
    for a, m, p in zip(again.passes, motion.passes, plan.passes, strict=True):
        np.testing.assert_array_equal(m.travel_dirs, p.travel_dirs)
        np.testing.assert_array_equal(m.speeds_m_s, a.speeds_m_s)
        np.testing.assert_array_equal(m.positions, a.positions)


def _fastest_program(s_plan: np.ndarray, v_plan: np.ndarray, a_m_s2: np.ndarray,
                     s_fine: np.ndarray, dt: float = 1e-3):
    """Independent truth for a robot along a straight pass: the fastest motion with the speed
    under the plan's (v² linear in arc length between samples) and |dv/dt| ≤ a_m_s2 (given on
    s_fine [m]), by the forward / backward sweeps of x = v² (x' = 2a), sampled at 1 kHz."""
    from types import SimpleNamespace

    x = np.interp(s_fine, s_plan, v_plan**2)
    ds = np.diff(s_fine)
    for k in range(len(ds)):                       # accelerate as hard as allowed
        x[k + 1] = min(x[k + 1], x[k] + 2 * a_m_s2[k] * ds[k])
    for k in range(len(ds) - 1, -1, -1):           # brake in time
        x[k] = min(x[k], x[k + 1] + 2 * a_m_s2[k] * ds[k])
    v = np.sqrt(x)
    t = np.concatenate([[0.0], np.cumsum(2 * ds / (v[1:] + v[:-1]))])
    tq = np.arange(0.0, t[-1], dt)
    s = np.interp(tq, t, s_fine)
    return SimpleNamespace(t_s=tq, s_pass_m=s, pass_index=np.zeros(len(tq), np.int64),
                           tcp_pos_world=np.stack([s, 0 * s, 0 * s], axis=1),
                           v_tcp_planned=np.sqrt(np.interp(s, s_plan, v_plan**2)), meta={})


def test_a_lag_between_samples_is_capped_until_the_program_follows_the_plan() -> None:
    """A plan that climbs steeply out of a slow sample (0.15 → 0.3 m/s over 2 cm: 1.7 m/s²)
    while the robot, its acceleration taken over the first 8 mm (0.2 m/s², then 3 m/s²), meets
    the plan at every sample but lags 28 % between two of them (cad_fender's pass 3 at
    s = 1.145 m). Re-planned under the fed-back caps (each sample's speed at most its cap),
    the re-measured 1 kHz speeds are within 10 % of the plan (the honest-reach window): the
    caps at the samples alone found nothing to cap."""
    from types import SimpleNamespace

    s_plan = np.arange(31) * 0.02
    v = np.full(31, 0.3)
    v[15] = 0.15
    s_fine = np.linspace(0.0, s_plan[-1], 12001)
    a = np.where((s_fine >= s_plan[15]) & (s_fine < s_plan[15] + 0.008), 0.2, 3.0)[:-1]
    p = SimpleNamespace(side=0, positions=np.stack([s_plan, 0 * s_plan, 0 * s_plan], axis=1),
                        speeds_m_s=v)
    plan = SimpleNamespace(passes=(p,))

    def ratio(prog) -> np.ndarray:
        v_a = np.linalg.norm(np.gradient(prog.tcp_pos_world, prog.t_s, axis=0), axis=1)
        return v_a[1:-1] / prog.v_tcp_planned[1:-1]

    prog = _fastest_program(s_plan, v, a, s_fine)
    assert ratio(prog).min() < 0.75                          # the lag, between samples
    np.testing.assert_allclose(achieved_speeds(plan, prog)[0], v, rtol=0.01)   # samples met
    t0, caps = prog.t_s[-1], {}
    for _ in range(3):
        caps, n_new, _ = speed_caps(plan, prog, caps)
        if n_new == 0:
            break
        p.speeds_m_s = np.minimum(v, caps[0])
        prog = _fastest_program(s_plan, p.speeds_m_s, a, s_fine)
    assert ratio(prog).min() >= 0.9
    assert np.all(np.isinf(caps[0][:15])) and np.all(np.isinf(caps[0][18:]))   # only there
    assert prog.t_s[-1] < 1.05 * t0
