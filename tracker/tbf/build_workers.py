"""Where a sample build's tasks run (`BuildSettings`): in this process, on joblib's processes of this machine
(``loky``) or on Ray's workers (a local Ray or a cluster's: ``make ray``), their results yielded as they finish."""

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
    joblib's ``backend``: ``loky`` (processes on this machine) or ``ray`` (Ray: a local one or a cluster's, at
    ``ray_address``)."""

    jobs: Annotated[int, Range(-1, 256)] = -1
    backend: Literal["loky", "ray"] = "loky"
    shard_size: Annotated[int, Range(1, 1_000_000)] = 512  # poses: a shard's images stay well under 100 MB
    # Ray's ray.init(address=...): null starts a Ray on this machine; "auto" joins the cluster this machine is part
    # of (started with `ray start`); "ray://<head>:10001" a remote cluster's head.
    ray_address: str | None = None

    def __post_init__(self) -> None:
        validate(self)
        if self.jobs == 0:
            raise ValueError("jobs=0 is not allowed: allowed -1 (one per core) or >= 1")


def run_tasks(tasks, settings: BuildSettings) -> Iterator:
    """Each task's result, as they finish: on joblib's processes (in this one for one job), or on Ray's workers."""
    from joblib import Parallel, delayed, parallel_config

    tasks = list(tasks)
    if settings.backend == "ray":
        yield from _on_ray(tasks, settings)
        return
    if settings.jobs == 1 or len(tasks) <= 1:
        yield from (function(*arguments, **keywords) for function, arguments, keywords in tasks)
        return
    tasks = [delayed(_in_worker)(function, *arguments, **keywords) for function, arguments, keywords in tasks]
    with parallel_config(backend=settings.backend, n_jobs=settings.jobs), warnings.catch_warnings():
        # An interrupted build (Ctrl-C) cancels the running tasks: expected, not a warning to print.
        warnings.filterwarnings("ignore", message=r".*tasks which were still being processed", category=UserWarning)
        yield from Parallel(return_as="generator_unordered")(tasks)


def start_ray(address: str | None) -> None:
    """Ray joined (at ``address``, or a local one started; the Ray extra)."""
    import ray

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)


def _on_ray(tasks: list, settings: BuildSettings) -> Iterator:
    """Each task's result as it finishes, on Ray's workers, at most ``settings.jobs`` running at once (-1: as many as
    Ray schedules). Ray's own tasks, not joblib's Ray backend: that one returns nothing before all are done."""
    import ray

    start_ray(settings.ray_address)
    remote = ray.remote(num_cpus=1)(_in_worker)
    waiting, running = list(reversed(tasks)), []
    limit = len(tasks) if settings.jobs == -1 else settings.jobs
    try:
        while waiting or running:
            while waiting and len(running) < limit:
                function, arguments, keywords = waiting.pop()
                running.append(remote.remote(function, *arguments, **keywords))
            done, running = ray.wait(running, num_returns=1)
            yield ray.get(done[0])
    finally:  # stopped early (an interrupt, a failed task): the rest are not wanted
        for task in running:
            ray.cancel(task)


def _in_worker(function, *arguments, **keywords):
    """A task in a worker process, deaf to Ctrl-C and SIGTERM (a terminal or a job system sends them to the whole
    process group): the stop is the parent's to handle (it keeps the shards finished so far, for a resumed build,
    and ends its workers itself), not each worker's. A worker that printed a traceback, or died by SIGTERM halfway
    through sending its shard back, could leave the parent waiting forever on the rest of the message."""
    if multiprocessing.parent_process() is not None:
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, signal.SIG_IGN)
    return function(*arguments, **keywords)
