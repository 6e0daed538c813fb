"""paintcell.output.plots: every figure is a non-blank PNG; bad inputs raise PlotError."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from paintcell.output import plots
from paintcell.surface.analytic import plane
from tests.helpers import RENDER_MIN_PIXEL_STD


def _check_png(path) -> np.ndarray:
    assert path.exists() and path.stat().st_size > 0
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.shape[0] > 100 and img.shape[1] > 100
    assert img.reshape(-1, 3).std(0).max() > RENDER_MIN_PIXEL_STD
    return img


def _program(seed: int = 0):
    """Two straight 0.6 m passes at 0.4 m/s with a turn-around, sampled at 1 kHz; the 'executed'
    trace lags the command by a small noisy offset."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0, 0.001)
    x = np.where(t < 1.5, 0.4 * t, np.where(t < 2.5, 0.6, 0.6 - 0.4 * (t - 2.5)))
    y = np.where(t < 1.5, 0.0, np.where(t < 2.5, 0.2 * (t - 1.5), 0.2))
    pos = np.column_stack([x, y, np.full_like(t, 1.0)])
    pidx = np.where(t < 1.5, 0, np.where(t < 2.5, -1, 1))
    s = np.where(pidx == 0, x, np.where(pidx == 1, 0.6 - x, np.nan))
    q = np.column_stack([np.sin(t + k) for k in range(6)])
    traj = SimpleNamespace(t_s=t, tcp_pos_world=pos, v_tcp_planned=np.where(pidx >= 0, 0.4, 0.0),
                           pass_index=pidx, s_pass_m=s, q=q, qd=np.gradient(q, t, axis=0),
                           joint_names=tuple(f"j{k + 1}" for k in range(6)), robot_name="x")
    pos_exe = pos + 1e-4 * rng.standard_normal(pos.shape).cumsum(0) / 30
    trace = SimpleNamespace(t_s=t, tcp_pos_world=pos_exe, pass_index=pidx, paint_on=pidx >= 0,
                            q=q + 1e-3, qd=traj.qd)
    return traj, trace


def test_thickness_maps_with_uv(tmp_path):
    s = plane(0.6, 0.4, resolution_m=0.05)
    planned = 20e-6 + 5e-6 * np.cos(8 * s.vertices[:, 0])
    executed = planned * (1 + 0.1 * s.vertices[:, 1])
    p = plots.plot_thickness_maps(tmp_path / "t.png", s, planned, executed)
    _check_png(p)
    assert not list(tmp_path.glob(".*"))  # atomic: no temp file left behind


def test_thickness_maps_without_uv_use_best_fit_plane(tmp_path):
    s = plane(0.6, 0.4, resolution_m=0.05)
    R = np.array([[1, 0, 0], [0, 0.6, -0.8], [0, 0.8, 0.6]])  # tilted plane, no uv
    tilted = SimpleNamespace(vertices=s.vertices @ R.T, faces=s.faces, uv=None,
                             vertex_areas=s.vertex_areas)
    flat, names = plots.unfold(tilted)
    # projecting a plane on its best-fit plane is an isometry: every distance is kept
    d3 = np.linalg.norm(tilted.vertices[:, None] - tilted.vertices[None], axis=2)
    d2 = np.linalg.norm(flat[:, None] - flat[None], axis=2)
    assert np.allclose(d2, d3, atol=1e-9)
    assert "plane" in names[0]
    p = plots.plot_thickness_maps(tmp_path / "t.png", tilted, np.linspace(1e-5, 3e-5,
                                                                          len(s.vertices)))
    _check_png(p)


def test_thickness_range_is_shared_and_never_empty():
    lo, hi = plots.thickness_range_um([10e-6, 20e-6], [30e-6, np.nan], lo_pct=0, hi_pct=100)
    assert (lo, hi) == pytest.approx((10.0, 30.0))
    lo, hi = plots.thickness_range_um(np.full(5, 1e-5))
    assert hi > lo


def test_speed_tracking_and_joint_plots(tmp_path):
    traj, trace = _program()
    _check_png(plots.plot_tcp_speed(tmp_path / "v.png", traj, trace))
    _check_png(plots.plot_tcp_speed(tmp_path / "v2.png", traj, None))
    t, err = plots.tracking_error_m(traj, trace)
    assert np.allclose(err, np.linalg.norm(trace.tcp_pos_world - traj.tcp_pos_world, axis=1))
    _check_png(plots.plot_tracking_error(tmp_path / "e.png", traj, trace))
    lim = np.full(6, 1.2)
    _check_png(plots.plot_joints(tmp_path / "q.png", trace.t_s, trace.q, trace.qd, -lim, lim,
                                 np.full(6, 2.0), traj.joint_names, traj.t_s, traj.q))


def test_index_width_curve(tmp_path):
    w = np.linspace(0.1, 0.8, 15)
    nsd = 0.02 + 0.5 * (w - 0.5) ** 2
    _check_png(plots.plot_index_width_curve(tmp_path / "w.png", w, nsd, 0.45, "bell"))
    with pytest.raises(plots.PlotError, match="equal length"):
        plots.plot_index_width_curve(tmp_path / "x.png", w, nsd[:-1])


def test_bad_inputs_raise(tmp_path):
    s = plane(0.6, 0.4, resolution_m=0.05)
    with pytest.raises(plots.PlotError, match="vertices"):
        plots.plot_thickness_maps(tmp_path / "t.png", s, np.zeros(3))
    traj, trace = _program()
    traj.pass_index = np.full_like(traj.pass_index, -1)
    with pytest.raises(plots.PlotError, match="no paint pass"):
        plots.plot_tcp_speed(tmp_path / "v.png", traj, trace)
    with pytest.raises(plots.PlotError, match="disagree"):
        plots.plot_joints(tmp_path / "q.png", trace.t_s, trace.q, trace.qd, np.zeros(5),
                          np.ones(5), np.ones(5))
