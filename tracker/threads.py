"""Work within a frame shared between the calling thread and the process' worker threads.

`TwoEndedJobs`: a list of independent jobs that the caller needs in order; the caller makes each when it needs it,
unless a worker thread has taken it, and the workers take them from the other end. Whoever reaches a job first does
it, so the work balances by itself however long each job and the caller's own work between them are, and the
caller never waits for a job nobody has started. The jobs must release the GIL for most of their time (OpenCV,
NumPy on large arrays) for this to pay.

The workers: one per core beside the caller's (at most `MAX_WORKERS`), made at first use; a forked child makes
its own, as the parent's threads do not exist in it.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Generic, TypeVar

MAX_WORKERS = 4
WORKERS = max(1, min(MAX_WORKERS, (os.cpu_count() or 1) - 1))  # the caller's thread has a core too

Result = TypeVar("Result")

_pool: ThreadPoolExecutor | None = None


def worker_pool() -> ThreadPoolExecutor:
    """The process' `WORKERS` worker threads."""
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(WORKERS, thread_name_prefix="worker")
    return _pool


def _forget_pool() -> None:
    global _pool
    _pool = None


os.register_at_fork(after_in_child=_forget_pool)


class TwoEndedJobs(Generic[Result]):
    """``jobs`` shared with the worker threads (see the module docstring): ``result(i)`` is job i's result (or
    raises its exception), made here unless a worker has taken it."""

    def __init__(self, jobs: Sequence[Callable[[], Result]]) -> None:
        self._jobs = list(jobs)
        self._taken = [False] * len(self._jobs)
        self._results: list[Future] = [Future() for _ in self._jobs]
        self._lock = threading.Lock()
        for _ in range(WORKERS):
            worker_pool().submit(self._from_the_back)

    def result(self, index: int) -> Result:
        if self._take(index):
            self._do(index)
        return self._results[index].result()

    def results(self) -> list[Result]:
        """Every job's result, in the jobs' order (the first failure raises)."""
        return [self.result(index) for index in range(len(self._jobs))]

    def settle(self) -> None:
        """No job not yet taken will start; those under way are waited for, their results and errors dropped: the
        jobs' state is the caller's again."""
        for index, result in enumerate(self._results):
            if self._take(index):
                result.cancel()
            else:
                result.exception()  # waits; an error is dropped with the result

    def _take(self, index: int) -> bool:
        with self._lock:
            taken, self._taken[index] = self._taken[index], True
        return not taken

    def _do(self, index: int) -> None:
        try:
            self._results[index].set_result(self._jobs[index]())
        except BaseException as error:  # handed to whoever asks for the result
            self._results[index].set_exception(error)

    def _from_the_back(self) -> None:
        for index in reversed(range(len(self._jobs))):
            if self._take(index):
                self._do(index)
