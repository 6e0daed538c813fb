"""Fuzz cases of the command line's front door and of `paintcell check` as a CI gate.

Real processes and real signals: options of every sub-command (generated and hand-picked bad
values), OS and decode errors (a full tmpfs, a read-only mount, a folder where a file belongs,
link loops, non-UTF-8 and BOM TOML files, meshes with inf vertices or cut short), scenarios that
hang, fork a process that outlives them, ignore SIGTERM or print control characters, and SIGINT,
SIGTERM and SIGKILL sent to `check` at seeded random moments. Each case asserts the exit code,
the one line on stderr naming the file or option, the JUnit file as read by an independent
reader (junitparser) and that no process of check's process groups is left. Long cases carry
the `fuzz_full` marker (`make fuzz`); the rest is the fast slice of `make test`.
"""

from __future__ import annotations

import argparse
import errno
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import psutil
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from junitparser import Error, JUnitXml, TestSuite

from paintcell.cli.common import EXIT_INTERRUPTED, EXIT_USAGE
from paintcell.cli.main import build_parser, error_line, main

ROOT = Path(__file__).resolve().parents[2]

# Scenario scripts (a .py scenario is code: it runs when paintcell loads it). One that starts a
# child process writes the child's pid beside itself (SCRIPT.py.pid), so the test can follow it.
HANG = "import time\ntime.sleep(600)\n"
_SPAWN = ("import subprocess\np = subprocess.Popen(['sleep', '600'])\n"
          "open(__file__ + '.pid', 'w').write(str(p.pid))\n")
FORK_HANG = _SPAWN + "import time\ntime.sleep(600)\n"
FORK_EXIT = _SPAWN + "raise SystemExit(0)\n"
STUBBORN = ("import signal\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\n" + _SPAWN
            + "import time\ntime.sleep(600)\n")
NASTY = "raise RuntimeError('bad \\x1b[31mred\\x1b[0m \\x00nul \\x07bel <&> ]]> \\x1f')\n"


