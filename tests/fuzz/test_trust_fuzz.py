"""Seeded fuzz of the trust boundaries: folder states, planted links and FIFOs, tampered results,
hostile texts bound for RAPID, poisoned robot-model cache files.

Every case re-measures the world afterwards (byte snapshots that never follow a link, the
module parsed by rapidchecker's independent RAPID grammar, MuJoCo-free file digests); the
seeds make every case reproducible. In-process and fast: the whole file runs in well under 40 s.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import math
import os
import random
import re
import stat
import string
import time
from pathlib import Path

import numpy as np
import pytest

from paintcell.cli.main import main
from paintcell.core.atomic_io import atomic_path, atomic_write_npz, atomic_write_text
from paintcell.core.results_dir import MARKER, ResultsDirError, lock_results, new_results
from paintcell.core.safe_paths import UnsafePathError
from paintcell.output.export_rapid import rapid_module
from paintcell.output.rapid_text import comment_text, recorded_mismatches, validation_header
from paintcell.validation.validate_report import Thresholds, ValidationReport, threshold_checks
from tests.trust_cases import dead_pid, flat, rapid_parse, small_program, snapshot

# --- what sits where paintcell writes ----------------------------------------------------------

STATES = ("absent", "regular", "link_to_file", "dangling_link", "link_to_dir", "fifo", "dir")
WRITABLE = {"absent", "regular"}


def _plant(path: Path, state: str, victim: Path) -> None:
    """Put `state` at `path`; links point at `victim` (a file holding b"victim")."""
    victim.write_bytes(b"victim")
    if state == "regular":
        path.write_bytes(b"old")
    elif state == "link_to_file":
        path.symlink_to(victim)
    elif state == "dangling_link":
        path.symlink_to(victim.parent / "nowhere")
    elif state == "link_to_dir":
        path.symlink_to(victim.parent)
    elif state == "fifo":
        os.mkfifo(path)
    elif state == "dir":
        path.mkdir()


def _write(kind: str, path: Path) -> None:
    if kind == "text":
        atomic_write_text(path, "new")
    elif kind == "npz":
        atomic_write_npz(path, {"x": np.arange(3.0)})
    else:
        with atomic_path(path) as tmp:
            tmp.write_bytes(b"new")


@pytest.mark.parametrize("kind", ["text", "npz", "path"])
@pytest.mark.parametrize("state", STATES)
def test_writers_write_only_new_or_regular_files(tmp_path: Path, state: str, kind: str) -> None:
    box = tmp_path / "box"
    box.mkdir()
    victim = tmp_path / "victim.bin"
    target = box / ("out.npz" if kind == "npz" else "out.png")
    _plant(target, state, victim)
    before = snapshot(tmp_path)
    t0 = time.monotonic()
    if state in WRITABLE:
        _write(kind, target)
        assert stat.S_ISREG(os.lstat(target).st_mode)
        assert [p.name for p in box.iterdir()] == [target.name]   # no temp file left
        if kind == "npz":
            with np.load(target) as z:
                assert list(z["x"]) == [0.0, 1.0, 2.0]
        else:
            assert target.read_bytes() == b"new"
    else:
        with pytest.raises(UnsafePathError, match=re.escape(str(target))):
            _write(kind, target)
        assert snapshot(tmp_path) == before       # nothing written, nothing replaced
    assert victim.read_bytes() == b"victim"
    assert time.monotonic() - t0 < 5              # a FIFO is never opened (no wait)


@pytest.mark.parametrize("state", [*STATES, "stale_record", "garbage"])
def test_the_lock_is_a_regular_file_or_refused_at_once(tmp_path: Path, state: str) -> None:
    lock = tmp_path / ".res.lock"
    victim = tmp_path / "victim.bin"
    if state == "stale_record":
        lock.write_text(f"paintcell run (pid {dead_pid()}, since 10:00:00)")
        victim.write_bytes(b"victim")
    elif state == "garbage":
        lock.write_bytes(bytes(range(256)))
        victim.write_bytes(b"victim")
    else:
        _plant(lock, state, victim)
    before = snapshot(tmp_path)
    t0 = time.monotonic()
    if state in WRITABLE | {"stale_record", "garbage"}:
        with lock_results(tmp_path / "res", "run"):
            assert "paintcell run (pid " in lock.read_text()
        assert not lock.exists()
    else:
        with pytest.raises(ResultsDirError, match=r"\.res\.lock") as e:
            with lock_results(tmp_path / "res", "run"):
                pass
        assert "\n" not in str(e.value)
        assert snapshot(tmp_path) == before
    assert victim.read_bytes() == b"victim" and time.monotonic() - t0 < 5


INPUTS = ("scenario.toml", "scenario.py", "part.stl", "metrics.json", "trace.npz")


@pytest.mark.parametrize("name", INPUTS)
@pytest.mark.parametrize("state", ["fifo", "link_to_file"])
def test_inputs_that_are_fifos_or_links_are_refused_at_once(tmp_path: Path, name: str,
                                                            state: str) -> None:
    """A FIFO where paintcell reads is refused, not waited on; a results file that is a link is
    not followed (a scenario or part file may be a link: the user's choice)."""
    from paintcell.app.run_files import check_folder_files, read_json
    from paintcell.app.scenario_files import load_scenario
    from paintcell.core.errors import PaintcellError
    from paintcell.surface.mesh_io import read_part_file

    victim = tmp_path / "victim.bin"
    _plant(tmp_path / name, state, victim)
    readers = {"scenario.toml": load_scenario, "scenario.py": load_scenario,
               "part.stl": read_part_file, "metrics.json": read_json,
               "trace.npz": lambda p: check_folder_files(p.parent)}
    if name == "trace.npz":   # check_folder_files reads metrics.json first
        (tmp_path / "metrics.json").write_text("{}")
    t0 = time.monotonic()
    if state == "link_to_file" and name in ("scenario.toml", "scenario.py", "part.stl"):
        with pytest.raises(PaintcellError):   # followed, and victim's content is no scenario
            readers[name](tmp_path / name)
    else:
        with pytest.raises(PaintcellError, match="FIFO|symbolic link"):
            readers[name](tmp_path / name)
    assert time.monotonic() - t0 < 5 and victim.read_bytes() == b"victim"


OUT_STATES = ("absent", "empty", "marked", "marked_foreign", "unmarked", "link_to_marked",
              "regular", "fifo", "linked_marker")


@pytest.mark.parametrize("state", OUT_STATES)
def test_run_replaces_only_its_own_folders(tmp_path: Path, state: str) -> None:
    res, real = tmp_path / "res", tmp_path / "real"

    def marked(d: Path) -> None:
        with new_results(d, "run") as tmp:
            (tmp / "metrics.json").write_text("{}")  # type: ignore[operator]

    if state == "empty":
        res.mkdir()
    elif state in ("marked", "marked_foreign"):
        marked(res)
        if state == "marked_foreign":
            (res / "notes.txt").write_text("mine")
    elif state == "unmarked":
        res.mkdir()
        (res / "notes.txt").write_text("mine")
    elif state == "link_to_marked":
        marked(real)
        res.symlink_to(real)
    elif state == "regular":
        res.write_text("mine")
    elif state == "fifo":
        os.mkfifo(res)
    elif state == "linked_marker":   # a marker that is a link is not paintcell's marker
        marked(real)
        res.mkdir()
        (res / "metrics.json").write_text("{}")
        (res / MARKER).symlink_to(real / MARKER)
    before = snapshot(tmp_path)
    if state in ("absent", "empty", "marked"):
        marked(res)
        assert (res / MARKER).is_file() and not (res / MARKER).is_symlink()
    else:
        with pytest.raises(ResultsDirError):
            marked(res)
        assert snapshot(tmp_path) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# --- the cleaner --------------------------------------------------------------------------------

LISTED = ("metrics.json", "plan.json", "film.npz", "render_front.png", "report.html")


@pytest.mark.parametrize("seed", range(20))
def test_the_cleaner_removes_exactly_the_killed_writers_leftovers(tmp_path: Path,
                                                                   seed: int) -> None:
    rng = random.Random(seed)
    res = tmp_path / "res"
    listed = rng.sample(LISTED, rng.randint(1, len(LISTED)))
    with new_results(res, "run") as tmp:
        for n in listed:
            (tmp / n).write_text(n)  # type: ignore[operator]
    stale, other = dead_pid(), dead_pid()
    record = rng.choice(["record", "record", "garbage", "none"])
    expect: set[str] = set()

    def r8() -> str:
        return "".join(rng.choice(string.ascii_lowercase + string.digits + "_") for _ in range(8))

    victim = tmp_path / "victim.txt"
    victim.write_text("victim")
    for _ in range(rng.randint(4, 12)):
        name = rng.choice(listed)
        stem, suffix = Path(name).stem, Path(name).suffix
        kind = rng.randrange(9)
        if kind == 0:        # the killed writer's temp file of a listed file
            p, mine = res / f".{name}.tmp-{stale}-{r8()}", True
        elif kind == 1:      # atomic_path's name (stem + suffix)
            p, mine = res / f".{stem}.tmp-{stale}-{r8()}{suffix}", True
        elif kind == 2:      # a user's look-alike
            p, mine = res / f".{name}.{rng.choice(['bak', 'orig', 'tmp', 'swp'])}", False
        elif kind == 3:      # another writer's temp file
            p, mine = res / f".{name}.tmp-{other}-{r8()}", False
        elif kind == 4:      # the killed writer's PID on a name the marker does not list
            p, mine = res / f".notes.txt.tmp-{stale}-{r8()}", False
        elif kind == 5:      # the killed writer's results folder, built beside
            p, mine = tmp_path / f".res.{rng.choice(['tmp', 'old'])}-{stale}-" \
                f"{rng.getrandbits(32):08x}", True
        elif kind == 6:      # another folder's or another writer's
            p, mine = tmp_path / rng.choice([f".res.tmp-{other}-beef", f".rez.tmp-{stale}-beef"]), \
                False
        elif kind == 7:      # named as the killed writer's temp but a link: the link goes
            p, mine = res / f".{name}.tmp-{stale}-{r8()}", True
        else:                # a user's file at the top
            p, mine = tmp_path / f"user-{r8()}.txt", False
        if p.exists() or p.is_symlink():
            continue
        if kind == 5 or (kind == 6 and rng.random() < 0.5):
            p.mkdir()
            (p / "x").write_text("x")
        elif kind == 7:
            p.symlink_to(victim)
        else:
            p.write_text(f"{kind}")
        if mine and record == "record":
            expect.add(str(p.relative_to(tmp_path)))
    lock = tmp_path / ".res.lock"
    if record == "record":
        lock.write_text(f"paintcell validate (pid {stale}, since 10:00:00)")
    elif record == "garbage":
        lock.write_text("\x00\x01 not a paintcell record")
    before = snapshot(tmp_path)
    with lock_results(res, "validate"):
        pass
    after = snapshot(tmp_path)
    gone = {k for k in set(before) - set(after) if not k.startswith(tuple(
        f"{e}/" for e in expect))} - {".res.lock"}
    assert gone == expect
    assert all(before[k] == v for k, v in after.items())
    assert victim.read_text() == "victim"


# --- the report ---------------------------------------------------------------------------------

def _png(rgb: tuple[int, int, int]) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (6, 6), rgb).save(buf, "PNG")
    return buf.getvalue()


