"""The memory the process may use (cgroup, RLIMIT_AS, the cap), the budgets built on it, the
scheduler probe, and the robots a booth script may name — each against figures computed here
from first principles (a cgroup tree written by the test, the arrays' sizes multiplied out, a
real Dask scheduler's handshake)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from paintcell.booth.booth import BoothRobot
from paintcell.booth.booth_checks import ARM_JOINTS, RAIL_ARMS, BoothDataError
from paintcell.core import memory
from paintcell.core.budget import check_planner_budget, planner_bytes
from paintcell.core.memory import BudgetError, memory_cap_bytes
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.index_width import search_range, search_size, search_widths
from paintcell.surface.mesh_thinning import cluster_vertices


@pytest.mark.parametrize("raw", ["0", "-1", "inf", "nan", "1e400", "lots", "0x10"])
def test_a_memory_cap_that_is_no_positive_number_is_refused(raw: str) -> None:
    with pytest.raises(BudgetError, match="PAINTCELL_MAX_MEMORY_GB = .* must be a number of GB"):
        memory_cap_bytes(raw)


def test_a_memory_cap_in_gb() -> None:
    assert memory_cap_bytes("2") == 2 * 2**30
    assert memory_cap_bytes("0.5") == 2**29
    assert memory_cap_bytes("") is None


def _tree(tmp: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp / rel).write_text(text)
    return tmp


def test_cgroup_v2_room_is_the_tightest_limit_less_usage_up_the_tree(tmp_path: Path) -> None:
    root = _tree(tmp_path / "cg", {
        "memory.max": "max\n",
        "box/memory.max": str(8 * 2**30), "box/memory.current": str(3 * 2**30),
        "box/job/memory.max": str(6 * 2**30), "box/job/memory.current": str(2 * 2**30)})
    proc = _tree(tmp_path, {"self_cgroup": "0::/box/job\n"}) / "self_cgroup"
    room, where = memory._cgroup_room(root, proc)
    assert room == 4 * 2**30 and where.endswith("box/job/memory.max")   # min(6-2, 8-3)
    (root / "box/memory.current").write_text(str(7 * 2**30))
    room, where = memory._cgroup_room(root, proc)
    assert room == 2**30 and where.endswith("box/memory.max")


def test_cgroup_v1_room_and_no_limit(tmp_path: Path) -> None:
    root = _tree(tmp_path / "cg", {"memory/memory.limit_in_bytes": str(5 * 2**30),
                                   "memory/memory.usage_in_bytes": str(2**30)})
    proc = _tree(tmp_path, {"self_cgroup": "4:memory:/docker/abc\n0::/\n"}) / "self_cgroup"
    assert memory._cgroup_room(root, proc)[0] == 4 * 2**30
    (root / "memory/memory.limit_in_bytes").write_text("9223372036854771712")
    assert memory._cgroup_room(root, proc) is None


def test_the_room_is_the_least_of_its_bounds(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(memory, "_cgroup_room", lambda: (3 * 2**30, "cgroup memory.max"))
    monkeypatch.setattr(memory, "_rlimit_room", lambda: (5 * 2**30, "RLIMIT_AS (ulimit -v)"))
    monkeypatch.setenv("PAINTCELL_MAX_MEMORY_GB", "4")
    assert memory.memory_room() == (3 * 2**30, "cgroup memory.max")
    monkeypatch.setenv("PAINTCELL_MAX_MEMORY_GB", "1")
    assert memory.memory_room() == (2**30, "PAINTCELL_MAX_MEMORY_GB")
    assert "(PAINTCELL_MAX_MEMORY_GB)" in memory.room_text()


def test_the_planner_estimate_is_the_width_search_arrays(monkeypatch: pytest.MonkeyPatch) -> None:
    """The estimate multiplies out the sides `search_widths` allocates: run it and compare
    with the float64 arrays it builds (measured by tracing numpy's allocations)."""
    import tracemalloc

    st = PlannerSettings(w_min_m=0.1, w_max_m=0.3, w_res_m=0.01, n_future=3, future_grid_n=4,
                         profile_spacing_m=0.002)
    widths = search_range(st.w_min_m, st.w_max_m, st.w_res_m)
    point_s = np.arange(-st.w_max_m, st.w_max_m + 1e-9, st.profile_spacing_m)
    g0 = int(np.ceil((st.w_max_m + 0.3 + st.w_res_m) / st.w_res_m))
    film = np.ones((2 * g0 + 1, len(point_s)))
    fut = widths[np.rint(np.linspace(0, len(widths) - 1, st.future_grid_n)).astype(int)]
    tracemalloc.start()
    search_widths(film, st.w_res_m, g0, point_s, [], widths, np.unique(fut), st.n_future, None)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    est = planner_bytes(search_size(st, 0.3))
    assert film.nbytes < est and 0.5 * peak < est < 4 * peak, (peak, est)


def test_a_width_search_past_the_room_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PAINTCELL_MAX_MEMORY_GB", "0.01")
    with pytest.raises(BudgetError, match=r"door.toml \[planner\]: the index-width search needs"):
        check_planner_budget(search_size(PlannerSettings()), "door.toml [planner]")
    monkeypatch.delenv("PAINTCELL_MAX_MEMORY_GB")
    assert check_planner_budget(search_size(PlannerSettings()), "door.toml [planner]") < 2**30


def test_clustering_merges_cells_and_keeps_the_outline() -> None:
    """A 40 × 40 grid of unit squares clustered at 4 units keeps its outline exactly (boundary
    vertices cluster among themselves: the mean of outline points on a straight side stays on
    it) and has about (40/4)² · 2 faces inside."""
    n = 40
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1)
                        .reshape(-1, 3)])
    tv, tf = cluster_vertices(v, f, 4.0)
    assert np.allclose(tv.min(axis=0)[:2], 0.0) and np.allclose(tv.max(axis=0)[:2], n)
    area = 0.5 * np.abs(np.cross(tv[tf[:, 1]] - tv[tf[:, 0]], tv[tf[:, 2]] - tv[tf[:, 0]])[:, 2])
    assert abs(area.sum() - n * n) < 0.06 * n * n
    assert 2 * (n // 4) ** 2 <= len(tf) < 4 * 2 * (n // 4) ** 2


def test_a_booth_script_names_only_known_robots() -> None:
    with pytest.raises(Exception, match="model 'irb9999' is not a known robot"):
        BoothRobot("a", "irb9999")
    with pytest.raises(Exception, match=r"rail_m = \(2.0, -1.0\) must be"):
        BoothRobot("a", "irb5500_rail", rail_m=(2.0, -1.0))
    assert BoothRobot("a", "irb5500_rail", rail_m=(-1.0, 2.0)).rail_m == (-1.0, 2.0)
    assert issubclass(BoothDataError, Exception)


@pytest.mark.parametrize("model", sorted(ARM_JOINTS))
def test_the_joint_counts_the_loader_checks_are_the_models(model: str) -> None:
    from paintcell.robots import load_robot

    assert load_robot(model).nq == ARM_JOINTS[model]
    if model in RAIL_ARMS:
        assert load_robot(f"{model}_rail").nq == ARM_JOINTS[model] + 1


def test_the_probe_accepts_a_real_scheduler() -> None:
    from distributed import LocalCluster

    from paintcell.sweeps.scheduler_probe import probe_scheduler

    with LocalCluster(n_workers=0, processes=True, dashboard_address=None,
                      scheduler_kwargs={"protocol": "tcp"}) as cluster:
        probe_scheduler(cluster.scheduler_address)


def test_ranges_hold_every_default() -> None:
    """Every settings class's defaults lie in the ranges the loader enforces."""
    from dataclasses import fields

    from paintcell.core.setting_ranges import check_range
    from paintcell.validation.settings_tables import settings_classes

    for table, cls in settings_classes().items():
        for f in fields(cls):
            if f.default is not None and not callable(f.default) and \
                    not isinstance(f.default, str) and not (isinstance(f.default, float)
                                                            and math.isinf(f.default)):
                assert check_range(table, f.name, f.default) is None, (table, f.name)