def _env(tmp: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    (tmp / "tmp").mkdir(exist_ok=True)
    env["TMPDIR"] = str(tmp / "tmp")   # every temporary file of check and its children
    return env


def _cli(tmp: Path, *args: str, timeout: float = 120,
         **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=tmp, timeout=timeout, env=_env(tmp), **kw)  # type: ignore[call-overload]


def _start(tmp: Path, *args: str) -> subprocess.Popen[str]:
    """`paintcell ARGS` leading its own process group (as a CI job runs it)."""
    return subprocess.Popen([sys.executable, "-m", "paintcell", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp, env=_env(tmp),
                            start_new_session=True)


def _wait_for(pred: Callable[[], object], timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not pred():
        assert time.monotonic() - t0 < timeout, "timed out waiting"
        time.sleep(0.05)


def _one_line(err: str) -> str:
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert "Traceback" not in err and "Warning" not in err, err
    return err


def _scenarios(tmp: Path, **files: str) -> Path:
    d = tmp / "scn"
    d.mkdir(exist_ok=True)
    for name, text in files.items():
        (d / f"{name}.py").write_text(text)
    return d


# --- processes ------------------------------------------------------------------------------

def _live(p: psutil.Process) -> bool:
    try:
        return p.status() != psutil.STATUS_ZOMBIE   # a zombie has ended; only its entry is left
    except psutil.NoSuchProcess:
        return False


def _descendants(pid: int) -> list[psutil.Process]:
    try:
        return [p for p in psutil.Process(pid).children(recursive=True) if _live(p)]
    except psutil.NoSuchProcess:
        return []


def _groups_of(procs: list[psutil.Process]) -> set[int]:
    out = set()
    for p in procs:
        try:
            out.add(os.getpgid(p.pid))
        except ProcessLookupError:
            pass
    return out


def _left_in(groups: set[int]) -> list[str]:
    """Live processes whose process group is one of `groups`."""
    left = []
    for p in psutil.process_iter(["pid", "cmdline"]):
        try:
            if os.getpgid(p.pid) in groups and _live(p):
                left.append(f"{p.pid}: {' '.join(p.info['cmdline'] or [])}")
        except (ProcessLookupError, psutil.NoSuchProcess):
            pass
    return left


def _assert_nothing_left(groups: set[int], timeout: float = 20.0) -> None:
    t0 = time.monotonic()
    while _left_in(groups) and time.monotonic() - t0 < timeout:
        time.sleep(0.1)
    assert not _left_in(groups), _left_in(groups)


def _watch(p: subprocess.Popen[str], until: Callable[[list[psutil.Process]], bool],
           timeout: float = 60.0) -> set[int]:
    """Process groups of `p` and of its descendants, gathered until `until(descendants)`."""
    groups = {p.pid}
    t0 = time.monotonic()
    while True:
        kids = _descendants(p.pid)
        groups |= _groups_of(kids)
        if until(kids):
            return groups
        assert p.poll() is None, p.communicate()
        assert time.monotonic() - t0 < timeout, "timed out waiting for the scenario processes"
        time.sleep(0.05)


def _has_sleep(n: int = 1) -> Callable[[list[psutil.Process]], bool]:
    def pred(kids: list[psutil.Process]) -> bool:
        try:
            return sum(1 for k in kids if k.name() == "sleep") >= n
        except psutil.NoSuchProcess:
            return False
    return pred


def _spawned(d: Path) -> list[int]:
    """The pids of the child processes the scenarios in `d` started (their .pid files)."""
    return [int(f.read_text()) for f in sorted(d.glob("*.py.pid"))]


def _assert_dead(pids: list[int], timeout: float = 20.0) -> None:
    def live() -> list[int]:
        out = []
        for pid in pids:
            try:
                if _live(psutil.Process(pid)):
                    out.append(pid)
            except psutil.NoSuchProcess:
                pass
        return out
    t0 = time.monotonic()
    while live() and time.monotonic() - t0 < timeout:
        time.sleep(0.1)
    assert not live(), live()


# --- JUnit ----------------------------------------------------------------------------------

def _suite(path: Path) -> TestSuite:
    ET.parse(path)   # well-formed XML 1.0 for a strict parser too
    x = JUnitXml.fromfile(str(path))
    suites = [x] if isinstance(x, TestSuite) else list(x)
    assert len(suites) == 1
    return suites[0]


def _errors(path: Path) -> dict[str, str]:
    """Each test case with an error result: name -> message."""
    return {c.name: r.message for c in _suite(path) for r in c.result if isinstance(r, Error)}


def _green(path: Path) -> bool:
    s = _suite(path)
    return s.errors == 0 and s.failures == 0 and all(not c.result for c in s)


# --- options --------------------------------------------------------------------------------

BASE = {"check": ["check", "x"], "inspect": ["inspect", "x.stl"],
        "init": ["init", "x.stl", "--out", "x.toml"], "generate": ["generate", "door", "--out",
                                                                   "x.stl"],
        "export": ["export", "d", "--rapid"], "sweep": ["sweep", "x.toml"],
        "run": ["run", "x.toml"]}


def _numeric_options() -> list[tuple[str, str, str]]:
    """(sub-command, option, a value it accepts) of every option whose type reads a number."""
    out = []
    sub = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    for cmd, parser in sub.items():
        for a in parser._actions:
            if getattr(a.type, "allowed", None) and a.option_strings:
                out.append((cmd, a.option_strings[0], a.type.example))  # type: ignore[union-attr]
    return out


def test_every_numeric_option_is_range_checked() -> None:
    """No sub-command reads a number with a bare int/float: each goes through a range check."""
    sub = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    bare = [(cmd, a.dest) for cmd, p in sub.items() for a in p._actions if a.type in (int, float)]
    assert bare == []
    names = {(cmd, opt) for cmd, opt, _ in _numeric_options()}
    assert {("check", "--timeout"), ("check", "--jobs"), ("inspect", "--resolution"),
            ("init", "--robots"), ("export", "--spacing"), ("sweep", "--samples"),
            ("sweep", "--seed"), ("sweep", "--workers"), ("generate", "--seed")} <= names


BAD = ["-1", "-5", "nan", "inf", "-inf", "1e400", "abc", "", "1e5000", "0x10", "-0.0", "1.5e"]


@pytest.mark.parametrize("cmd,opt,good", _numeric_options())
def test_bad_numbers_are_usage_errors_naming_the_option(cmd: str, opt: str, good: str,
                                                        capsys: pytest.CaptureFixture[str]) \
        -> None:
    parser = build_parser()
    args = parser.parse_args([*BASE[cmd], f"{opt}={good}"])
    assert getattr(args, opt.lstrip("-").replace("-", "_")) is not None
    allowed = parser._subparsers._group_actions[0].choices[cmd]  # type: ignore[union-attr]
    rule = next(a.type.allowed for a in allowed._actions if opt in a.option_strings)
    for bad in BAD:
        try:
            value = float(bad)
        except ValueError:
            value = None
        if value is not None and value == 0 and "≥ 0" in rule:
            continue   # zero is meaningful here (e.g. --jobs 0: one per CPU core)
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([*BASE[cmd], f"{opt}={bad}"])
        assert exc.value.code == EXIT_USAGE
        err = _one_line(capsys.readouterr().err)
        assert err.startswith(f"paintcell: error: argument {opt}") and rule in err, err


_TIMEOUT = [a for a in build_parser()._subparsers._group_actions[0]  # type: ignore[union-attr]
            .choices["check"]._actions if "--timeout" in a.option_strings][0].type


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.integers(-10**30, 10**30).map(str), st.text(max_size=12)))
def test_timeout_accepts_exactly_the_finite_positive_numbers(text: str) -> None:
    """Generated values: the option takes a value iff it is a finite number of seconds > 0,
    surrounding whitespace aside (str.strip's, which is wider than float()'s: '1\x1f' is 1 s)."""
    try:
        truth = float(text.strip())
        ok = truth > 0 and truth != float("inf")
    except ValueError:
        ok = False
    try:
        got = _TIMEOUT(text)
    except argparse.ArgumentTypeError as exc:   # argparse turns it into exit 2
        assert not ok and "out of range" in str(exc) and "> 0 s" in str(exc)
    else:
        assert ok and got == float(text.strip())


def test_reported_option_cases_in_a_real_process(tmp_path: Path) -> None:
    """The reported commands: exit 2, one line naming the option and the allowed range, and the
    --junit file says so (an earlier run's green file is replaced)."""
    d = _scenarios(tmp_path, a=HANG)
    junit = tmp_path / "j.xml"
    junit.write_text('<testsuite name="old" tests="1" failures="0" errors="0">'
                     '<testcase name="old"/></testsuite>')
    assert _green(junit)
    for value in ("-5", "nan"):
        out = _cli(tmp_path, "check", str(d), "--timeout", value, "--junit", str(junit))
        assert out.returncode == EXIT_USAGE and out.stdout == ""
        assert "argument --timeout: " in _one_line(out.stderr) and "> 0 s" in out.stderr
        assert not _green(junit) and "--timeout" in _errors(junit)["usage"]
    # An error of the check itself (a missing folder) is in the JUnit file too.
    out = _cli(tmp_path, "check", str(tmp_path / "nope"), "--junit", str(junit))
    assert out.returncode == EXIT_USAGE and f"{tmp_path / 'nope'} does not exist" in \
        _one_line(out.stderr)
    assert _errors(junit) == {"error": f"paintcell check stopped: scenario path "
                                       f"{tmp_path / 'nope'} does not exist"}
    for value in ("-1", "nan"):
        out = _cli(tmp_path, "inspect", "x.stl", "--resolution", value)
        assert out.returncode == EXIT_USAGE and "argument --resolution: " in _one_line(out.stderr)
        assert "≥ 0 and ≤ 1 m" in out.stderr


# --- OS and decode errors -------------------------------------------------------------------

def _can_unshare() -> bool:
    return shutil.which("unshare") is not None and subprocess.run(
        ["unshare", "-rm", "true"], capture_output=True).returncode == 0


def _in_tmpfs(tmp: Path, mount: Path, options: str, shell: str) -> subprocess.CompletedProcess[str]:
    """Run `shell` with a small tmpfs mounted at `mount` (a private mount namespace)."""
    mount.mkdir()
    script = f"mount -t tmpfs -o {options} tmpfs {mount} && {shell}"
    return subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True,
                          cwd=tmp, env=_env(tmp), timeout=120)