@pytest.mark.parametrize("seed", range(8))
def test_the_report_embeds_only_listed_regular_images(tmp_path: Path, seed: int) -> None:
    rng = random.Random(100 + seed)
    secret = tmp_path / "secret.png"
    secret.write_bytes(_png((1, 2, 3)))
    res = tmp_path / "res"
    listed = {f"plot_{i}.png": _png((10 * i, 200, seed)) for i in range(rng.randint(1, 4))}
    metrics = {"passed": False, "checks": [], "scenario": {"name": f"fz{seed}"}}
    with new_results(res, "run") as tmp:
        (tmp / "metrics.json").write_text(json.dumps(metrics))  # type: ignore[operator]
        for n, b in listed.items():
            (tmp / n).write_bytes(b)  # type: ignore[operator]
    planted: list[str] = []
    for j in range(rng.randint(1, 5)):
        n = rng.choice(["render_executed_spec.png", f"zz_{j}.png", f"render_{j}.gif",
                        "thickness_maps.png", f"robot_{j}.png"])
        if (res / n).exists() or (res / n).is_symlink():
            continue
        kind = rng.randrange(4)
        if kind == 0:
            (res / n).symlink_to(secret)
        elif kind == 1:
            (res / n).write_bytes(_png((250, 0, j)))   # regular, but the marker does not list it
        elif kind == 2:
            os.mkfifo(res / n)
        else:
            (res / n).symlink_to(tmp_path / "missing.png")
        planted.append(n)
    t0 = time.monotonic()
    assert main(["report", str(res)]) == 0
    assert time.monotonic() - t0 < 30
    doc = (res / "report.html").read_text()
    uris = re.findall(r'src="data:image/(?:png|gif|jpeg);base64,([^"]+)"', doc)
    embedded = {base64.b64decode(u) for u in uris}
    assert _png((1, 2, 3)) not in embedded          # the link's target never travels
    assert set(listed.values()) <= embedded
    assert not any(_png((250, 0, j)) in embedded for j in range(6))
    for n in planted:
        assert f"<code>{n}</code>" not in doc and f'alt="{n}"' not in doc


