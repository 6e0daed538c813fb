"""paintcell.motion.time_law on a Cartesian robot (TCP = q), where every bound has a closed
form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from paintcell.motion.joint_trajectory import TrajectoryError
from paintcell.motion.time_law import JointPath, make_grid, parameterize_pass
from tests.helpers import FD_LIMIT_RTOL, SPEED_FOLLOW_RTOL

DT = 1e-3


def _fk(Q: np.ndarray) -> np.ndarray:
    return np.asarray(Q)[:, :3]


def _line(length: float = 1.0, m: int = 51, direction: tuple[float, ...] = (1.0, 0.0, 0.0)
          ) -> JointPath:
    d = np.asarray(direction) / np.linalg.norm(direction)
    s = np.linspace(0.0, length, m)
    return JointPath(s, s[:, None] * d)


def _arc(radius: float, angle: float, m: int = 81) -> JointPath:
    s = np.linspace(0.0, radius * angle, m)
    th = s / radius
    return JointPath(s, np.column_stack([radius * np.cos(th), radius * np.sin(th), 0 * th]))


def _sampled(law) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, law.duration_s, DT)
    s, sd, q, qd, qdd = law.joint_state(t)
    return t, sd, q


def test_follows_planned_speed_when_limits_are_loose() -> None:
    path = _line()
    v = np.full(51, 0.6)
    law = parameterize_pass(path, _fk, v, np.full(3, 5.0), np.full(3, 50.0), 24.0)
    assert law.duration_s == pytest.approx(1.0 / 0.6, rel=1e-6)
    _, sd, q = _sampled(law)
    speed = np.linalg.norm(np.diff(q, axis=0), axis=1) / DT
    np.testing.assert_allclose(speed, 0.6, rtol=SPEED_FOLLOW_RTOL)
    assert not law.sd_start_clipped and not law.sd_end_clipped


def test_joint_velocity_limit_binds_exactly() -> None:
    # Travel along (1, 1, 0)/√2: joint speeds are ṡ/√2, so ṡ ≤ √2 · 0.3.
    path = _line(direction=(1.0, 1.0, 0.0))
    law = parameterize_pass(path, _fk, np.full(51, 1.0), np.full(3, 0.3), np.full(3, 50.0), 24.0)
    assert np.max(law.sd_grid) == pytest.approx(np.sqrt(2) * 0.3, rel=1e-6)
    _, _, q = _sampled(law)
    assert np.all(np.abs(np.diff(q, axis=0)) / DT <= 0.3 * (1 + FD_LIMIT_RTOL))


def test_tcp_acceleration_on_an_arc() -> None:
    # Centripetal v²/R ≤ a: the inscribed 16-gon gives ṡ between √(a R cos(π/16)) and √(a R).
    radius, a_tcp = 0.2, 5.0
    path = _arc(radius, 2.0)
    law = parameterize_pass(path, _fk, np.full(81, 3.0), np.full(3, 50.0), np.full(3, 500.0),
                            a_tcp, grid_spacing_m=0.005)
    mid = law.sd_grid[len(law.sd_grid) // 2]
    assert np.sqrt(a_tcp * radius * np.cos(np.pi / 16)) * (1 - 1e-6) <= mid
    assert mid <= np.sqrt(a_tcp * radius) * (1 + 1e-6)
    _, _, q = _sampled(law)
    acc = np.linalg.norm(np.diff(q, 2, axis=0), axis=1) / DT**2
    assert acc.max() <= a_tcp * (1 + FD_LIMIT_RTOL)


def test_sampled_output_respects_acceleration_limits_on_a_curved_path() -> None:
    # A wiggly joint path: q'' varies between grid points, where TOPP-RA does not look; the
    # re-measurement must tighten the limits until the 1 kHz samples respect them.
    s = np.linspace(0.0, 1.0, 41)
    q = np.column_stack([s, 0.05 * np.sin(12 * s), 0.03 * np.cos(9 * s), 0.4 * np.sin(5 * s)])
    path = JointPath(s, q)
    a_lim = np.array([2.0, 2.0, 2.0, 3.0])
    law = parameterize_pass(path, _fk, np.full(41, 2.0), np.full(4, 3.0), a_lim, 50.0,
                            grid_spacing_m=0.05)
    t = np.arange(0.0, law.duration_s, DT)
    _, _, qs, _, qdd = law.joint_state(t)
    assert np.all(np.abs(qdd) <= a_lim * (1 + 1e-9))
    assert np.all(np.abs(np.diff(qs, 2, axis=0)) / DT**2 <= a_lim * (1 + FD_LIMIT_RTOL))


def test_boundary_speed_is_clipped_when_unreachable() -> None:
    # A very short pass cannot reach 2 m/s from the requested start of 0 under a = 1 m/s²;
    # the requested end speed is lowered and reported.
    path = _line(length=0.1, m=11)
    law = parameterize_pass(path, _fk, np.full(11, 2.0), np.full(3, 5.0), np.full(3, 1.0), 24.0,
                            sd_start_m_s=0.0)
    assert law.sd_end_clipped
    assert law.sd_grid[0] == 0.0
    # Within the 0.1 % step back from the feasibility edge
    # (paintcell.motion.time_law._reachable_end).
    assert law.sd_grid[-1] == pytest.approx(np.sqrt(2 * 1.0 * 0.1), rel=2e-3)


def test_grid_contains_every_knot() -> None:
    knots = np.array([0.0, 0.013, 0.05, 0.051])
    g = make_grid(knots, 0.01)
    assert np.all(np.isin(knots, g))
    assert np.max(np.diff(g)) <= 0.01 + 1e-12


def test_bad_inputs_raise() -> None:
    with pytest.raises(TrajectoryError, match="strictly increase"):
        JointPath([0.0, 0.0, 1.0], np.zeros((3, 3)))
    path = _line()
    with pytest.raises(TrajectoryError, match="planned speeds"):
        parameterize_pass(path, _fk, np.zeros(51), np.ones(3), np.ones(3), 1.0)
    with pytest.raises(TrajectoryError, match="joint limits"):
        parameterize_pass(path, _fk, np.ones(51), np.ones(2), np.ones(3), 1.0)


def test_a_pass_tightening_cannot_fix_gets_a_finer_grid(monkeypatch) -> None:
    """A real pass (tests/data: an IRB 5500 on a rail painting crs_cowling_creases' tongue band
    from its 10 mm plan, 49 knots over 0.67 m) whose joint path bends between the 10 mm grid
    points: tightening the limits six times leaves the 1 kHz samples 2.4 % over one. With the
    grid halvings the law exists, and its samples, re-measured by finite differences of q(t)
    and of the TCP's forward kinematics, keep every joint velocity and acceleration and the TCP
    acceleration within the limits."""
    from paintcell.motion import time_law
    from paintcell.robots.rail import RailSpec, load_rail_robot

    d = np.load(Path(__file__).parent / "data" / "time_law_coarse_grid_pass.npz")
    robot = load_rail_robot("irb5500", T_world_rail=d["T_world_rail"],
                            rail=RailSpec(lower_m=-0.6, upper_m=0.6))

    def fk(Q: np.ndarray) -> np.ndarray:
        return robot.fk_many(Q)[:, :3, 3]

    path = JointPath(d["s_knots_m"], d["q_knots"])
    args = (path, fk, d["v_knots_m_s"], d["v_max_rad_s"], d["a_max_rad_s2"],
            float(d["tcp_a_max_m_s2"]))
    monkeypatch.setattr(time_law, "GRID_HALVINGS", 0)
    with pytest.raises(TrajectoryError, match="still exceeds a limit"):
        parameterize_pass(*args, grid_spacing_m=0.01)
    monkeypatch.undo()
    law = parameterize_pass(*args, grid_spacing_m=0.01)
    assert len(law.s_grid) > len(make_grid(path.s_knots, 0.01))      # it did refine the grid
    t = np.arange(0.0, law.duration_s, DT)
    _, _, q, _, _ = law.joint_state(t)
    qd = np.diff(q, axis=0) / DT
    qdd = np.diff(q, 2, axis=0) / DT**2
    assert np.all(np.abs(qd) <= d["v_max_rad_s"] * (1 + FD_LIMIT_RTOL))
    assert np.all(np.abs(qdd) <= d["a_max_rad_s2"] * (1 + FD_LIMIT_RTOL))
    p = fk(q)
    a_tcp = np.linalg.norm(np.diff(p, 2, axis=0), axis=1) / DT**2
    assert a_tcp.max() <= float(d["tcp_a_max_m_s2"]) * (1 + FD_LIMIT_RTOL)
