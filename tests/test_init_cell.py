"""`paintcell init`'s robot choice (`paintcell.app.init_cell`): a pass no floor-standing
base reaches gets the next robot model that does — its joints re-measured by forward
kinematics — and a part no robot reaches is refused in one line with a fix."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from paintcell.app.init_cell import (
    AUTO_ROBOTS,
    BASES_VERIFIED,
    RAIL_VERIFIED,
    _place_rail,
    choose_cell,
)
from paintcell.core.errors import PaintcellError
from paintcell.robots import load_robot
from paintcell.robots.rail import solve_rail_paths


def _vertical_pass(z0_m: float, z1_m: float, y_m: float, n: int = 30) -> np.ndarray:
    """(n, 4, 4) T_world_tcp: a pass straight up at x = 1.2 m, the spray axis along +x."""
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = [0, 0, 1], [0, -1, 0], [1, 0, 0]
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = 1.2, y_m, np.linspace(z0_m, z1_m, n)
    return T


PART = np.array([[1.4, 0.0, 1.0]])


def test_a_pass_no_floor_base_reaches_gets_the_next_robot_that_does() -> None:
    # 2.4 m tall: beyond the IRB 4600-class arm's 2.05 m reach from any base of the grid
    paths = [_vertical_pass(0.6, 3.0, y) for y in (-0.2, 0.2)]
    cell = choose_cell(AUTO_ROBOTS, paths, [np.full(30, 0.5)] * 2, PART, "part.stl")
    assert cell.robot != "abb_paint"
    assert "abb_paint reaches no base" in cell.why and "\n" not in cell.why
    # independent truth: the chosen cell's joints put the TCP on every pose (FK round trip)
    robot = load_robot(cell.robot).placed(cell.T_base)
    if cell.robot.endswith("_rail"):
        qs = [r.q for r in solve_rail_paths(robot, paths)]
    else:
        from paintcell.robots.paths import solve_paths
        qs = [r.q for r in solve_paths(robot, paths)]
    for q, T in zip(qs, paths, strict=True):
        fk = robot.fk_many(q)
        assert np.max(np.linalg.norm(fk[:, :3, 3] - T[:, :3, 3], axis=1)) < 1e-4
        assert np.min(np.einsum("ij,ij->i", fk[:, :3, 2], T[:, :3, 2])) > np.cos(1e-3)


def test_a_part_no_robot_reaches_is_refused_in_one_line() -> None:
    paths = [_vertical_pass(0.3, 7.0, 0.0)]          # 6.7 m tall
    with pytest.raises(PaintcellError) as e:
        choose_cell(("abb_paint",), paths, [np.full(30, 0.5)], PART, "tower.stl")
    msg = str(e.value)
    assert "\n" not in msg and "tower.stl" in msg and "abb_paint reaches no base" in msg
    assert "--robot auto" in msg and "[base]" in msg
    # what works instead: a two-robot booth, pointing at a shipped scenario that is one
    named = re.search(r"(scenarios/\S+\.toml)", msg)
    assert named and "two-robot booth" in msg, msg
    text = (Path(__file__).resolve().parents[1] / named.group(1)).read_text()
    assert "[[parts]]" in text and "[parts.part]" in text and text.count("[[robots]]") == 2


SHORT = [_vertical_pass(0.9, 1.5, y, n=12) for y in (-0.2, 0.2)]   # every model reaches it
SPEEDS = [np.full(12, 0.5)] * 2


def test_a_robot_whose_program_fails_is_skipped_with_the_reason() -> None:
    """init's `verify` (the joint program as run builds it) failing the first robot: the next
    one is chosen, at its own base, and the reason is in the one line."""
    calls: list[tuple[str, np.ndarray]] = []

    def verify(name: str, T: np.ndarray) -> str | None:
        calls.append((name, T.copy()))
        return "a move between passes would leave the joint limits" if name == "abb_paint" \
            else None

    cell = choose_cell(("abb_paint", "irb5500"), SHORT, SPEEDS, PART, "part.stl", verify=verify)
    names = [c[0] for c in calls]
    # abb_paint: its best base, then the next ones of the motion ranking (at most
    # BASES_VERIFIED, each a different base), then the next robot
    assert names[-1] == "irb5500" and set(names[:-1]) == {"abb_paint"}
    assert 1 < len(names) - 1 <= BASES_VERIFIED
    assert len({c[1].tobytes() for c in calls[:-1]}) == len(names) - 1
    assert cell.robot == "irb5500" and np.array_equal(cell.T_base, calls[-1][1])
    assert "abb_paint reaches every pose but a move between passes would leave the joint " \
           "limits" in cell.why and "\n" not in cell.why
    # and the line says why each of the next bases failed too: one reason per base verified
    assert "(the next " in cell.why
    assert cell.why.count("a move between passes") == len(names) - 1


def test_a_base_whose_program_fails_gives_way_to_the_next_base() -> None:
    """The best-ranked base's program fails: the next base of the ranking, whose program
    passes, is chosen — a feasible base (its joints re-measured by FK) — and the line says
    why the best one was not."""
    from paintcell.robots.paths import solve_paths

    calls: list[np.ndarray] = []

    def verify(name: str, T: np.ndarray) -> str | None:
        calls.append(T.copy())
        return "its program meets the part (flange 5 mm deep at t = 9.0 s)" \
            if len(calls) == 1 else None

    cell = choose_cell(("abb_paint",), SHORT, SPEEDS, PART, "part.stl", verify=verify)
    assert cell.robot == "abb_paint" and len(calls) == 2
    assert not np.array_equal(calls[0], calls[1]) and np.array_equal(cell.T_base, calls[1])
    assert "(the best-ranked base's program: its program meets the part" in cell.verdict
    p = cell.T_base[:3, 3]
    assert f"chosen base at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m" in cell.verdict
    robot = load_robot("abb_paint").placed(cell.T_base)
    for r, T in zip(solve_paths(robot, SHORT), SHORT, strict=True):
        fk = robot.fk_many(r.q)
        assert np.max(np.linalg.norm(fk[:, :3, 3] - T[:, :3, 3], axis=1)) < 1e-4


def test_rail_frames_are_checked_in_turn_then_refused_in_one_line() -> None:
    """The rail: a frame whose program fails gives way to the next checked frame; when all
    `RAIL_VERIFIED` checked frames fail, one line says so, and the frame returned is the one the
    line names."""
    calls: list[np.ndarray] = []

    def fail_first(name: str, T: np.ndarray) -> str | None:
        calls.append(T.copy())
        return "its moves leave the joint limits" if len(calls) == 1 else None

    cell = choose_cell(("irb5500_rail",), SHORT, SPEEDS, PART, "part.stl", verify=fail_first)
    assert len(calls) == 2 and not np.array_equal(calls[0], calls[1])
    assert np.array_equal(cell.T_base, calls[1])
    x, z = cell.T_base[0, 3], cell.T_base[2, 3]
    assert cell.verdict.startswith("rail found")
    assert f"rail at x {x:.2f} m, height {z:.2f} m" in cell.verdict

    calls.clear()
    robot = load_robot("irb5500_rail")
    T, ok, line = _place_rail(robot, SHORT, lambda T: calls.append(T.copy()) or "no paint left")
    assert not ok and len(calls) == RAIL_VERIFIED                  # then it gives up
    assert np.array_equal(T, calls[0]) and "\n" not in line
    assert line.startswith("rail frames: ") and f"{RAIL_VERIFIED} of the {RAIL_VERIFIED} checked" \
        in line and f"rail at x {T[0, 3]:.2f} m, height {T[2, 3]:.2f} m: no paint left" in line
    with pytest.raises(PaintcellError) as e:                       # as init says it
        choose_cell(("irb5500_rail",), SHORT, SPEEDS, PART, "part.stl",
                    verify=lambda n, T: "no paint left")
    msg = str(e.value)
    assert "\n" not in msg and "irb5500_rail rail frames: " in msg and "no paint left" in msg
