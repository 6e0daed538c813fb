"""Fuzz of the scenario and booth loaders: values, types, ranges, structures, nesting, encodings.

Every case writes a TOML file and asserts what `tests/fuzz/fuzz_cases.py` states: the loader
returns or refuses in one line naming the file (never another exception); a value out of its
documented range (`paintcell.core.setting_ranges`) is refused, naming the key; through the real
`paintcell` command the refusal exits 2 with one stderr line and writes no results folder.
Generators are seeded, so every run tries the same cases.
"""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import pytest
import tomli_w

from paintcell.app.scenario_files import load_scenario
from paintcell.core.setting_ranges import INF_ALLOWED, RANGES
from tests.fuzz.fuzz_cases import cli_refusal, loader_outcome

BASE: dict[str, Any] = {
    "name": "fz", "part": "panel", "robot": "abb_paint",
    "part_placement": {"xyz_m": [1.2, 0.0, 0.8], "rpy_rad": [1.5707963, 0.0, -1.5707963]},
}
BOOTH: dict[str, Any] = {
    "name": "fzb", "conveyor": {"speed_m_s": 0.0},
    "parts": [{"part": "panel", "xyz_m": [0.0, 0.0, 1.0]},
              {"part": "door", "xyz_m": [1.2, 0.0, 1.0]}],
    "robots": [{"name": "a", "model": "irb5500", "rail": [-1.0, 1.0],
                "base": {"xyz_m": [0.0, -2.0, 0.0]}},
               {"name": "b", "model": "irb5500", "base": {"xyz_m": [1.2, -2.0, 0.0]}}],
}


def _write(tmp: Path, d: dict[str, Any], name: str = "case.toml") -> Path:
    p = tmp / name
    p.write_bytes(tomli_w.dumps(d).encode())
    return p