@pytest.mark.skipif(not _can_unshare(), reason="needs unshare -rm (a user + mount namespace) "
                    "to mount a small tmpfs")
def test_full_disk_and_read_only_mounts(tmp_path: Path) -> None:
    d = _scenarios(tmp_path, a=HANG)
    py = f"{sys.executable} -m paintcell"
    # A full disk: --junit refused before any scenario runs, naming the option, path and fix.
    full = tmp_path / "full"
    out = _in_tmpfs(tmp_path, full, "size=16k",
                    f"dd if=/dev/zero of={full}/fill bs=1k count=64 2>/dev/null; "
                    f"{py} check {d} --junit {full}/j.xml")
    assert out.returncode == EXIT_USAGE and out.stdout == "", out
    assert f"--junit {full}/j.xml cannot be written ({full}/" in _one_line(out.stderr)
    assert "no space left" in out.stderr
    assert "no scenario was run" in out.stderr
    out = _in_tmpfs(tmp_path, tmp_path / "full2", "size=16k",
                    f"dd if=/dev/zero of={tmp_path}/full2/fill bs=1k count=64 2>/dev/null; "
                    f"{py} generate door --out {tmp_path}/full2/door.stl")
    assert out.returncode == EXIT_USAGE and f"{tmp_path}/full2/" in _one_line(out.stderr)
    assert "no space left on the device; free space there" in out.stderr
    ro = tmp_path / "ro"
    out = _in_tmpfs(tmp_path, ro, "size=1m,ro", f"{py} check {d} --junit {ro}/j.xml")
    assert out.returncode == EXIT_USAGE and f"--junit {ro}/j.xml cannot be written ({ro}/" in \
        _one_line(out.stderr)
    assert "read-only file system; write to another folder" in out.stderr


