"""Shared pieces of the trust-boundary tests: the CLI as a real process, folder snapshots, a dead
PID, a small joint program for RAPID modules and the independent RAPID grammar check
(`rapidchecker`, a pyparsing grammar of RAPID written apart from paintcell)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from paintcell.motion.joint_trajectory import APPROACH, PAINT, RETRACT, JointTrajectory

ROOT = Path(__file__).resolve().parents[1]


def env(**extra: str) -> dict[str, str]:
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [e.get("PYTHONPATH")])])
    e.update(extra)
    return e


def cli(*args: str, cwd: Path, timeout: float = 120,
        **extra: str) -> subprocess.CompletedProcess[str]:
    """`python -m paintcell ARGS` as a real process; a hang fails the test (TimeoutExpired)."""
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout, env=env(**extra))


def snapshot(d: Path) -> dict[str, str]:
    """Relative path → file type and SHA-256 (regular files) or link target, never following."""
    out: dict[str, str] = {}
    for p in sorted(d.rglob("*")):
        rel = str(p.relative_to(d))
        if p.is_symlink():
            out[rel] = "link:" + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        elif p.is_dir():
            out[rel] = "dir"
        else:
            out[rel] = "special"
    return out


def dead_pid() -> int:
    """The PID of a process that has ended (a killed writer's)."""
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def small_program(n_pass: int = 40, dt_s: float = 0.01) -> JointTrajectory:
    """One straight 0.4 m pass along world y at x = 1.2 m, with approach and retract: a module
    of a handful of targets (the grammar check costs ~0.1 s a target)."""
    seg = np.r_[np.full(5, APPROACH), np.full(n_pass, PAINT), np.full(5, RETRACT)]
    k = len(seg)
    pos = np.c_[np.full(k, 1.2), np.linspace(-0.2, 0.2, k), np.full(k, 1.0)]
    R = np.zeros((k, 3, 3))
    R[:, :, 2] = [1.0, 0.0, 0.0]
    R[:, :, 0] = [0.0, 1.0, 0.0]
    R[:, :, 1] = np.cross(R[:, :, 2], R[:, :, 0])
    q = np.zeros((k, 6))
    q[:, 0] = np.linspace(-0.1, 0.1, k)
    q[:, 4] = 0.5
    paint = seg == PAINT
    return JointTrajectory(
        t_s=np.arange(k) * dt_s, q=q, qd=np.gradient(q, dt_s, axis=0), qdd=np.zeros((k, 6)),
        tcp_pos_world=pos, tcp_rot_world=R, v_tcp_planned=np.where(paint, 0.4, 0.0),
        paint_on=paint, pass_index=np.where(paint, 0, -1), segment=seg,
        s_pass_m=np.full(k, np.nan), robot_name="test",
        joint_names=tuple(f"j{i}" for i in range(6)))


def rapid_parse(text: str) -> list[object]:
    """The module parsed by rapidchecker's RAPID grammar (a syntax error raises) as a token list;
    its whitespace and indentation findings must be none (what `rapidchecker FILE` reports)."""
    import warnings

    with warnings.catch_warnings():   # rapidchecker uses pyparsing's pre-3.1 names
        warnings.simplefilter("ignore", DeprecationWarning)
        from rapidchecker.parser.grammar import module
        from rapidchecker.parser.indent import reset_level
        from rapidchecker.whitespace_checks import check_whitespace

        reset_level()
        tokens = list(module.parse_string(text, parse_all=True).as_list())
    errors = [str(e) for e in check_whitespace(text)]
    assert errors == [], errors
    return tokens


def flat(tokens: list[object]) -> list[object]:
    out: list[object] = []
    for t in tokens:
        out.extend(flat(t) if isinstance(t, list) else [t])  # type: ignore[arg-type]
    return out
