"""Results safety, replayed as a hostile user would: real processes, real signals.

Every case: decoy folders survive, failed runs are not exported, code named in a
results folder is never executed, invalid thresholds are refused, `check` survives scenarios that
exit, raise or crash, killed runs leave nothing the next run does not clean, two concurrent runs
cannot both write, and the messages name the file at fault.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from paintcell.cli.common import EXIT_INTERRUPTED, EXIT_USAGE
from paintcell.cli.main import main
from paintcell.core.results_dir import MARKER, new_results
from tests.helpers import LOOSE_SPEC_TOML

ROOT = Path(__file__).resolve().parents[1]

SCENARIO = """\
name = "{name}"
part = "panel"
fast_resolution_m = 0.04
{extra_top}
[part_placement]
xyz_m = [1.4, 0.0, 1.0]
rpy_rad = [1.5707963267948966, 0.0, -1.5707963267948966]

[base]
xyz_m = [{base_x}, 0.0, 0.0]

[fast_planner]
sample_spacing_m = 0.04

[trajectory]
q_home = [0.0, -0.6, 0.3, 0.0, 0.9, 0.0]

[thresholds]
max_executed_nsd_pct = {nsd}
max_loss_pp = 1.0
max_cycle_time_s = 90.0

""" + LOOSE_SPEC_TOML


def _scenario(d: Path, name: str = "fz", nsd: float = 30.0, base_x: float = 0.0,
              extra_top: str = "") -> Path:
    path = d / f"{name}.toml"
    path.write_text(SCENARIO.format(name=name, nsd=nsd, base_x=base_x, extra_top=extra_top))
    return path


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _cli(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout, env=_env())


def _start(*args: str, cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "paintcell", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=cwd, env=_env())


def _wait_for(pred: object, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not pred():  # type: ignore[operator]
        if time.monotonic() - t0 > timeout:
            raise AssertionError("timed out waiting for the run to reach its stage")
        time.sleep(0.02)


def _hidden(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir() if p.name.startswith("."))


def _snapshot(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file()}


# --- refusals that need no run ------------------------------------------------------------------

@pytest.mark.parametrize(("snippet", "expect"), [
    ("[thresholds]\nmax_loss_pp = nan", "max_loss_pp = nan is not a finite number"),
    ("[thresholds]\nmax_executed_nsd_pct = nan", "max_executed_nsd_pct = nan"),
    ("[thresholds]\nmax_collisions = -1", "max_collisions = -1 is out of range; valid: [0, inf)"),
    ("[thresholds]\nreachability_pct = 101.0", "reachability_pct = 101.0 is out of range"),
    ("[planner]\nu_max = 5.0", "u_max = 5.0 is out of range; valid: [1e-06, 0.999]"),
    ("[planner]\nv_nominal_m_s = inf", "v_nominal_m_s = inf is not a finite number"),
    ("[planner]\nu_maxx = 0.04", "unknown planner setting(s) ['u_maxx']; valid: "),
    ("[robot_base]\nxyz_m = [0, 0, 0]", "unknown key(s) ['robot_base']; valid: "),
    ("[thresholds]\nmax_colisions = 0", "unknown [thresholds] key(s) ['max_colisions']"),
])
def test_invalid_settings_and_thresholds_are_refused_naming_the_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], snippet: str, expect: str) -> None:
    text = SCENARIO.format(name="bad", nsd=30.0, base_x=0.0, extra_top="")
    table, line = snippet.split("\n")
    key = line.split(" = ")[0]
    text = "\n".join(ln for ln in text.splitlines() if not ln.startswith(key + " =")) + "\n"
    if table in text:  # add the key to the existing table instead of repeating it
        text = text.replace(table + "\n", snippet + "\n")
    else:
        text += "\n" + snippet + "\n"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["run", str(path), "--fast", "--out", str(tmp_path / "out")]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert expect in err and str(path) in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_python_scenario_with_a_nan_threshold_is_refused(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) \
        -> None:
    script = tmp_path / "nan.py"
    script.write_text("from paintcell.app.scenario import Placement, Scenario, Thresholds\n"
                      "SCENARIO = Scenario(name='nan', part='panel', part_placement=Placement(),"
                      " thresholds=Thresholds(max_loss_pp=float('nan')))\n")
    assert main(["run", str(script), "--fast", "--out", str(tmp_path / "o")]) == EXIT_USAGE
    assert "max_loss_pp = nan is not a finite number" in capsys.readouterr().err


def test_toml_decode_error_names_the_file(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "broken.toml"
    path.write_text('name = "x"\npart = [\n')
    assert main(["run", str(path)]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert f"{path}: not valid TOML" in err and err.count("\n") == 1


def test_decoy_folders_are_never_replaced(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    scn = _scenario(tmp_path)
    decoy = tmp_path / "decoy"
    decoy.mkdir()
    (decoy / "important.txt").write_text("precious")
    (decoy / "metrics.json").write_text("{}")
    (decoy / "scenario.json").write_text("{}")
    before = _snapshot(decoy)
    for cmd in ("run", "plan"):
        assert main([cmd, str(scn), "--fast", "--out", str(decoy)]) == EXIT_USAGE
        assert "is not a paintcell results folder" in capsys.readouterr().err
    for cmd in ("validate", "report"):
        assert main([cmd, str(decoy)]) == EXIT_USAGE
        assert "not a paintcell results folder" in capsys.readouterr().err
    assert main(["export", str(decoy), "--rapid"]) == EXIT_USAGE
    assert _snapshot(decoy) == before and _hidden(tmp_path) == []
    # A paintcell folder with a file the user dropped into it is not replaced either.
    with new_results(tmp_path / "mine", "test") as tmp:
        (tmp / "plan.json").write_text("{}")  # type: ignore[operator]
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    assert main(["plan", str(scn), "--fast", "--out", str(tmp_path / "mine")]) == EXIT_USAGE
    assert "holds files paintcell did not write (notes.txt)" in capsys.readouterr().err
    assert (tmp_path / "mine" / "notes.txt").read_text() == "mine"


def test_the_results_folder_is_never_missing_during_a_swap(tmp_path: Path) -> None:
    out = tmp_path / "res"
    missing = []
    stop = threading.Event()

    def watch() -> None:
        while not stop.is_set():
            if not out.is_dir():
                missing.append(time.monotonic())

    with new_results(out, "test") as tmp:
        (tmp / "a.txt").write_text("0")  # type: ignore[operator]
    t = threading.Thread(target=watch)
    t.start()
    try:
        for i in range(1, 200):
            with new_results(out, "test") as tmp:
                (tmp / "a.txt").write_text(str(i))  # type: ignore[operator]
    finally:
        stop.set()
        t.join()
    assert missing == [] and (out / "a.txt").read_text() == "199"
    assert _hidden(tmp_path) == [] and json.loads((out / MARKER).read_text())["files"] == ["a.txt"]


@pytest.mark.parametrize(("name", "data", "expect"), [
    ("garbage.stl", os.urandom(3000), "is neither a binary STL"),
    ("garbage.obj", b"v 0 0 0\n" + bytes(range(128, 256)) * 8, "is not a text OBJ file"),
    ("cut.stl", (b"\0" * 80 + (10).to_bytes(4, "little") + b"\0" * 200),
     "the header's 10 triangles need 584"),
])
def test_garbage_meshes_get_a_message_naming_the_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, data: bytes,
        expect: str) -> None:
    (tmp_path / name).write_bytes(data)
    scn = _scenario(tmp_path).read_text().replace('part = "panel"', f'part = "{name}"')
    (tmp_path / "m.toml").write_text(scn)
    assert main(["plan", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o")]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert expect in err and name in err and "charset_normalizer" not in err, err


def test_a_failed_plan_leaves_the_results_folder_as_it_was(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with new_results(tmp_path / "res", "run") as tmp:
        (tmp / "plan.json").write_text('{"old": 1}')  # type: ignore[operator]
    before = _snapshot(tmp_path / "res")
    (tmp_path / "cut.stl").write_bytes(b"\0" * 80 + (10).to_bytes(4, "little"))
    scn = _scenario(tmp_path).read_text().replace('part = "panel"', 'part = "cut.stl"')
    (tmp_path / "m.toml").write_text(scn)
    assert main(["plan", str(tmp_path / "m.toml"), "--out", str(tmp_path / "res")]) == EXIT_USAGE
    assert "cut.stl" in capsys.readouterr().err
    assert _snapshot(tmp_path / "res") == before and _hidden(tmp_path) == []


def test_a_signal_a_library_swallows_still_interrupts(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # trimesh imports optional modules inside `except BaseException`: a Ctrl-C that lands there
    # is swallowed. Replay it with a real SIGINT raised inside such a block during the plan.
    import paintcell.app.pipeline

    real = paintcell.app.pipeline.load_surface

    def swallowing_load(*args: object, **kw: object) -> object:
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # the handler runs here and its exception is swallowed below
        except BaseException:  # noqa: BLE001 - what the library does
            pass
        return real(*args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(paintcell.app.pipeline, "load_surface", swallowing_load)
    with new_results(tmp_path / "res", "run") as tmp:
        (tmp / "plan.json").write_text('{"old": 1}')  # type: ignore[operator]
    before = _snapshot(tmp_path / "res")
    assert main(["plan", str(_scenario(tmp_path)), "--fast", "--out",
                 str(tmp_path / "res")]) == EXIT_INTERRUPTED
    assert _snapshot(tmp_path / "res") == before and _hidden(tmp_path) == []


# --- with real runs -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("safety")
    _scenario(d)
    out = _cli("run", "fz.toml", "--fast", "--out", "res", "--no-report", "--mode", "kinematic",
               cwd=d)
    assert out.returncode == 0, out.stderr
    return d


@pytest.mark.slow
def test_results_use_the_snapshot_and_never_run_code_from_the_folder(good: Path,
                                                                     tmp_path: Path) -> None:
    # In-process on purpose: a planted import would run in this very process.
    res = tmp_path / "res"
    shutil.copytree(good / "res", res)
    assert main(["export", str(res), "--rapid", "--out", str(tmp_path / "before.mod")]) == 0
    # A planted script named as the scenario's source, and one sitting in the folder.
    sentinel = tmp_path / "SENTINEL"
    evil = f"import pathlib\npathlib.Path({str(sentinel)!r}).write_text('ran')\n"
    (tmp_path / "evil.py").write_text(evil)
    meta = json.loads((res / "scenario.json").read_text())
    meta["source"] = str(tmp_path / "evil.py")
    (res / "scenario.json").write_text(json.dumps(meta))
    # Move the robot base 0.5 m in the scenario file after the run: export must not follow.
    _scenario(good, base_x=0.5)
    try:
        for args in (["validate", str(res)], ["export", str(res), "--rapid"],
                     ["report", str(res)]):
            assert main(args) == 0, args
    finally:
        _scenario(good)
    assert not sentinel.exists()
    assert (res / "fz.mod").read_text() == (tmp_path / "before.mod").read_text()
    assert "VALIDATED in MuJoCo simulation: PASS" in (res / "fz.mod").read_text()
    marker = json.loads((res / MARKER).read_text())
    assert {"fz.mod", "report.html", "metrics.json", "film.npz", "film.glb"} <= set(marker["files"])


@pytest.mark.slow
def test_corrupt_files_are_named(good: Path, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    res = tmp_path / "res"
    shutil.copytree(good / "res", res)
    (res / "trace.npz").write_text("this is text, not numpy\n")
    assert main(["validate", str(res)]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "trace.npz is not an .npz archive" in err
    assert "allow_pickle" not in err and err.count("\n") == 1
    shutil.copy(good / "res" / "trace.npz", res / "trace.npz")
    (res / "metrics.json").write_text("{ not json")
    for args in (["export", str(res), "--rapid"], ["report", str(res)]):
        assert main(args) == EXIT_USAGE
        assert f"{res / 'metrics.json'} is not readable JSON" in capsys.readouterr().err
    # validate rewrites metrics.json: the corrupt one is named and replaced, not fatal.
    assert main(["validate", str(res)]) == 0
    assert "metrics.json" in capsys.readouterr().err
    assert json.loads((res / "metrics.json").read_text())["passed"] is True
    (res / "figures.json").write_text("[1, 2]")
    assert main(["report", str(res)]) == EXIT_USAGE
    assert "figures.json must hold a JSON object" in capsys.readouterr().err


@pytest.mark.slow
def test_killed_runs_leave_nothing_the_next_run_does_not_clean(good: Path,
                                                               tmp_path: Path) -> None:
    res = tmp_path / "res"
    shutil.copytree(good / "res", res)
    before = _snapshot(res)
    scn = str(good / "fz.toml")

    def started() -> bool:
        return any(".res.tmp-" in n for n in _hidden(tmp_path))

    # SIGKILL mid-run: the old results stay whole; the temp folder of the dead process stays.
    p = _start("run", scn, "--fast", "--out", str(res), "--no-report", cwd=tmp_path)
    _wait_for(started)
    time.sleep(1.0)
    p.kill()
    p.wait()
    assert _snapshot(res) == before and started()
    # SIGTERM mid-run: exit 130, its own temp folder removed (the dead one's is not its to judge
    # until it holds the lock: it is the next writer, so it cleans it too).
    p = _start("run", scn, "--fast", "--out", str(res), "--no-report", cwd=tmp_path)
    _wait_for(lambda: len([n for n in _hidden(tmp_path) if ".res.tmp-" in n]) == 1
              and str(p.pid) in "".join(_hidden(tmp_path)))
    time.sleep(0.5)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == EXIT_INTERRUPTED and "interrupted (SIGTERM)" in err, err
    assert _hidden(tmp_path) == [] and _snapshot(res) == before
    # Ctrl-C in the first moments (while importing) is not ignored and is not an input error.
    p = _start("run", scn, "--fast", "--out", str(res), "--no-report", cwd=tmp_path)
    time.sleep(0.4)
    p.send_signal(signal.SIGINT)
    p.communicate(timeout=60)
    assert p.returncode in (EXIT_INTERRUPTED, -signal.SIGINT), p.returncode
    assert _hidden(tmp_path) == [] and _snapshot(res) == before


@pytest.mark.slow
def test_two_concurrent_runs_one_is_refused_nothing_lost(good: Path, tmp_path: Path) -> None:
    scn = str(good / "fz.toml")
    a = _start("run", scn, "--fast", "--out", "res", "--no-report", "--mode", "kinematic",
               cwd=tmp_path)
    # Once `a` holds the lock (its temporary folder exists), it is frozen with SIGSTOP while `b`
    # tries: a fast run would otherwise finish before `b` has imported, and `b` would then
    # rightly replace the folder (the test raced the run's speed).
    _wait_for(lambda: any(".res.tmp-" in n for n in _hidden(tmp_path)))
    os.kill(a.pid, signal.SIGSTOP)
    try:
        b = _cli("run", scn, "--fast", "--out", "res", "--no-report", cwd=tmp_path)
    finally:
        os.kill(a.pid, signal.SIGCONT)
    assert b.returncode == EXIT_USAGE and b.stderr.count("\n") == 1
    assert f"is being written by paintcell run (pid {a.pid}" in b.stderr, b.stderr
    _, err = a.communicate(timeout=300)
    assert a.returncode == 0, err
    marker = json.loads((tmp_path / "res" / MARKER).read_text())
    assert set(marker["files"]) == {p.name for p in (tmp_path / "res").iterdir()} - {MARKER}
    assert _hidden(tmp_path) == []


@pytest.mark.slow
def test_check_survives_exits_exceptions_crashes_and_memory_hogs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "scn"
    d.mkdir()
    head = ("from paintcell.app.scenario import Placement, Scenario\n"
            "SCENARIO = Scenario(name='{n}', part='panel', part_placement=Placement())\n")
    (d / "a_exit.py").write_text("import sys\nsys.exit(0)\n")
    (d / "b_memory.py").write_text(head.format(n="b") + "raise MemoryError('planted')\n")
    (d / "c_killed.py").write_text("import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n")
    bell = (ROOT / "paintcell" / "paint" / "data" / "default_bell.toml").read_text()
    # whatever the shipped values (a plain text replace of them silently stopped matching when
    # the default bell changed, and d_huge ran the ordinary bell)
    bell = re.sub(r"^sigma_x_m = .*$", "sigma_x_m = 50.0", bell, flags=re.M)
    bell = re.sub(r"^sigma_y_m = .*$", "sigma_y_m = 50.0", bell, flags=re.M)
    assert bell.count("= 50.0") == 2
    (d / "huge_bell.toml.txt").write_text(bell)
    _scenario(d, name="d_huge", extra_top='applicator = "huge_bell.toml.txt"')
    _scenario(d, name="e_tight", nsd=0.01)  # σ/μ ≤ 0.01 %: no real coat passes
    out = _cli("check", "scn", "--fast", "--junit", "j.xml", "--out", "res", cwd=tmp_path)
    assert out.returncode == 1, out.stderr
    assert "Traceback" not in out.stdout + out.stderr
    rows = {ln.split()[0]: ln for ln in out.stdout.splitlines()[2:-1]}
    assert "called sys.exit(0) while loading" in rows["a_exit"]
    assert "MemoryError" in rows["b_memory"]
    assert "killed by SIGKILL" in rows["c_killed"]
    assert "GiB" in rows["d_huge"] and "sigma_x_m" in rows["d_huge"]
    assert "FAIL" in rows["e_tight"] and "ERROR" not in rows["e_tight"]
    root = ET.parse(tmp_path / "j.xml").getroot()
    assert root.get("tests") == "5" and root.get("errors") == "4" and root.get("failures") == "1"
    cases = {c.get("name"): c for c in root.iter("testcase")}
    assert all(cases[n].find("error") is not None for n in
               ("a_exit", "b_memory", "c_killed", "d_huge"))
    assert cases["e_tight"].find("failure") is not None
    # The failed run's results are there, and its program is not exported.
    run = tmp_path / "res" / "e_tight"
    assert main(["export", str(run), "--rapid"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "did not pass validation" in err and "executed" in err
    assert not list(run.glob("*.mod"))
    assert main(["export", str(run), "--rapid", "--allow-failed"]) == 0
    head = (run / "e_tight.mod").read_text().splitlines()[:5]
    assert "NOT VALIDATED: THIS RUN FAILED" in head[2] and "executed" in head[3]


@pytest.mark.slow
def test_an_interrupted_check_stops_its_scenario_and_still_writes_junit(good: Path,
                                                                        tmp_path: Path) -> None:
    d = tmp_path / "scn"
    d.mkdir()
    shutil.copy(good / "fz.toml", d / "fz.toml")
    p = _start("check", "scn", "--fast", "--junit", "j.xml", cwd=tmp_path)
    kids = Path(f"/proc/{p.pid}/task/{p.pid}/children")
    _wait_for(lambda: kids.exists() and kids.read_text().strip() != "")
    child = int(kids.read_text().split()[0])
    time.sleep(1.0)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == EXIT_INTERRUPTED and "interrupted (SIGTERM)" in err, err
    assert not Path(f"/proc/{child}").exists()  # the scenario's process was stopped and reaped
    # The JUnit is not green: the stopped scenario is an error case, and so is the interruption.
    root = ET.parse(tmp_path / "j.xml").getroot()
    cases = {c.get("name"): c.find("error") for c in root.iter("testcase")}
    assert root.get("errors") == "2" and set(cases) == {"fz", "interrupted"}, cases
    assert "interrupted (SIGTERM): 0 scenario(s) not run" in cases["interrupted"].get("message")