def test_unwritable_junit_paths_are_refused_before_any_scenario(tmp_path: Path) -> None:
    trace = tmp_path / "ran.txt"
    d = _scenarios(tmp_path, a=f"open({str(trace)!r}, 'w').write('ran')\n" + HANG)
    (tmp_path / "plain").write_text("a file")
    for junit, says in ((tmp_path, "is a folder; give a file path"),
                        (tmp_path / "plain" / "j.xml", "a part of the path is a file, not a "
                         "folder; fix the path")):
        out = _cli(tmp_path, "check", str(d), "--junit", str(junit), "--timeout", "5")
        assert out.returncode == EXIT_USAGE and out.stdout == ""
        assert "--junit" in _one_line(out.stderr) and str(junit) in out.stderr, out.stderr
        assert says in out.stderr, out.stderr
    assert not trace.exists()


def _without_root_powers() -> list[str] | None:
    """A command prefix under which permission bits hold (root: without the capabilities that
    override them); None where that cannot be had."""
    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv") is None:
        return None
    drop = "-dac_override,-dac_read_search,-fowner"
    return ["setpriv", "--bounding-set", drop, "--inh-caps", drop]


@pytest.mark.skipif(_without_root_powers() is None, reason="root without setpriv: permission "
                    "bits do not apply")
def test_permission_denied_names_the_path(tmp_path: Path) -> None:
    """EACCES: a folder without write permission for the --junit file."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    d = _scenarios(tmp_path, a=HANG)
    prefix = _without_root_powers() or []
    cmd = [*prefix, sys.executable, "-m", "paintcell", "check", str(d), "--junit",
           str(locked / "j.xml")]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, env=_env(tmp_path),
                         timeout=120)
    assert out.returncode == EXIT_USAGE, out
    assert f"({locked}/j.xml: permission denied; make it" in _one_line(out.stderr), out.stderr
    assert os.listdir(locked) == []


def test_os_errors_from_the_os_become_one_line_with_the_path(tmp_path: Path) -> None:
    """Real OS errors (raised by the OS, not built by hand) through the CLI's one formatter."""
    made = []
    (tmp_path / "there").mkdir()
    calls: list[Callable[[], object]] = [
        lambda: os.mkdir(tmp_path / "there"),                                  # EEXIST
        lambda: open(tmp_path / "there", "w"),                                  # EISDIR
        lambda: os.write(os.open("/dev/full", os.O_WRONLY), b"x"),              # ENOSPC
        lambda: open(tmp_path / "missing" / "f.txt"),                           # ENOENT
    ]
    for call in calls:
        with pytest.raises(OSError) as exc:
            call()
        made.append((exc.value.errno, error_line(exc.value)))
    assert made[0][0] == errno.EEXIST and made[0][1] == f"{tmp_path / 'there'}: already " \
        "exists; remove it or choose another name"
    assert made[1][0] == errno.EISDIR and made[1][1].startswith(f"{tmp_path / 'there'}: is a "
                                                                "folder")
    assert made[2][0] == errno.ENOSPC and "no space left on the device" in made[2][1]
    assert made[3][0] == errno.ENOENT and str(tmp_path / "missing") in made[3][1]


