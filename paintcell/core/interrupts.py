"""Ctrl-C and SIGTERM that cannot be lost.

The signal handler raises `Interrupted` at once, but a library may swallow it: trimesh, for one,
imports its optional dependencies inside `try: … except BaseException`, so a signal that lands
during such an import is caught there and the run would carry on and exit 0. The handler therefore
also records the signal; `raise_if_interrupted()` re-raises it at the checkpoints that matter —
each pipeline stage, the moment before a results folder is swapped in, and the command's exit.
"""

from __future__ import annotations

import signal
from typing import Any

__all__ = ["Interrupted", "on_signal", "pending", "raise_if_interrupted", "reset"]


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM: the command stops, cleans up and exits 130."""


_pending: str | None = None


def on_signal(signum: int, frame: Any) -> None:
    """Signal handler: remember the signal, ignore further ones, raise `Interrupted`."""
    global _pending
    _pending = signal.Signals(signum).name
    # Further signals are ignored while the temp folder is removed; then the process exits.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Interrupted(_pending)


def pending() -> str | None:
    """The name of a signal received and not yet acted on (None when there is none)."""
    return _pending


def raise_if_interrupted() -> None:
    """Raise `Interrupted` when a signal arrived, even if a library swallowed the first raise."""
    if _pending is not None:
        raise Interrupted(_pending)


def reset() -> None:
    """Forget a recorded signal (at the start of a command run in the same process)."""
    global _pending
    _pending = None