# --- texts bound for RAPID ----------------------------------------------------------------------

HOSTILE = ["\n", "\r\n", "\r", "\x00", "\x07", "\x1b[2J", "\x7f", "\x85", "\u2028", "\u2029",
           "\t", "  PROC evil()", "ENDPROC", "SetDO doBrush, 1;", "MoveAbsJ jHome, v1000, fine, "
           "tBell;", "ENDMODULE", "!", ";", "σ/μ ≤ 4", "µm", "\ufeff", "é", "日本", "'", '"',
           "\\", "%%%", " "]


def _rapid_keywords() -> set[str]:
    """Every keyword rapidchecker's grammar knows (an independent list of RAPID's)."""
    import warnings

    with warnings.catch_warnings():   # rapidchecker uses pyparsing's pre-3.1 names
        warnings.simplefilter("ignore", DeprecationWarning)
        import rapidchecker.parser.tokens as tokens
        from rapidchecker.parser.tokens import RapidKeyword

    return {v.match for v in vars(tokens).values() if isinstance(v, RapidKeyword)}


@pytest.mark.parametrize("seed", range(12))
def test_no_hostile_text_injects_a_rapid_line(seed: int) -> None:
    from types import SimpleNamespace

    rng = random.Random(200 + seed)
    keywords = sorted(_rapid_keywords())
    texts = ["".join(rng.choice(HOSTILE + [rng.choice(string.printable)])
                     for _ in range(rng.randint(1, 12))) for _ in range(rng.randint(1, 4))]
    name = rng.choice([rng.choice(keywords), rng.choice(keywords).lower(), "9lives", "",
                       "a" * 40, "door-left v2", "ENDMODULE", "main", "tBell"]
                      + texts[:1])
    for t in texts:
        c = comment_text(t)
        assert all(" " <= ch <= "~" for ch in c) and len(c) <= 200
    robot = SimpleNamespace(T_world_base=np.eye(4), T_flange_tcp=np.eye(4))
    text = rapid_module(small_program(), robot, module_name=name, max_spacing_m=0.2,
                        load=(5.0, np.zeros(3)), validation=texts)
    tokens = flat(rapid_parse(text))
    assert tokens[0] == "MODULE"
    mod = str(tokens[1])
    assert mod.upper() not in {k.upper() for k in keywords}
    assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", mod)
    assert [tokens[i + 1] for i, t in enumerate(tokens) if t == "PROC"] == ["main"]
    assert tokens.count("ENDMODULE") == 1 and tokens[-1] == "ENDMODULE"
    assert "evil" not in tokens and "SetDO" not in tokens
    lines = text.splitlines()
    assert all(" " <= ch <= "~" for ln in lines for ch in ln)
    # the two fixed header lines, one per text, "! pass 0": no text made a second line
    assert sum(ln.lstrip().startswith("!") for ln in lines) == 3 + len(texts)


