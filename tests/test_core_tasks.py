"""`paintcell.core.tasks.map_tasks`: the calls' values in order, every call sent to the pool
before the first value is waited for (so they run side by side)."""

from __future__ import annotations

from typing import Any

from paintcell.core.tasks import map_tasks


class _Pool:
    """A pool that runs a call when its value is asked for, and logs sends and waits."""

    def __init__(self) -> None:
        self.log: list[tuple[str, tuple[Any, ...]]] = []

    def submit(self, fn: Any, *args: Any) -> Any:
        self.log.append(("send", args))
        log = self.log

        class _Future:
            def result(self) -> Any:
                log.append(("wait", args))
                return fn(*args)

        return _Future()


def test_map_tasks_sends_every_call_before_it_waits() -> None:
    calls = [(2, 3), (3, 2), (5, 0)]
    pool = _Pool()
    assert map_tasks(pow, calls, pool) == [8, 9, 1] == map_tasks(pow, calls)
    assert pool.log == [("send", c) for c in calls] + [("wait", c) for c in calls]
    assert map_tasks(pow, [], pool) == []