def _in_process(capfd: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """`paintcell ARGS` run by `main` in this process (the imports are paid once): exit code
    and what reached file descriptor 2."""
    try:
        code = main(list(args))
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capfd.readouterr().err


def test_a_folder_where_a_file_belongs_is_named(tmp_path: Path,
                                                capfd: pytest.CaptureFixture[str]) -> None:
    """A folder where a file is to be written: refused in one line naming the folder the user
    named (not a temporary name), nothing written."""
    target = tmp_path / "door.stl"
    target.mkdir()
    code, err = _in_process(capfd, "generate", "door", "--out", str(target))
    assert code == EXIT_USAGE and f"paintcell: error: --out {target} is a folder" in _one_line(err)
    assert ".tmp" not in err
    assert os.listdir(tmp_path) == ["door.stl"] and os.listdir(target) == []


def test_link_loops_and_encodings(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    loop = tmp_path / "loop.stl"
    loop.symlink_to("loop.stl")
    code, err = _in_process(capfd, "init", str(loop), "--out", str(tmp_path / "x.toml"))
    assert code == EXIT_USAGE and _one_line(err) == (f"paintcell: error: {loop}: is a "
                                                     "symbolic-link loop; fix or remove the "
                                                     "link\n")
    assert not (tmp_path / "x.toml").exists()
    # A TOML file that is not UTF-8 (Latin-1 é on line 2): the file, the byte, the line.
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'name = "x"\n# caf\xe9\npart = "panel"\n')
    code, err = _in_process(capfd, "plan", str(latin), "--fast", "--out", str(tmp_path / "p"))
    assert code == EXIT_USAGE and not (tmp_path / "p").exists()
    assert _one_line(err) == (f"paintcell: error: {latin}: not UTF-8 text (byte 0xe9 on line "
                              "2); save the file as UTF-8\n")


def test_a_utf8_bom_is_accepted(tmp_path: Path) -> None:
    """A TOML scenario and a booth saved with a byte-order mark load as the same files without
    one."""
    import shutil

    from paintcell.app.scenario_files import load_scenario

    for name in ("panel.toml", "booth.toml"):
        text = (ROOT / "scenarios" / name).read_bytes()
        for kind, head in (("plain", b""), ("bom", b"\xef\xbb\xbf")):
            (tmp_path / kind).mkdir(exist_ok=True)
            (tmp_path / kind / name).write_bytes(head + text)
            # the booth's bell file, which the loader reads with it
            shutil.copytree(ROOT / "scenarios" / "bells", tmp_path / kind / "bells",
                            dirs_exist_ok=True)
        a = load_scenario(tmp_path / "plain" / name)
        b = load_scenario(tmp_path / "bom" / name)
        assert type(a) is type(b)
        da, db = a.to_dict(), b.to_dict()
        da.pop("source", None), db.pop("source", None)
        assert str(da).replace(f"{tmp_path}/plain/", f"{tmp_path}/bom/") == str(db)


def _stl(path: Path, triangles: list[list[list[float]]], count: int | None = None,
         cut: int | None = None) -> None:
    import numpy as np

    t = np.asarray(triangles, dtype="<f4")
    body = b"".join(np.zeros(3, "<f4").tobytes() + tri.tobytes() + b"\0\0" for tri in t)
    data = b"\0" * 80 + (len(t) if count is None else count).to_bytes(4, "little") + body
    path.write_bytes(data[:cut])


@pytest.mark.parametrize("case", ["inf", "nan", "truncated", "count_too_big", "empty"])
def test_broken_meshes_are_one_line_without_library_noise(tmp_path: Path, case: str,
                                                          capfd: pytest.CaptureFixture[str]) \
        -> None:
    """A mesh with inf or NaN vertices, cut short, with a wrong triangle count or empty: one
    line naming the file, no library warning (the inf case in its own process: what reaches a
    terminal), no picture written."""
    tri = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    bad = {"inf": [[float("inf"), 0, 0], [1, 1, 0], [0, 1, 0]],
           "nan": [[0, 0, 1], [1, 0, 1], [float("nan"), 1, 1]]}.get(case, tri)
    f = tmp_path / f"{case}.stl"
    _stl(f, [tri, bad, [[0, 0, 2], [1, 0, 2], [0, 1, 2]]],
         count={"count_too_big": 1000, "truncated": 1000}.get(case),
         cut={"truncated": 150, "empty": 0}.get(case))
    if case == "inf":
        out = _cli(tmp_path, "inspect", f.name, "--png", "r.png")
        code, err = out.returncode, out.stderr
    else:
        code, err = _in_process(capfd, "inspect", str(f), "--png", str(tmp_path / "r.png"))
    assert code == EXIT_USAGE and f.name in _one_line(err), err
    assert "internal error" not in err and "ModuleNotFoundError" not in err
    assert not (tmp_path / "r.png").exists()


# --- check: hung, forking, stubborn scenarios -------------------------------------------------

def _check(tmp: Path, d: Path, *extra: str, until: Callable[[list[psutil.Process]], bool]
           | None = None, timeout: float = 120) -> tuple[subprocess.Popen[str], str, str, set[int]]:
    p = _start(tmp, "check", str(d), "--junit", str(tmp / "j.xml"), *extra)
    groups = {p.pid}
    if until is not None:
        groups = _watch(p, until)
    t0 = time.monotonic()
    while p.poll() is None and time.monotonic() - t0 < timeout:
        groups |= _groups_of(_descendants(p.pid))
        time.sleep(0.1)
    out, err = p.communicate(timeout=10)
    return p, out, err, groups


def test_timeout_stops_a_scenario_and_every_process_it_started(tmp_path: Path) -> None:
    """A hung scenario, one whose child process hangs and one that ignores SIGTERM (and whose
    child would outlive it), at once: each is an error case after --timeout, and nothing of any
    process group is left."""
    d = _scenarios(tmp_path, a_hang=HANG, b_fork=FORK_HANG, d_stubborn=STUBBORN)
    t0 = time.monotonic()
    p, out, err, groups = _check(tmp_path, d, "--timeout", "5", "--jobs", "4")
    assert time.monotonic() - t0 < 60
    assert p.returncode == 1 and err == "", err
    assert len(groups) >= 4   # check's own and one per scenario
    _assert_nothing_left(groups)
    assert len(_spawned(d)) == 2   # both started their child before the time ran out
    _assert_dead(_spawned(d))
    errors = _errors(tmp_path / "j.xml")
    assert set(errors) == {"a_hang", "b_fork", "d_stubborn"}
    assert not _green(tmp_path / "j.xml")
    for name in ("a_hang", "b_fork", "d_stubborn"):
        assert errors[name] == ("exceeded --timeout 5 s and was stopped with every process it "
                                "started")
    assert os.listdir(tmp_path / "tmp") == []


def _xml_char(ch: str) -> bool:
    """The Char production of XML 1.0 (section 2.2)."""
    c = ord(ch)
    return c in (0x9, 0xA, 0xD) or 0x20 <= c <= 0xD7FF or 0xE000 <= c <= 0xFFFD \
        or 0x10000 <= c <= 0x10FFFF


_ANY_TEXT = st.text(st.characters(codec=None, exclude_characters="\x1b"), max_size=40)


@settings(max_examples=150, deadline=None)
@given(name=_ANY_TEXT.filter(lambda t: any(map(_xml_char, t))), message=_ANY_TEXT,
       failure=_ANY_TEXT, n_done=st.integers(0, 3))
def test_junit_of_any_text_reads_back(tmp_path_factory: pytest.TempPathFactory, name: str,
                                      message: str, failure: str, n_done: int) -> None:
    """Generated names and messages (any code point but ESC): the file is well-formed, and an
    independent reader gets back each text with exactly the characters XML cannot hold gone."""
    from paintcell.cli.junit import write_junit

    path = tmp_path_factory.mktemp("j") / "j.xml"
    keep = "".join(filter(_xml_char, message))
    checks = [{"name": failure, "value": 2.0, "limit": 1.0, "unit": "%", "passed": False}]
    cases = [(f"{name}{i}", 1.0, checks, None) for i in range(n_done)]
    cases.append((name, 0.5, [], message))
    write_junit(path, cases, suite_error=("interrupted", message))
    suite = _suite(path)
    assert suite.tests == n_done + 2 and suite.errors == 2 and suite.failures == n_done
    got = [(c.name, [(type(r).__name__, r.message) for r in c.result]) for c in suite]
    clean_name = "".join(filter(_xml_char, name))
    assert got[n_done] == (clean_name, [("Error", keep or None)]) or \
        got[n_done] == (clean_name, [("Error", keep)])   # an empty attribute may read as None
    assert got[-1][0] == "interrupted" and got[-1][1][0][0] == "Error"
    for i in range(n_done):
        assert got[i][0] == f"{clean_name}{i}" and got[i][1][0][0] == "Failure"
        assert "".join(filter(_xml_char, failure)) in (got[i][1][0][1] or "")
    assert not _green(path)


def test_a_child_that_outlives_its_scenario_does_not_hold_the_check(tmp_path: Path) -> None:
    """The scenario exits at once and leaves a `sleep 600` behind (with its stderr open): check
    ends with the scenario, and the sleep with it. Beside it, ESC, NUL, BEL and unit separator in
    a scenario's error: gone from the JUnit (which a strict XML parser and junitparser read) and
    from the table; <, & and ]]> are escaped."""
    d = _scenarios(tmp_path, fork=FORK_EXIT, nasty=NASTY)
    t0 = time.monotonic()
    p, out, err, groups = _check(tmp_path, d, "--jobs", "2")
    assert time.monotonic() - t0 < 60 and p.returncode == 1 and err == "", (out, err)
    assert "called sys.exit(0) while loading" in out
    _assert_nothing_left(groups)
    _assert_dead(_spawned(d))
    message = _errors(tmp_path / "j.xml")["nasty"]
    assert message.endswith("RuntimeError: bad red nul bel <&> ]]>"), message
    assert not any(ch in out + message for ch in "\x00\x07\x1b\x1f")
    assert "ERROR   cannot import scenario" in out and "bad red nul bel <&>" in out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_to_check_stops_everything_and_the_junit_says_interrupted(
        tmp_path: Path, sig: signal.Signals) -> None:
    _signal_case(tmp_path, sig, seed=int(sig), jobs=2)


def _signal_case(tmp: Path, sig: signal.Signals, seed: int, jobs: int) -> None:
    """`sig` at a seeded random moment once check has started its scenarios: exit 130, one line,
    a JUnit that is not green and names the interruption, no process left, no temp file."""
    rng = random.Random(seed)
    files = {f"s{i}": rng.choice([HANG, FORK_HANG]) for i in range(rng.randint(1, 4))}
    d = _scenarios(tmp, **files)
    p = _start(tmp, "check", str(d), "--junit", str(tmp / "j.xml"), "--jobs", str(jobs))
    groups = _watch(p, lambda kids: len(kids) >= 1)
    t_end = time.monotonic() + rng.uniform(0.0, 3.0)
    while time.monotonic() < t_end:
        groups |= _groups_of(_descendants(p.pid))
        time.sleep(0.05)
    os.kill(p.pid, sig)
    out, err = p.communicate(timeout=60)
    assert p.returncode == EXIT_INTERRUPTED, (out, err)
    assert _one_line(err) == f"paintcell: interrupted ({sig.name}); nothing half-written was " \
        "left\n"
    _assert_nothing_left(groups)
    _assert_dead(_spawned(d))
    junit = tmp / "j.xml"
    assert not _green(junit)
    errors = _errors(junit)
    stopped = set(errors) - {"interrupted"}
    assert stopped and stopped <= set(files)
    assert all(errors[n] == f"interrupted ({sig.name}) while running; no result" for n in stopped)
    assert errors["interrupted"].startswith(
        f"interrupted ({sig.name}): {len(files) - len(stopped)} scenario(s) not run")
    assert _suite(junit).errors == len(stopped) + 1
    assert os.listdir(tmp / "tmp") == []


def test_sigkill_of_check_leaves_no_scenario_running(tmp_path: Path) -> None:
    """SIGKILL cannot be caught: the scenarios learn of it from the kernel (their parent died)
    and end with everything they started; the JUnit file says the check did not finish."""
    d = _scenarios(tmp_path, a=FORK_HANG, b=FORK_HANG)
    p = _start(tmp_path, "check", str(d), "--junit", str(tmp_path / "j.xml"), "--jobs", "2")
    groups = _watch(p, _has_sleep(2))
    p.kill()
    p.communicate(timeout=30)
    _assert_nothing_left(groups)
    _assert_dead(_spawned(d))
    assert _errors(tmp_path / "j.xml") == {
        "incomplete": "paintcell check started and did not finish (killed, or still running)"}
    assert os.listdir(tmp_path / "tmp") == []


# --- the long cases (make fuzz) ---------------------------------------------------------------

@pytest.mark.fuzz_full
@pytest.mark.parametrize("seed", range(10))
def test_signals_at_random_points(tmp_path: Path, seed: int) -> None:
    rng = random.Random(1000 + seed)
    _signal_case(tmp_path, rng.choice([signal.SIGINT, signal.SIGTERM]), seed=1000 + seed,
                 jobs=rng.choice([1, 2, 3]))


@pytest.mark.fuzz_full
@pytest.mark.parametrize("jobs", [1, 2])
def test_an_interrupt_kills_a_scenario_that_ignores_sigterm(tmp_path: Path, jobs: int) -> None:
    """SIGTERM to check while a scenario that ignores SIGTERM runs: its group is SIGKILLed after
    the grace period; exit 130, nothing left, the JUnit says interrupted."""
    d = _scenarios(tmp_path, a=STUBBORN, b=HANG)
    p = _start(tmp_path, "check", str(d), "--junit", str(tmp_path / "j.xml"), "--jobs",
               str(jobs))
    groups = _watch(p, _has_sleep(1))
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=60)
    assert p.returncode == EXIT_INTERRUPTED, (out, err)
    _assert_nothing_left(groups)
    _assert_dead(_spawned(d))
    errors = _errors(tmp_path / "j.xml")
    assert errors["a"] == "interrupted (SIGTERM) while running; no result"
    assert errors["interrupted"].startswith("interrupted (SIGTERM): ")


