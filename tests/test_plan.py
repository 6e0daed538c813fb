"""PassPlan validation and CoveragePlan persistence: inputs converted and checked, a corrupt or
mismatched JSON/npz pair refused with a PlanError naming the file."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from paintcell.core.errors import PlanError
from paintcell.coverage.plan import TIMING_RTOL, CoveragePlan, PassPlan, times_from_speeds
from paintcell.paint.applicator import Applicator

M = 6


def _arrays(v: float = 0.5) -> dict:
    pos = np.c_[np.linspace(0.0, 0.5, M), np.zeros(M), np.full(M, 0.25)]
    speeds = np.linspace(v, 1.5 * v, M)
    return dict(positions=pos, spray_axes=np.tile([0.0, 0.0, -1.0], (M, 1)),
                travel_dirs=np.tile([1.0, 0.0, 0.0], (M, 1)), speeds_m_s=speeds,
                times_s=times_from_speeds(pos, speeds), on_part=np.ones(M, bool),
                paint_on=np.ones(M, bool))


def _plan(v: float = 0.5) -> CoveragePlan:
    return CoveragePlan(surface_name="strip", applicator=Applicator.default(),
                        passes=(PassPlan(**_arrays(v)), PassPlan(**_arrays(v), side=1)))


def test_lists_are_converted() -> None:
    p = PassPlan(**{k: v.tolist() for k, v in _arrays().items()})
    assert isinstance(p.positions, np.ndarray) and p.positions.shape == (M, 3)
    assert p.on_part.dtype == bool and p.duration_s > 0 and p.length_m == pytest.approx(0.5)


@pytest.mark.parametrize("name,value,match", [
    ("positions", np.zeros((M, 2)), r"shape \(M, 3\)"),
    ("spray_axes", np.zeros((M - 1, 3)), r"spray_axes has shape \(5, 3\), expected \(6, 3\)"),
    ("speeds_m_s", np.ones((M, 1)), r"speeds_m_s has shape \(6, 1\), expected \(6,\)"),
    ("on_part", np.ones(M), "must be bool"),
    ("spray_axes", np.tile([0.0, 0.0, -2.0], (M, 1)), "spray_axes must be unit vectors"),
    ("travel_dirs", np.tile([0.0, 0.6, -0.8], (M, 1)), "orthogonal to spray_axes"),
    ("times_s", np.arange(M, dtype=float), "times_s and speeds_m_s disagree"),
])
def test_bad_pass_arrays_raise(name: str, value: np.ndarray, match: str) -> None:
    kw = _arrays()
    kw[name] = value
    with pytest.raises(PlanError, match=match):
        PassPlan(**kw)


def test_timing_definition_is_checked_to_its_tolerance() -> None:
    p = PassPlan(**_arrays())
    replace(p, times_s=p.times_s * (1 + 0.5 * TIMING_RTOL))       # within the tolerance
    with pytest.raises(PlanError, match="disagree"):
        replace(p, times_s=p.times_s * (1 + 2 * TIMING_RTOL))


def test_round_trip_is_exact_and_hash_is_stored(tmp_path) -> None:
    plan = _plan()
    plan.save(tmp_path / "plan.json")
    meta = json.loads((tmp_path / "plan.json").read_text())
    assert len(meta["arrays_sha256"]) == 16
    back = CoveragePlan.load(tmp_path / "plan.json")
    for a, b in zip(plan.passes, back.passes, strict=True):
        for name in ("positions", "spray_axes", "travel_dirs", "speeds_m_s", "times_s",
                     "on_part", "paint_on"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def _expect(path, match: str) -> None:
    with pytest.raises(PlanError, match=match) as info:
        CoveragePlan.load(path)
    msg = str(info.value)
    assert str(path) in msg and "\n" not in msg


def test_truncated_json_raises_plan_error(tmp_path) -> None:
    _plan().save(tmp_path / "plan.json")
    text = (tmp_path / "plan.json").read_text()
    (tmp_path / "plan.json").write_text(text[: len(text) // 2])
    _expect(tmp_path / "plan.json", "not valid JSON.*re-run `paintcell plan`")


def test_mismatched_json_npz_pair_raises_plan_error(tmp_path) -> None:
    # the npz of another plan with the same layout: only the content hash tells them apart
    _plan(0.5).save(tmp_path / "a" / "plan.json")
    _plan(0.6).save(tmp_path / "b" / "plan.json")
    (tmp_path / "a" / "plan.npz").write_bytes((tmp_path / "b" / "plan.npz").read_bytes())
    _expect(tmp_path / "a" / "plan.json", "do not match.*re-run `paintcell plan`")
    # an npz with fewer passes than the JSON lists (KeyError before)
    one = CoveragePlan(surface_name="strip", applicator=Applicator.default(),
                       passes=(PassPlan(**_arrays()),))
    one.save(tmp_path / "c" / "plan.json")
    meta = json.loads((tmp_path / "a" / "plan.json").read_text())
    del meta["arrays_sha256"]
    (tmp_path / "c" / "plan.json").write_text(json.dumps(meta))
    _expect(tmp_path / "c" / "plan.json", "KeyError.*re-run `paintcell plan`")


def test_corrupt_npz_raises_plan_error(tmp_path) -> None:
    _plan().save(tmp_path / "plan.json")
    (tmp_path / "plan.npz").write_bytes(b"PK\x03\x04 not a zip")
    _expect(tmp_path / "plan.json", "re-run `paintcell plan`")


def _pass_through(points: np.ndarray) -> PassPlan:
    """A pass at 0.4 m/s along `points` (M, 3) [m], the spray axis straight down."""
    d = np.gradient(points, axis=0)
    d[:, 2] = 0.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    m = len(points)
    v = np.full(m, 0.4)
    return PassPlan(points, np.tile([0.0, 0.0, -1.0], (m, 1)), d, v,
                    times_from_speeds(points, v), np.ones(m, bool), np.ones(m, bool))


def test_worst_turn_of_a_pass_against_closed_forms(tmp_path) -> None:
    # an arc of radius R sampled every dθ: consecutive chords turn by exactly dθ
    R, dth = 0.5, np.radians(3.0)
    th = np.arange(0, 40) * dth
    arc = _pass_through(np.c_[R * np.cos(th), R * np.sin(th), np.zeros_like(th)])
    assert arc.max_turn_deg == pytest.approx(3.0, abs=1e-9)
    # a straight run, a 90° corner and a straight run: 90° at the corner, nowhere more
    x = np.r_[np.linspace(0, 0.2, 11), np.full(10, 0.2)]
    y = np.r_[np.zeros(11), np.linspace(0.02, 0.2, 10)]
    corner = _pass_through(np.c_[x, y, np.zeros_like(x)])
    assert corner.max_turn_deg == pytest.approx(90.0, abs=1e-9)
    plan = replace(_plan(), passes=(arc, corner))
    plan.save(tmp_path / "plan.json")
    meta = json.loads((tmp_path / "plan.json").read_text())
    assert [p["max_turn_deg"] for p in meta["passes"]] == pytest.approx([3.0, 90.0], abs=1e-9)
