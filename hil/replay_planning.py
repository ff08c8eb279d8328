"""Planning in a replay of a `rover run` recording: done by the next tick, as the rover's worker thread was.

``rover run`` plans on a worker thread (``navigator.plan_worker``): a plan asked for in one control tick
is taken in by a later one, the next on the maps a rover drives (planning takes milliseconds, a tick is
20 ms). A lockstep trial plans inline, inside the tick that asked. A replay of a `rover run` recording
computes each plan inline, deterministic, and hands it over at the next tick, as the worker would have
(``release`` before each tick); a plan that took the rover longer than a tick is the one case it times
differently.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any, TypeVar

T = TypeVar("T")


class NextTickPlanning(Executor):
    """An ``Executor`` whose jobs run at ``submit`` and are done from the next ``release`` on."""

    def __init__(self) -> None:
        self._done_next_tick: list[Callable[[], None]] = []

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        future: Future[T] = Future()
        try:
            result = fn(*args, **kwargs)
        except Exception as err:  # read from the future at the next tick, as from a worker's
            failure = err
            self._done_next_tick.append(lambda: future.set_exception(failure))
        else:
            self._done_next_tick.append(lambda: future.set_result(result))
        return future

    def release(self) -> None:
        """Every job submitted so far is done: call before each tick."""
        finishing, self._done_next_tick = self._done_next_tick, []
        for finish in finishing:
            finish()
