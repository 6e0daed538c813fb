"""Independent calls of one function, in this process or on a pool of worker processes.

`map_tasks(fn, args, pool)` is `[fn(*a) for a in args]`; given a pool (a
`paintcell.booth.booth_tasks.TaskPool`, e.g. `paintcell run --workers N`'s Dask workers) it
sends every call before it waits for the first, so the calls run side by side, and returns their
values in the order of `args` — the same values, bit for bit, when fn is a function of its
arguments alone, and not of the number of BLAS threads, which a Dask worker sets to one: a large
least-squares solve or matrix product can round differently (the film refinement's does, by
~1e-13 m/s on a car panel). A booth with `film_refine_pace` plans without that refinement and
refines in the client, so its runs are equal bit for bit; a planner that refines each part
itself (`film_refine`, the default without `film_refine_pace`) can differ by that rounding. A
call that may be refused should return its error rather than raise it, so one refusal does not
hide the other calls' values.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

T = TypeVar("T")


def map_tasks(fn: Callable[..., T], args: Sequence[tuple[Any, ...]],
              pool: Any = None) -> list[T]:
    """fn(*a) for each a of args, in order (module doc); pool: None, in this process."""
    if pool is None:
        return [fn(*a) for a in args]
    futures = [pool.submit(fn, *a) for a in args]
    return [f.result() for f in futures]