# --- verdicts taken from data, never from metrics.json ------------------------------------------

def _metrics(rng: random.Random) -> dict[str, float]:
    return {"reachability_pct": 100.0, "n_collisions": 0, "executed_nsd_pct": rng.uniform(1, 5),
            "loss_pp": rng.uniform(-0.3, 0.3), "abs_loss_pp": rng.uniform(0, 0.3),
            "executed_cycle_time_s": rng.uniform(5, 60), "tracking_error_max_mm": 1.0,
            "speed_error_rms_pct": 1.0, "max_torque_utilization": rng.uniform(0.2, 0.9),
            "max_joint_range_utilization": rng.uniform(0.2, 0.9), "reachability_verdict": ""}


TAMPERS = ("none", "flip_passed", "flip_check", "nan", "null", "text", "bool", "nudge", "drop",
           "extra", "no_passed", "passed_text", "inf", "rename")


@pytest.mark.parametrize("tamper", TAMPERS)
@pytest.mark.parametrize("fails", [False, True])
def test_validated_only_when_the_data_pass_and_metrics_json_agrees(tamper: str,
                                                                   fails: bool) -> None:
    rng = random.Random(f"{tamper}-{fails}")
    m = _metrics(rng)
    th = Thresholds(max_executed_nsd_pct=0.5 if fails else 20.0)
    checks = threshold_checks(m, th)
    rep = ValidationReport(metrics=m, checks=tuple(checks), reachability=None, collisions=(),
                           joint_range_utilization=(), torque_utilization=())
    recorded = json.loads(json.dumps(rep.to_dict()))     # what `run` writes into metrics.json
    c = rng.choice(recorded["checks"])
    if tamper == "flip_passed":
        recorded["passed"] = not recorded["passed"]
    elif tamper == "flip_check":
        c["passed"] = not c["passed"]
    elif tamper in ("nan", "inf"):
        c["value"] = math.nan if tamper == "nan" else math.inf
    elif tamper in ("null", "text", "bool"):
        c["value"] = {"null": None, "text": str(c["value"]), "bool": True}[tamper]
    elif tamper == "nudge":
        c["value"] = c["value"] * (1 + 1e-3) + 1e-3
    elif tamper == "drop":
        recorded["checks"].remove(c)
    elif tamper == "extra":
        recorded["checks"].append({"name": "made up", "value": 0, "limit": 1, "passed": True})
    elif tamper == "no_passed":
        del recorded["passed"]
    elif tamper == "passed_text":
        recorded["passed"] = "true"
    elif tamper == "rename":
        c["name"] += " "
    recorded = json.loads(json.dumps(recorded))          # NaN/inf through JSON, as on disk
    mism = recorded_mismatches(recorded, checks, rep.passed)
    head = validation_header(checks, "0" * 64, mism)
    validated = head[0].startswith("VALIDATED")
    assert validated == (tamper == "none" and not fails)
    assert (mism == []) == (tamper == "none")
    if not validated:
        assert "NOT VALIDATED" in head[0] and len(head) == 3


