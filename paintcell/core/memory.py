"""The memory this process may use, and the error a budget raises when a stage would need more.

`memory_room` is the least of MemAvailable (Linux; else the physical memory), the memory
cgroup's limit less its usage (a container's `memory.max`, cgroup v2, or v1's
`memory.limit_in_bytes`), RLIMIT_AS less the address space in use (`ulimit -v`), and
`PAINTCELL_MAX_MEMORY_GB`, with the name of the one that bounds it. The stage budgets that use
it are `paintcell.core.budget`'s.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from paintcell.core.errors import PaintcellError

__all__ = ["BudgetError", "available_bytes", "gib", "memory_cap_bytes", "memory_room"]


class BudgetError(PaintcellError):
    """A stage would need more memory or time than the machine has."""


def gib(n_bytes: float) -> str:
    """A byte count in GiB for messages."""
    return f"{n_bytes / 2**30:.3g} GiB"


#: A limit at or above this many bytes means "no limit" (cgroup v1 writes 2⁶³ rounded to a page).
_UNLIMITED = 2**60


def _read_int(path: Path) -> int | None:
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _cgroup_room(root: Path = Path("/sys/fs/cgroup"),
                 proc_cgroup: Path = Path("/proc/self/cgroup")) -> tuple[int, str] | None:
    """Bytes the process's memory cgroup still allows (its limit less its usage, the tightest
    of the cgroup and its parents) and which file said so; None without a limit.

    cgroup v2: `memory.max` − `memory.current` along the `0::/path` hierarchy; v1: the
    `memory` controller's `memory.limit_in_bytes` − `memory.usage_in_bytes`."""
    try:
        lines = proc_cgroup.read_text().splitlines()
    except OSError:
        return None
    best: tuple[int, str] | None = None

    def consider(limit_file: Path, usage_file: Path) -> None:
        nonlocal best
        limit = _read_int(limit_file)
        if limit is None or limit >= _UNLIMITED:
            return
        room = max(0, limit - (_read_int(usage_file) or 0))
        if best is None or room < best[0]:
            best = (room, str(limit_file))

    for line in lines:
        _, controllers, rel = line.split(":", 2) if line.count(":") >= 2 else ("", "", "")
        if controllers == "" and rel:          # v2 unified hierarchy
            d = root / rel.lstrip("/")
            while True:
                consider(d / "memory.max", d / "memory.current")
                if d == root or root not in d.parents:
                    break
                d = d.parent
        elif "memory" in controllers.split(","):    # v1 memory controller
            base = root / "memory"
            for d in (base / rel.lstrip("/"), base):   # a namespaced view shows its own at base
                consider(d / "memory.limit_in_bytes", d / "memory.usage_in_bytes")
    return best


def _rlimit_room() -> tuple[int, str] | None:
    """Address space RLIMIT_AS still leaves the process (its soft limit less VmSize), or None."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0 or soft >= _UNLIMITED:
        return None
    used = 0
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                used = int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return max(0, soft - used), "RLIMIT_AS (ulimit -v)"


def memory_cap_bytes(raw: str | None = None) -> int | None:
    """`PAINTCELL_MAX_MEMORY_GB` in bytes (None when unset); anything but a finite number of
    GB > 0 is refused in one line (BudgetError)."""
    raw = os.environ.get("PAINTCELL_MAX_MEMORY_GB") if raw is None else raw
    if raw is None or raw.strip() == "":
        return None
    try:
        gb = float(raw)
    except ValueError:
        gb = math.nan
    if not math.isfinite(gb) or gb <= 0 or gb > 2**30:
        raise BudgetError(f"PAINTCELL_MAX_MEMORY_GB = {raw!r} must be a number of GB > 0 "
                          "(e.g. 8); unset it to use what the machine has")
    return max(1, int(gb * 2**30))


def memory_room() -> tuple[int, str]:
    """(bytes the run may use, what bounds it): the least of MemAvailable (Linux; else the
    physical memory), the memory cgroup's limit less its usage, RLIMIT_AS less the address
    space in use, and `PAINTCELL_MAX_MEMORY_GB`."""
    rooms: list[tuple[int, str]] = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                rooms.append((int(line.split()[1]) * 1024, "MemAvailable"))
                break
    except (OSError, ValueError):
        pass
    if not rooms:
        try:
            rooms.append((os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"),
                          "physical memory"))
        except (ValueError, OSError, AttributeError):
            rooms.append((2**62, "no known limit"))
    for room in (_cgroup_room(), _rlimit_room()):
        if room is not None:
            rooms.append(room)
    cap = memory_cap_bytes()
    if cap is not None:
        rooms.append((cap, "PAINTCELL_MAX_MEMORY_GB"))
    return min(rooms, key=lambda r: r[0])


def available_bytes() -> int:
    """Memory the run may use (`memory_room`), in bytes."""
    return int(memory_room()[0])


def room_text() -> str:
    """The room as a message fragment: "the 3.1 GiB available (cgroup memory.max)"."""
    room, what = memory_room()
    return f"the {gib(room)} available ({what})"