@pytest.mark.fuzz_full
def test_a_part_file_that_is_a_fifo_ends_within_the_timeout(tmp_path: Path) -> None:
    """A TOML scenario (no code of its own) whose part file is a FIFO nobody writes: its run
    blocks or is refused; either way check ends within the timeout with an error case and
    nothing left."""
    d = tmp_path / "scn"
    d.mkdir()
    os.mkfifo(d / "part.stl")
    (d / "fifo.toml").write_text(FZ.replace('part = "panel"', 'part = "part.stl"'))
    t0 = time.monotonic()
    p, out, err, groups = _check(tmp_path, d, "--timeout", "20")
    assert p.returncode == 1 and err == "" and time.monotonic() - t0 < 90, (out, err)
    _assert_nothing_left(groups)
    assert set(_errors(tmp_path / "j.xml")) == {"fifo"}


@pytest.mark.fuzz_full
def test_a_passing_check_is_green_and_only_then(tmp_path: Path) -> None:
    """The positive control: a scenario that passes gives an all-green JUnit whose case carries
    the figures of the table's row; the same with a failing twin is not green."""
    d = tmp_path / "scn"
    d.mkdir()
    (d / "fz.toml").write_text(FZ)
    p, out, err, groups = _check(tmp_path, d, "--fast", timeout=600)
    assert p.returncode == 0, (out, err)
    junit = tmp_path / "j.xml"
    assert _green(junit) and [c.name for c in _suite(junit)] == ["fz"]
    row = out.splitlines()[2]
    assert row.split()[0] == "fz" and "PASS" in row
    # Each threshold of the row is in the case's output, with the same value and limit.
    system_out = list(_suite(junit))[0].system_out or ""
    shown = re.findall(r"\s*(.+?) (\S+) [≤≥] (\S+)", row.split("PASS", 1)[1].replace(";", "\n"))
    assert len(shown) == system_out.count("\n") + 1 >= 5, (shown, system_out)
    for name, value, limit in shown:
        assert f"{name}: {value} (limit {limit} " in system_out, (name, system_out)
    (d / "fz_tight.toml").write_text(FZ.replace('name = "fz"', 'name = "fz_tight"')
                                     .replace("max_executed_nsd_pct = 30.0",
                                              "max_executed_nsd_pct = 0.01"))
    p, out, err, groups = _check(tmp_path, d, "--fast", "--jobs", "2", timeout=600)
    assert p.returncode == 1 and not _green(junit)
    assert _suite(junit).failures == 1 and _suite(junit).errors == 0
    _assert_nothing_left(groups)


