"""Trust boundaries, replayed as a hostile user sharing the machine would: real planted links,
FIFOs, tampered results files, a poisoned robot-model cache, a second concurrent sweep.

Each case checks what must not happen by re-measuring the world afterwards (the link's target
and the FIFO unchanged, the module parsed by an independent RAPID grammar, the cached model's
joint ranges read back by MuJoCo), not by asking paintcell.
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from paintcell.cli.common import EXIT_USAGE
from paintcell.cli.main import main
from paintcell.core.results_dir import MARKER, ResultsDirError, new_results
from tests.sweep_cases import plate_scenario
from tests.trust_cases import cli, dead_pid, env, flat, rapid_parse, snapshot


def _one_line(err: str, *words: str) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)


# --- links and FIFOs where paintcell writes ----------------------------------------------------

def test_run_never_writes_through_a_linked_lock(tmp_path: Path) -> None:
    plate_scenario(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's file\n")
    (tmp_path / ".res.lock").symlink_to(victim)
    out = cli("run", "plate.toml", "--fast", "--out", "res", cwd=tmp_path)
    assert out.returncode == EXIT_USAGE
    _one_line(out.stderr, ".res.lock", "symbolic link", "remove it")
    assert victim.read_text() == "the user's file\n"
    assert (tmp_path / ".res.lock").is_symlink() and not (tmp_path / "res").exists()


def test_fifos_as_outputs_and_as_a_part_are_refused_at_once(tmp_path: Path) -> None:
    plate_scenario(tmp_path)
    for name in ("door.stl", "scn.toml", "regions.png", "part.stl"):
        os.mkfifo(tmp_path / name)
    cases = [(("generate", "door", "--out", "door.stl"), "door.stl"),
             (("init", "plate.stl", "--out", "scn.toml"), "scn.toml"),
             (("inspect", "plate.stl", "--png", "regions.png"), "regions.png"),
             (("inspect", "part.stl"), "part.stl")]
    for args, name in cases:
        t0 = time.monotonic()
        out = cli(*args, cwd=tmp_path, timeout=60)   # a blocked open would time out here
        assert out.returncode == EXIT_USAGE, (args, out.stderr)
        _one_line(out.stderr, name, "FIFO")
        assert time.monotonic() - t0 < 60
        assert stat.S_ISFIFO(os.lstat(tmp_path / name).st_mode), args


def test_init_generate_refuse_an_existing_file_unless_force(tmp_path: Path) -> None:
    mine = tmp_path / "door.stl"
    mine.write_text("my own mesh\n")
    out = cli("generate", "door", "--out", "door.stl", cwd=tmp_path)
    assert out.returncode == EXIT_USAGE
    _one_line(out.stderr, "door.stl exists", "--force")
    assert mine.read_text() == "my own mesh\n"
    plate_scenario(tmp_path)
    scn = tmp_path / "mine.toml"
    scn.write_text("# my scenario\n")
    out = cli("init", "plate.stl", "--out", "mine.toml", cwd=tmp_path)
    assert out.returncode == EXIT_USAGE
    _one_line(out.stderr, "mine.toml exists", "--force")
    assert scn.read_text() == "# my scenario\n"
    out = cli("generate", "door", "--out", "door.stl", "--force", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    import trimesh

    assert len(trimesh.load(mine, force="mesh").faces) > 100   # a real mesh replaced the text
    for cmd in ("init", "generate", "export"):
        h = cli(cmd, "--help", cwd=tmp_path).stdout
        assert "--force" in h and "replace an existing --out file" in h, cmd


# --- the cleaner and the report -----------------------------------------------------------------

def _marked(d: Path, files: dict[str, bytes]) -> None:
    with new_results(d, "run") as tmp:
        for name, data in files.items():
            (tmp / name).write_bytes(data)  # type: ignore[operator]


def test_the_cleaner_removes_only_what_the_killed_writers_lock_records(tmp_path: Path) -> None:
    res = tmp_path / "res"
    _marked(res, {"metrics.json": b'{"passed": true}', "plan.json": b"{}"})
    pid, other = dead_pid(), dead_pid()
    (res / ".metrics.json.bak").write_text("the user's backup")      # looks like a temp file
    (res / f".metrics.json.tmp-{other}-abcdefgh").write_text("another writer's")
    (res / f".metrics.json.tmp-{pid}-abcdefgh").write_text("half")   # the killed writer's
    (res / f".plan.tmp-{pid}-x1y2z3w4.json").write_text("half")
    (tmp_path / f".res.tmp-{pid}-beef").mkdir()
    (tmp_path / f".res.tmp-{other}-cafe").mkdir()
    (tmp_path / ".res.lock").write_text(f"paintcell validate (pid {pid}, since 10:00:00)")
    before = snapshot(tmp_path)
    with pytest.raises(ResultsDirError, match=r"\.metrics\.json\.bak"):
        _marked(res, {"metrics.json": b"{}"})   # the next run: refused, nothing lost
    gone = set(before) - set(snapshot(tmp_path))
    assert gone == {f"res/.metrics.json.tmp-{pid}-abcdefgh", f"res/.plan.tmp-{pid}-x1y2z3w4.json",
                    f".res.tmp-{pid}-beef", ".res.lock"}
    after = snapshot(tmp_path)
    assert {k: before[k] for k in after} == after   # everything kept is byte-identical


def test_report_embeds_only_regular_files_the_marker_lists(tmp_path: Path) -> None:
    from PIL import Image

    def png(colour: tuple[int, int, int]) -> bytes:
        import io

        buf = io.BytesIO()
        Image.new("RGB", (8, 8), colour).save(buf, "PNG")
        return buf.getvalue()

    secret = tmp_path / "secret.png"
    secret.write_bytes(png((255, 0, 0)))
    res = tmp_path / "res"
    metrics = {"passed": True, "checks": [], "scenario": {"name": "t"}}
    _marked(res, {"metrics.json": json.dumps(metrics).encode(), "plot_ok.png": png((0, 255, 0))})
    (res / "plot_link.png").symlink_to(secret)
    (res / "plot_planted.png").write_bytes(png((0, 0, 255)))
    os.mkfifo(res / "plot_fifo.png")
    assert main(["report", str(res)]) == 0
    doc = (res / "report.html").read_text()
    embedded = [base64.b64decode(u) for u in re.findall(r'src="data:image/png;base64,([^"]+)"',
                                                         doc)]
    assert png((0, 255, 0)) in embedded
    assert png((255, 0, 0)) not in embedded and png((0, 0, 255)) not in embedded
    assert "plot_link" not in doc and "plot_planted" not in doc and "plot_fifo" not in doc


# --- the robot-model cache ----------------------------------------------------------------------

def test_a_poisoned_robot_model_cache_file_is_rejected_and_rebuilt(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import mujoco

    from paintcell.robots import load_robot

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    robot = load_robot("ur10")
    path = Path(robot.mjcf_path)
    assert path.parent == tmp_path / "cache" / "paintcell" / "robots"
    assert stat.S_IMODE(path.parent.stat().st_mode) == 0o700
    clean = path.read_bytes()
    assert path.name.endswith(hashlib.sha256(clean).hexdigest()[:16] + ".xml")

    def ranges(p: Path) -> list[float]:
        m = mujoco.MjModel.from_xml_path(str(p))
        return [float(x) for x in m.jnt_range.ravel()]

    poisoned = re.sub(rb'range="[^"]*"', b'range="-0.1 0.1"', clean)
    assert poisoned != clean
    path.write_bytes(poisoned)
    assert set(ranges(path)) == {-0.1, 0.1}          # the poison would change a run
    again = load_robot("ur10")
    assert Path(again.mjcf_path) == path and path.read_bytes() == clean
    assert list(again.q_upper) == list(robot.q_upper) and max(robot.q_upper) > 1.0
    path.unlink()
    path.symlink_to(tmp_path / "elsewhere.xml")       # a link in the cache: replaced, not read
    (tmp_path / "elsewhere.xml").write_bytes(poisoned)
    third = load_robot("ur10")
    assert not path.is_symlink() and path.read_bytes() == clean
    assert list(third.q_upper) == list(robot.q_upper)
    assert (tmp_path / "elsewhere.xml").read_bytes() == poisoned


# --- a second concurrent sweep -----------------------------------------------------------------

@pytest.mark.slow
def test_a_second_concurrent_sweep_to_the_same_folder_is_refused_at_once(tmp_path: Path) -> None:
    plate_scenario(tmp_path)
    # Enough samples that the first sweep is still running when the second one asks for the
    # folder, however fast the machine; the first is ended by SIGTERM below.
    args = ["sweep", "plate.toml", "--fast", "--workers", "0", "--samples", "500", "--mode",
            "kinematic", "--no-report", "--out", "sw", "--vary", "flow_scale=uniform(0.9, 1.1)"]
    first = subprocess.Popen([sys.executable, "-m", "paintcell", *args], cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env())
    try:
        lock = tmp_path / ".sw.lock"
        t0 = time.monotonic()
        while not (lock.exists() and "paintcell sweep" in lock.read_text()):
            assert first.poll() is None, first.communicate()
            assert time.monotonic() - t0 < 120
            time.sleep(0.1)
        t1 = time.monotonic()
        second = cli(*args, cwd=tmp_path, timeout=60)
        assert second.returncode == EXIT_USAGE
        _one_line(second.stderr, "sw is being written by paintcell sweep", f"pid {first.pid}")
        assert time.monotonic() - t1 < 30      # refused at once: imports, no sample run
        assert first.poll() is None            # the first is untouched, still running
    finally:
        first.send_signal(signal.SIGTERM)
        first.communicate(timeout=120)


# --- verdicts and RAPID from a real run ---------------------------------------------------------

@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("trust")
    plate_scenario(d)
    out = cli("run", "plate.toml", "--fast", "--out", "res", "--no-report", "--mode",
              "kinematic", cwd=d, timeout=600)
    assert out.returncode == 0, out.stderr
    return d / "res"


def _copy(run_dir: Path, tmp_path: Path) -> Path:
    res = tmp_path / "res"
    shutil.copytree(run_dir, res, symlinks=True)
    return res


def _edit(path: Path, fn: object) -> None:
    d = json.loads(path.read_text())
    fn(d)  # type: ignore[operator]
    path.write_text(json.dumps(d))


def _header(mod: Path) -> list[str]:
    return [ln for ln in mod.read_text().splitlines()[:6] if ln.lstrip().startswith("!")]


@pytest.mark.slow
def test_export_rederives_the_verdict(run_dir: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    res = _copy(run_dir, tmp_path)
    assert main(["export", str(res), "--rapid", "--spacing", "1.0"]) == 0
    assert "VALIDATED in MuJoCo simulation: PASS" in _header(res / "plate.mod")[1]
    # A failed run's folder (its scenario's σ/μ limit 0.01 %) with passed = true written in.
    _edit(res / "scenario.json", lambda d: d["thresholds"].update(max_executed_nsd_pct=0.01))

    def claim_pass(d: dict) -> None:
        d["passed"] = True
        for c in d["checks"]:
            c["passed"] = True
            if c["name"] == "executed σ/μ":
                c["limit"] = 0.01
    _edit(res / "metrics.json", claim_pass)
    capsys.readouterr()
    assert main(["export", str(res), "--rapid", "--out", str(tmp_path / "a.mod")]) == EXIT_USAGE
    err = capsys.readouterr().err
    _one_line(err, "did not pass validation", "executed")
    assert not (tmp_path / "a.mod").exists()
    # NaN figures and a verdict that says pass, against the scenario's own thresholds.
    shutil.rmtree(res)
    res = _copy(run_dir, tmp_path)

    def nan_all(d: dict) -> None:
        for c in d["checks"]:
            c["value"] = math.nan
        d["executed_nsd_pct"] = math.nan
    _edit(res / "metrics.json", nan_all)
    assert main(["export", str(res), "--rapid", "--out", str(tmp_path / "b.mod")]) == EXIT_USAGE
    _one_line(capsys.readouterr().err, "metrics.json does not match its data")
    assert main(["export", str(res), "--rapid", "--out", str(tmp_path / "b.mod"),
                 "--allow-failed", "--spacing", "1.0"]) == 0
    head = _header(tmp_path / "b.mod")
    assert "NOT VALIDATED" in head[1] and "VALIDATED in MuJoCo" not in "".join(head)


@pytest.mark.slow
def test_no_text_from_the_folder_injects_a_rapid_line(run_dir: Path, tmp_path: Path) -> None:
    res = _copy(run_dir, tmp_path)
    evil = "x\n  ENDPROC\n  PROC evil()\n    SetDO doBrush, 1;\n    MoveAbsJ jHome, v1000, fine, " \
           "tBell;\r\n\x1b[2J\x00\x07\u2028  ENDPROC\n"

    def inject(d: dict) -> None:
        d["checks"][0]["name"] = evil
        d["checks"][0]["limit"] = evil
        d["checks"][0]["passed"] = False
        d["passed"] = False
    _edit(res / "metrics.json", inject)
    _edit(res / "scenario.json", lambda d: d.update(name="ENDMODULE"))
    assert main(["export", str(res), "--rapid", "--allow-failed", "--spacing", "1.0"]) == 0
    mods = list(res.glob("*.mod"))
    assert [m.name for m in mods] == ["m_ENDMODULE.mod"]
    text = mods[0].read_text()
    tokens = flat(rapid_parse(text))                  # the independent RAPID grammar
    assert tokens[:2] == ["MODULE", "m_ENDMODULE"]
    procs = [tokens[i + 1] for i, t in enumerate(tokens) if t == "PROC"]
    assert procs == ["main"] and "evil" not in tokens and "SetDO" not in tokens
    assert all(" " <= c <= "~" for c in text.replace("\n", ""))
    assert "NOT VALIDATED" in _header(mods[0])[1]


@pytest.mark.slow
def test_export_never_touches_the_marker_and_asks_before_replacing(
        run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    res = _copy(run_dir, tmp_path)
    marker = (res / MARKER).read_bytes()
    for name in (MARKER, "metrics.json"):
        assert main(["export", str(res), "--rapid", "--out", str(res / name), "--force"]) \
            == EXIT_USAGE
        _one_line(capsys.readouterr().err, name, "a file of the results folder")
    assert (res / MARKER).read_bytes() == marker
    mine = tmp_path / "cell.mod"
    mine.write_text("MODULE mine\nENDMODULE\n")
    assert main(["export", str(res), "--rapid", "--out", str(mine)]) == EXIT_USAGE
    _one_line(capsys.readouterr().err, "cell.mod exists", "--force")
    assert mine.read_text() == "MODULE mine\nENDMODULE\n"
    os.mkfifo(tmp_path / "fifo.mod")
    assert main(["export", str(res), "--rapid", "--out", str(tmp_path / "fifo.mod"),
                 "--force"]) == EXIT_USAGE
    _one_line(capsys.readouterr().err, "fifo.mod is a FIFO")
    assert main(["export", str(res), "--rapid", "--out", str(mine), "--force",
                 "--spacing", "1.0"]) == 0
    assert "VALIDATED in MuJoCo simulation: PASS" in mine.read_text()
    # the folder's own module (listed in the marker) is replaced without --force
    assert main(["export", str(res), "--rapid", "--spacing", "1.0"]) == 0
    assert main(["export", str(res), "--rapid", "--spacing", "1.0"]) == 0
    assert "plate.mod" in json.loads((res / MARKER).read_text())["files"]
    assert not (res / ".paintcell-results").is_symlink()
