"""A scenario's process group, from both sides: `paintcell check` starts each scenario as the
leader of a new process group (setsid) and stops the whole group (SIGTERM, SIGKILL after a
grace period) on a time-out, on an interrupt and when the scenario ends (what it left
running); the scenario's process (`paintcell run --parent-pid`) asks the kernel for SIGTERM
when the check dies (Linux `PR_SET_PDEATHSIG`) and kills the rest of its own group on its way out.

A group's id is its leader's pid, which the kernel keeps reserved until the leader is reaped, so a
group is signalled only while its leader is unreaped (`waitid(WNOWAIT)` waits without reaping).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["GRACE_S", "Children", "scenario_worker", "stop_group", "wait_exit"]

GRACE_S = 5.0   # between SIGTERM and SIGKILL of a scenario's process group [s]

# The group's id is its leader's pid, reserved until the leader is reaped: the group is signalled
# only while the leader is unreaped (a zombie at most), and reaped under this lock after.
_REAP = threading.Lock()


def _exited(proc: subprocess.Popen[bytes]) -> bool:
    """Whether `proc` has ended, without reaping it (Linux `waitid(WNOWAIT)`)."""
    if proc.returncode is not None:
        return True
    if not hasattr(os, "waitid"):
        return proc.poll() is not None
    try:
        return os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True


def wait_exit(proc: subprocess.Popen[bytes], timeout_s: float | None) -> bool:
    """Wait up to `timeout_s` (None: for ever) for `proc` to end, unreaped; whether it ended."""
    t_end = None if timeout_s is None else time.monotonic() + timeout_s
    delay = 0.001
    while not _exited(proc):
        if t_end is not None and time.monotonic() >= t_end:
            return False
        time.sleep(delay if t_end is None else min(delay, max(t_end - time.monotonic(), 0)))
        delay = min(2 * delay, 0.05)
    return True


def stop_group(proc: subprocess.Popen[bytes], grace_s: float = GRACE_S) -> None:
    """Stop the process group that `proc` leads: SIGTERM (a paintcell run cleans up and exits),
    SIGKILL after `grace_s`, and SIGKILL for whatever of the group is left once `proc` ended;
    then reap `proc`."""
    with _REAP:
        running = proc.returncode is None and not _exited(proc)
        if running:
            _signal_group(proc.pid, signal.SIGTERM)
    if running:
        wait_exit(proc, grace_s)
    with _REAP:
        if proc.returncode is None:
            _signal_group(proc.pid, signal.SIGKILL)
            proc.wait()


def _signal_group(pgid: int, sig: signal.Signals) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass   # the group is gone (a PermissionError: its last member is exiting)


class Children:
    """The check's running scenario processes, so that every way out stops each group."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._procs: set[subprocess.Popen[bytes]] = set()
        self.closed = False

    def add(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._procs.add(proc)
            closed = self.closed
        if closed:   # started while the check was stopping
            stop_group(proc)

    def discard(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._procs.discard(proc)

    def stop_all(self) -> None:
        with self._lock:
            self.closed = True
            procs = list(self._procs)
        with _REAP:   # SIGTERM to every group first, so that they stop in parallel
            for proc in procs:
                if proc.returncode is None and not _exited(proc):
                    _signal_group(proc.pid, signal.SIGTERM)
        for proc in procs:
            stop_group(proc)


@contextmanager
def scenario_worker(parent_pid: int) -> Iterator[None]:
    """What `paintcell run --parent-pid PID` (the check's child) does around its work: SIGTERM
    when the check dies (Linux `PR_SET_PDEATHSIG`; a check already gone: at once), and on the
    way out SIGKILL to every other process of its own group (what the scenario started)."""
    _die_with_parent(parent_pid)
    try:
        yield
    finally:
        if os.getpgrp() == os.getpid():
            _kill_own_group()


def _die_with_parent(parent_pid: int) -> None:
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM))
    if os.getppid() != parent_pid:   # the check died before the request took effect
        os.kill(os.getpid(), signal.SIGTERM)


def _kill_own_group() -> None:
    me, group = os.getpid(), os.getpgrp()
    for entry in Path("/proc").iterdir() if Path("/proc/self").exists() else []:
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        if int(stat.rpartition(")")[2].split()[2]) == group:
            try:
                os.kill(int(entry.name), signal.SIGKILL)
            except OSError:
                pass
