"""Where a sample build's tasks run (`BuildSettings`): in this process, on joblib's processes of this machine
(``loky``) or on Ray (a local one or a cluster's: ``make ray``), their results yielded as they finish."""

from __future__ import annotations

import multiprocessing
import signal
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Annotated, Literal

from tracker.ranges import Range
from tracker.settings import validate


@dataclass(frozen=True)
class BuildSettings:
    """How a sample set is built: ``shard_size`` poses at a time over ``jobs`` processes (-1: one per core) on
    joblib's ``backend``: ``loky`` (processes on this machine) or ``ray`` (Ray: a local one or a cluster's)."""

    jobs: Annotated[int, Range(-1, 256)] = -1
    backend: Literal["loky", "ray"] = "loky"
    shard_size: Annotated[int, Range(1, 1_000_000)] = 512  # poses: a shard's images stay well under 100 MB

    def __post_init__(self) -> None:
        validate(self)
        if self.jobs == 0:
            raise ValueError("jobs=0 is not allowed: allowed -1 (one per core) or >= 1")


def run_tasks(tasks, settings: BuildSettings) -> Iterator:
    """Each task's result, as they finish, on the configured joblib backend (in this process for one job)."""
    from joblib import Parallel, delayed, parallel_config

    tasks = list(tasks)
    if settings.jobs == 1 or len(tasks) <= 1:
        yield from (function(*arguments, **keywords) for function, arguments, keywords in tasks)
        return
    tasks = [delayed(_in_worker)(function, *arguments, **keywords) for function, arguments, keywords in tasks]
    if settings.backend == "ray":
        from ray.util.joblib import register_ray  # the Ray extra: make ray

        register_ray()
    with parallel_config(backend=settings.backend, n_jobs=settings.jobs), warnings.catch_warnings():
        # An interrupted build (Ctrl-C) cancels the running tasks: expected, not a warning to print.
        warnings.filterwarnings("ignore", message=r".*tasks which were still being processed", category=UserWarning)
        yield from Parallel(return_as="generator_unordered")(tasks)


def _in_worker(function, *arguments, **keywords):
    """A task in a worker process, deaf to Ctrl-C and SIGTERM (a terminal or a job system sends them to the whole
    process group): the stop is the parent's to handle (it keeps the shards finished so far, for a resumed build,
    and ends its workers itself), not each worker's. A worker that printed a traceback, or died by SIGTERM halfway
    through sending its shard back, could leave the parent waiting forever on the rest of the message."""
    if multiprocessing.parent_process() is not None:
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, signal.SIG_IGN)
    return function(*arguments, **keywords)