# --- the robot-model cache ----------------------------------------------------------------------

POISONS = ("flip_byte", "truncate", "append", "empty", "link", "fifo", "loose_dir_mode")


@pytest.mark.parametrize("poison", POISONS)
def test_a_poisoned_cache_entry_is_rebuilt(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            poison: str) -> None:
    from paintcell.robots.robot import write_generated_mjcf

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    rng = random.Random(poison)
    xml = "<mujoco>" + "".join(f'<!-- {rng.random()} -->' for _ in range(20)) + "</mujoco>"
    path = write_generated_mjcf(xml, "arm")
    assert hashlib.sha256(path.read_bytes()).hexdigest()[:16] in path.name
    elsewhere = tmp_path / "elsewhere.xml"
    elsewhere.write_text(xml.replace("mujoco", "evil"))
    data = path.read_bytes()
    if poison == "flip_byte":
        i = rng.randrange(len(data))
        path.write_bytes(data[:i] + bytes([data[i] ^ 0x20]) + data[i + 1:])
    elif poison == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif poison == "append":
        path.write_bytes(data + b"<!-- x -->")
    elif poison == "empty":
        path.write_bytes(b"")
    elif poison in ("link", "fifo"):
        path.unlink()
        if poison == "link":
            path.symlink_to(elsewhere)
        else:
            os.mkfifo(path)
    else:
        os.chmod(path.parent, 0o777)
    t0 = time.monotonic()
    again = write_generated_mjcf(xml, "arm")
    assert again == path and not path.is_symlink() and path.read_text() == xml
    assert stat.S_IMODE(path.parent.stat().st_mode) == 0o700
    assert elsewhere.read_text() == xml.replace("mujoco", "evil")
    assert time.monotonic() - t0 < 5