FZ = """\
name = "fz"
part = "panel"
fast_resolution_m = 0.04
[part_placement]
xyz_m = [1.4, 0.0, 1.0]
rpy_rad = [1.5707963267948966, 0.0, -1.5707963267948966]
[fast_planner]
sample_spacing_m = 0.04
[trajectory]
q_home = [0.0, -0.6, 0.3, 0.0, 0.9, 0.0]
[thresholds]
max_executed_nsd_pct = 30.0
max_loss_pp = 1.0
max_cycle_time_s = 90.0
"""


@pytest.mark.fuzz_full
@pytest.mark.parametrize("seed", range(3))
def test_sigkill_during_a_real_run_leaves_no_process_and_no_temp_folder(tmp_path: Path,
                                                                        seed: int) -> None:
    """A real scenario writing its results (--out) when check is SIGKILLed at a random moment:
    the run stops, removes its temporary folder and leaves nothing running."""
    d = tmp_path / "scn"
    d.mkdir()
    (d / "fz.toml").write_text(FZ)
    p = _start(tmp_path, "check", str(d), "--fast", "--out", str(tmp_path / "res"), "--junit",
               str(tmp_path / "j.xml"))
    res = tmp_path / "res"

    def writing(kids: list[psutil.Process]) -> bool:   # the run's temporary folder is there
        return res.is_dir() and any(".fz.tmp-" in q.name for q in res.iterdir())

    groups = _watch(p, writing, timeout=180)
    t_end = time.monotonic() + random.Random(seed).uniform(0.0, 3.0)
    while time.monotonic() < t_end and p.poll() is None:
        groups |= _groups_of(_descendants(p.pid))
        time.sleep(0.05)
    p.kill()
    p.communicate(timeout=30)
    _assert_nothing_left(groups, timeout=60)
    assert [q.name for q in res.iterdir() if ".tmp-" in q.name] == []
    assert os.listdir(tmp_path / "tmp") == []
    assert not _green(tmp_path / "j.xml")