def _with(base: dict[str, Any], path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    """A deep copy of `base` with the key at `path` set to `value` (tables made on the way)."""
    import copy

    d = copy.deepcopy(base)
    node = d
    for k in path[:-1]:
        node = node.setdefault(k, {}) if isinstance(k, str) else node[k]
    node[path[-1]] = value
    return d


def test_the_bases_load(tmp_path: Path) -> None:
    assert loader_outcome(lambda: load_scenario(_write(tmp_path, BASE)), "case.toml") is None
    booth = load_scenario(_write(tmp_path, BOOTH, "booth.toml"))
    assert [r.model for r in booth.robots] == ["irb5500_rail", "irb5500"]


# --- every ranged setting, just outside its range and of the wrong kind --------------------

def _range_cases() -> list[tuple[str, str, Any]]:
    cases = []
    for (table, key), (lo, hi, _) in sorted(RANGES.items()):
        if table == "conveyor" or key == "seed":
            continue
        listy = key in ("kp", "kd", "q_home")
        wrap = (lambda x: [x] * 6) if listy else (lambda x: x)
        below = lo - max(1.0, abs(lo))
        cases.append((table, key, wrap(below)))
        if math.isfinite(hi):
            cases.append((table, key, wrap(hi + max(1.0, abs(hi)))))
        cases.append((table, key, wrap(math.nan)))
        if (table, key) not in INF_ALLOWED:
            cases.append((table, key, wrap(math.inf)))
        cases.append((table, key, wrap("a")))
    return cases


@pytest.mark.parametrize("table,key,value", _range_cases(),
                         ids=lambda x: str(x) if not isinstance(x, list) else "list")
def test_a_setting_outside_its_range_is_refused_naming_the_key(tmp_path: Path, table: str,
                                                                key: str, value: Any) -> None:
    p = _write(tmp_path, _with(BASE, (table, key), value))
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None, f"[{table}] {key} = {value!r} was accepted"
    assert key in msg and f"[{table}]" in msg


# --- the settings that multiply time or memory, in combination ----------------------------

@pytest.mark.parametrize("planner,what", [
    ({"profile_spacing_m": 0.0005, "w_max_m": 3.0, "w_res_m": 0.0005}, "index-width search"),
    ({"future_grid_n": 50, "n_future": 8}, "index-width search"),
    ({"future_grid_n": 30, "n_future": 6, "profile_spacing_m": 0.001}, "index-width search"),
])
def test_a_width_search_past_memory_is_refused_by_the_budget(tmp_path: Path, planner: dict,
                                                             what: str) -> None:
    p = _write(tmp_path, _with(BASE, ("planner",), planner))
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and what in msg and "available" in msg


# --- TOML structures and encodings --------------------------------------------------------

_TEXT = 'name = "fz"\npart = "panel"\n[part_placement]\nxyz_m = [1.2, 0.0, 0.8]\n'
_STRUCTURES: dict[str, bytes] = {
    "deep_arrays": ("a = " + "[" * 5000 + "]" * 5000 + "\n" + _TEXT).encode(),
    "deep_inline_tables": ("a = " + "{b = " * 3000 + "1" + "}" * 3000 + "\n" + _TEXT).encode(),
    "nested_40": ("name = " + "[" * 40 + "1" + "]" * 40 + "\n").encode(),
    "non_utf8": _TEXT.encode("utf-8") + "# \u00e9\n".encode("latin-1"),
    "utf16": _TEXT.encode("utf-16"),
    "empty": b"",
    "binary": bytes(range(256)) * 4,
    "only_comments": b"# nothing\n",
    "nul_byte": _TEXT.encode() + b"\x00\n",
    "table_for_scalar": b'part = "panel"\n[resolution_m]\nx = 1\n',
    "array_for_table": _TEXT.encode() + b"planner = [1, 2]\n",
    "string_placement": b'name = "fz"\npart = "panel"\npart_placement = "here"\n',
    "string_coordinate": b'name = "fz"\npart = "panel"\n[part_placement]\nxyz_m = ["a", 0, 0]\n',
    "short_coordinate": b'name = "fz"\npart = "panel"\n[part_placement]\nxyz_m = [1.0]\n',
    "nested_coordinate": b'part = "panel"\n[part_placement]\nxyz_m = [[1.0], 0, 0]\n',
    "huge_int_resolution": _TEXT.encode() + b"resolution_m = 99999999999999999999\n",
    "inf_resolution": _TEXT.encode() + b"resolution_m = inf\n",
    "bad_name": _TEXT.replace('"fz"', '"a/../b"').encode(),
    "long_name": _TEXT.replace('"fz"', '"' + "x" * 100000 + '"').encode(),
    "unknown_top": _TEXT.encode() + b"[wheels]\nx = 1\n",
    "part_number": b'part = 7\n[part_placement]\nxyz_m = [0, 0, 0]\n',
    "thresholds_array": _TEXT.encode() + b"thresholds = [1]\n",
    "sweep_string": _TEXT.encode() + b'sweep = "all"\n',
    "sweep_huge_samples": _TEXT.encode() + b"[sweep]\nsamples = 100000000\n",
    "sweep_many_workers": _TEXT.encode() + b"[sweep]\nworkers = 100000\n",
    "duplicate_key": _TEXT.encode() + b'name = "again"\n',
    "planner_not_table": _TEXT.replace("[part_placement]", 'planner = "fast"\n[part_placement]')
    .encode(),
    "control_chars": _TEXT.replace('"fz"', '"f\\u001bz\\u0007"').encode(),
}


@pytest.mark.parametrize("kind", sorted(_STRUCTURES))
def test_a_malformed_toml_is_one_line_naming_the_file(tmp_path: Path, kind: str) -> None:
    p = tmp_path / "case.toml"
    p.write_bytes(_STRUCTURES[kind])
    assert loader_outcome(lambda: load_scenario(p), str(p)) is not None, kind


@pytest.mark.parametrize("robot", ["irb9999", "", "ABB_PAINT", "ur10_rail"])
def test_an_unknown_robot_is_refused_at_load(tmp_path: Path, robot: str) -> None:
    p = _write(tmp_path, _with(BASE, ("robot",), robot))
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and f"robot = {robot!r} is not a known robot" in msg


def test_a_byte_order_mark_is_read_as_utf8(tmp_path: Path) -> None:
    p = _write(tmp_path, BASE)
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    assert load_scenario(p).name == "fz"


# --- booth tables -------------------------------------------------------------------------

_BOOTH_CASES: dict[str, tuple[tuple[Any, ...], Any, str]] = {
    "unknown_model": (("robots", 0, "model"), "irb9999", "model = 'irb9999' is not a known"),
    "model_number": (("robots", 0, "model"), 5500, "is not a known robot"),
    "duplicate_name": (("robots", 1, "name"), "a", "robot names must be unique"),
    "bad_name": (("robots", 0, "name"), "a b", "must be letters"),
    "no_name": (("robots", 0, "name"), None, "must be letters"),
    "reversed_rail": (("robots", 0, "rail"), [1.65, -1.5], "write rail = [-1.5, 1.65]"),
    "equal_rail": (("robots", 0, "rail"), [1.0, 1.0], "lower < upper"),
    "rail_in_mm": (("robots", 0, "rail"), [-1500.0, 1500.0], "rail[0] = -1500.0 is out of"),
    "rail_string": (("robots", 0, "rail"), ["a", 1.0], "rail[0] = 'a' must be a number"),
    "rail_scalar": (("robots", 0, "rail"), 1.0, "rail = 1.0 must be rail = [lower, upper]"),
    "rail_nan": (("robots", 0, "rail"), [math.nan, 1.0], "rail[0] = nan is out of range"),
    "ur10_on_rail": (("robots", 0, "model"), "ur10", "model 'ur10' has no rail"),
    "home_short": (("robots", 1, "home"), [0.0, 0.0], "home = [0.0, 0.0] must be a list of 6"),
    "home_string": (("robots", 1, "home"), ["a"] * 6, "home[0] = 'a' must be a number"),
    "home_off_rail": (("robots", 0, "home"), [5.0] + [0.0] * 6, "off its rail"),
    "base_string": (("robots", 0, "base", "xyz_m"), ["a", 0, 0], "xyz_m[0] = 'a' must be"),
    "base_short": (("robots", 0, "base", "xyz_m"), [0.0], "must be a list of 3"),
    "allocation_list": (("allocation",), [1, 2], "[allocation] must be a table"),
    "allocation_robot": (("allocation",), {"z": [0, 0, 2]}, "'z' is not a robot"),
    "allocation_part": (("allocation",), {"a": [5, 0, 2]}, "names part 5"),
    "allocation_order": (("allocation",), {"a": [0, 3, 1]}, "must be below end pass"),
    "allocation_string": (("allocation",), {"a": ["0", 0, 2]}, "whole numbers"),
    "part_unknown": (("parts", 0, "part"), "bumper", "is not a library part"),
    "part_xyz_string": (("parts", 0, "xyz_m"), [0, "a", 0], "xyz_m[1] = 'a' must be"),
    "parts_empty": (("parts",), [], "needs at least one [[parts]]"),
    "parts_table": (("parts",), {"part": "door"}, "must be [[parts]] tables"),
    "robots_empty": (("robots",), [], "needs at least one [[robots]]"),
    "robots_table": (("robots",), {"name": "a"}, "must be [[robots]] tables"),
    "conveyor_fast": (("conveyor", "speed_m_s"), 50.0, "speed_m_s = 50.0 is out of range"),
    "conveyor_string": (("conveyor", "speed_m_s"), "a", "speed_m_s"),
    "direction_string": (("conveyor", "direction"), ["x", 0, 0], "direction[0] = 'x'"),
    "resolution_string": (("resolution_m",), "a", "resolution_m = 'a' must be a number"),
    "resolution_tiny": (("fast_resolution_m",), 1e-9, "fast_resolution_m = 1e-09 is out"),
    "planner_tiny_profile": (("planner", "profile_spacing_m"), 1e-6, "profile_spacing_m"),
    "part_planner_bands": (("parts", 0, "planner", "band_curves"), 10001, "band_curves"),
    "trajectory_jerk": (("trajectory", "jerk_ramp_s"), 3600.0, "jerk_ramp_s = 3600.0 is out"),
    "servo_string": (("servo", "bandwidth_hz"), "fast", "bandwidth_hz must be a number"),
    "planner_list": (("planner",), [1], "planner must be a table"),
    "clearance_huge": (("body_clearance_m",), 1e6, "body_clearance_m must be a distance"),
    "film_target_huge": (("film_target_um",), 1e9, "film_target_um must be a number"),
}


@pytest.mark.parametrize("kind", sorted(_BOOTH_CASES))
def test_a_bad_booth_key_is_refused_at_load_naming_table_and_key(tmp_path: Path,
                                                                 kind: str) -> None:
    path, value, expect = _BOOTH_CASES[kind]
    d = _with(BOOTH, path, value)
    if value is None:
        d["robots"][0].pop("name")
    p = _write(tmp_path, d, "booth.toml")
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and expect in msg, msg


def test_the_same_part_twice_at_one_place_is_a_copy(tmp_path: Path) -> None:
    d = _with(BOOTH, ("parts",), BOOTH["parts"] + [dict(BOOTH["parts"][1])])
    p = _write(tmp_path, d, "booth.toml")
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and "[[parts]] #2" in msg and "as [[parts]] #1" in msg


def test_a_booth_without_robots_is_told_it_needs_them(tmp_path: Path) -> None:
    d = {k: v for k, v in BOOTH.items() if k != "robots"}
    p = _write(tmp_path, d, "booth.toml")
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and "needs at least one [[robots]]" in msg
    assert "unknown key" not in msg


# --- seeded random mutations --------------------------------------------------------------

_POOL: list[Any] = [0, -1, 1, 10**30, -(10**30), 1e-300, 1e300, math.nan, math.inf, -math.inf,
                    "", "a", "1.0", "true", True, False, [], [1], [1.0, "a"], [[1.0]], {},
                    {"x": 1}, [math.nan] * 3, "\u202e\u0000", 0.5]
_PATHS: list[tuple[Any, ...]] = [("name",), ("part",), ("robot",), ("resolution_m",),
                                 ("fast_resolution_m",), ("applicator",),
                                 ("part_placement", "xyz_m"), ("part_placement", "rpy_rad"),
                                 ("base", "xyz_m"), ("thresholds", "max_collisions"),
                                 ("thresholds", "tolerance"), ("sweep", "samples"),
                                 ("sweep", "factors"), ("fast_planner", "n_future")]
_PATHS += [(t, k) for (t, k) in sorted(RANGES) if t != "conveyor"]


@pytest.mark.parametrize("seed", range(60))
def test_random_mutations_load_or_are_refused_in_one_line(tmp_path: Path, seed: int) -> None:
    rng = random.Random(seed)
    d = BASE
    for _ in range(rng.randint(1, 3)):
        value = rng.choice(_POOL) if rng.random() < 0.6 else \
            rng.choice([-1, 1]) * 10 ** rng.uniform(-12, 12)
        d = _with(d, rng.choice(_PATHS), value)
    p = _write(tmp_path, d)
    loader_outcome(lambda: load_scenario(p), str(p))


@pytest.mark.fuzz_full
@pytest.mark.parametrize("seed", range(60, 400))
def test_random_mutations_long_run(tmp_path: Path, seed: int) -> None:
    test_random_mutations_load_or_are_refused_in_one_line(tmp_path, seed)


# --- through the real command: exit 2, one line, no results folder --------------------------

_CLI: dict[str, tuple[tuple[Any, ...], Any, str]] = {
    "tiny_profile_spacing": (("planner", "profile_spacing_m"), 1e-6, "profile_spacing_m"),
    "huge_band_curves": (("planner", "band_curves"), 1000001, "band_curves"),
    "huge_overspray": (("planner", "overspray_m"), 1e6, "overspray_m"),
    "huge_jerk_ramp": (("trajectory", "jerk_ramp_s"), 1e6, "jerk_ramp_s"),
    "string_coordinate": (("part_placement", "xyz_m"), ["a", 0, 0], "case.toml"),
}


def _full_but(keep: tuple[str, ...], items: list[str]) -> list[Any]:
    """`items` as parameters, all but `keep` marked fuzz_full (a subprocess each, seconds)."""
    return [k if k in keep else pytest.param(k, marks=pytest.mark.fuzz_full) for k in items]


@pytest.mark.parametrize("kind", _full_but(("tiny_profile_spacing",), sorted(_CLI)))
def test_the_command_refuses_at_load(tmp_path: Path, kind: str) -> None:
    path, value, expect = _CLI[kind]
    p = _write(tmp_path, _with(BASE, path, value))
    out = tmp_path / "results" / "fz"
    out.parent.mkdir()
    line = cli_refusal(["plan", str(p), "--fast", "--out", str(out)], tmp_path, str(p), out)
    assert expect in line


@pytest.mark.parametrize("cap", _full_but(("0",), ["0", "inf", "nan", "-3", "lots"]))
def test_a_bad_memory_cap_is_one_line(tmp_path: Path, cap: str) -> None:
    p = _write(tmp_path, BASE)
    out = tmp_path / "results" / "fz"
    out.parent.mkdir()
    cli_refusal(["plan", str(p), "--fast", "--out", str(out)], tmp_path,
                "PAINTCELL_MAX_MEMORY_GB", out, env={"PAINTCELL_MAX_MEMORY_GB": cap})


def test_a_booth_with_an_unknown_model_is_refused_by_the_command(tmp_path: Path) -> None:
    p = _write(tmp_path, _with(BOOTH, ("robots", 1, "model"), "irb9999"), "booth.toml")
    out = tmp_path / "results" / "fzb"
    out.parent.mkdir()
    line = cli_refusal(["run", str(p), "--fast", "--out", str(out)], tmp_path, str(p), out)
    assert "[[robots]] b" in line and "irb5500" in line


_VARY = ["--vary", "part_offset_m=normal(0, 0.003)"]


def test_a_sweep_of_a_hundred_million_samples_is_refused_at_load(tmp_path: Path) -> None:
    p = _write(tmp_path, BASE)
    out = tmp_path / "results" / "fz-sweep"
    out.parent.mkdir()
    line = cli_refusal(["sweep", str(p), "--fast", "--samples", "100000000", *_VARY, "--out",
                        str(out)], tmp_path, "samples", out)
    assert "100,000,000" in line


@pytest.mark.parametrize("answer", _full_but(("garbage",), ["http", "garbage", "silent"]))
def test_a_scheduler_that_is_not_dask_is_refused_in_seconds(tmp_path: Path, answer: str) -> None:
    import socket
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    stop = threading.Event()

    def serve() -> None:    # a web server answers a request; garbage speaks first; silent waits
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            with conn:
                if answer == "garbage":
                    conn.sendall(b"\xff" * 64)
                elif answer == "http":
                    conn.settimeout(10)
                    try:
                        if conn.recv(1024):
                            conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n")
                    except OSError:
                        pass
                stop.wait(10 if answer != "garbage" else 0.5)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        address = f"tcp://127.0.0.1:{srv.getsockname()[1]}"
        p = _write(tmp_path, BASE)
        out = tmp_path / "results" / "fz-sweep"
        out.parent.mkdir()
        cli_refusal(["sweep", str(p), "--fast", "--samples", "2", *_VARY, "--scheduler",
                     address, "--out", str(out)], tmp_path, address, out)
    finally:
        stop.set()
        t.join(timeout=15)
        srv.close()


@pytest.mark.parametrize("bell", ['sigma_x_m = "a"\n', "a = " + "[" * 3000 + "]" * 3000 + "\n",
                                  "\xff\xfe", ""])
def test_a_bad_applicator_file_is_refused_at_load(tmp_path: Path, bell: str) -> None:
    (tmp_path / "bell.toml").write_bytes(bell.encode("latin-1"))
    p = _write(tmp_path, _with(BASE, ("applicator",), "bell.toml"))
    msg = loader_outcome(lambda: load_scenario(p), str(p))
    assert msg is not None and "bell.toml" in msg


@pytest.mark.parametrize("text", ["[" * 100000 + "]" * 100000, '{"a":' * 5000 + "1" + "}" * 5000,
                                  '{"a": ' + "[" * 40 + "]" * 40 + "}", "\ufeff{}", "", "nul\0",
                                  "[1, 2]"])
def test_a_results_json_nested_or_corrupt_is_one_line(tmp_path: Path, text: str) -> None:
    from paintcell.app.run_files import read_json

    p = tmp_path / "metrics.json"
    p.write_text(text, encoding="utf-8")
    msg = loader_outcome(lambda: read_json(p), str(p))
    assert (msg is None) == (text == "\ufeff{}"), msg
