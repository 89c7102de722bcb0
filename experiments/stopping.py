"""How a run and a sweep stop on SIGINT or SIGTERM: outputs written and marked, nothing lost (`docs/outputs.md`).

A run (`StopRequest`) finishes its frame, or stops at once while its tracker starts, and writes its outputs with
``status: failed: interrupted by <signal>``. A sweep (`SweepStop`) lets its running jobs do that, starts no more, and
then ends. Either ends as a stopped command does (`experiments.cli_runs.exit_interrupted`).
"""

from __future__ import annotations

import functools
import logging
import os
import signal
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import joblib
from joblib._parallel_backends import LokyBackend

from experiments.cli_runs import write_text

log = logging.getLogger(__name__)


class StopRequest:
    """SIGINT and SIGTERM stop the run: while the tracker starts (`at_once`: a sample set being built, say, the shards
    finished so far kept for the next run), at once; otherwise after the current frame. Either way the run then
    writes its outputs, ``status: failed: interrupted by <signal>``. In a sweep the file ``sweep_stop`` asks the same
    (its text: the signal's name): the sweep's process writes it when a signal reached it alone.

    In the frames a KeyboardInterrupt raised wherever the signal lands can be swallowed (inside a finalizer of a GL
    object it is only printed), and the run would go on; a flag checked once per frame cannot be missed. A second
    signal of the same kind takes the default action at once.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)
    received: str | None = None  # the first stop this process received, by any run (a sweep's later jobs do not start)

    def __init__(self, sweep_stop: Path | None = None) -> None:
        self.sweep_stop = sweep_stop
        self.deferred = True
        self._requested: str | None = None
        self._previous: dict[int, Any] = {}
        self._previous_mask: set[signal.Signals] | None = None

    @classmethod
    def install(cls, sweep_stop: Path | None = None) -> StopRequest:
        request = cls(sweep_stop)
        if threading.current_thread() is threading.main_thread():  # signal handlers live in the main thread
            for number in cls.SIGNALS:
                request._previous[number] = signal.signal(number, request._handle)
            # a sweep's worker blocks them between its jobs (`SweepStop`); one already sent arrives now
            request._previous_mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, cls.SIGNALS)
        return request

    @contextmanager
    def at_once(self) -> Iterator[None]:
        """Within the block, a signal (or one already received) stops the run at once (`Interrupted`)."""
        if self.requested:
            raise Interrupted(self.requested)
        self.deferred = False
        try:
            yield
        finally:
            self.deferred = True

    @property
    def requested(self) -> str | None:
        """The signal's name once a stop was asked, else None (checked once a frame: a file's existence)."""
        if self._requested is None and self.sweep_stop is not None and self.sweep_stop.exists():
            self._requested = self.sweep_stop.read_text().strip() or "SIGTERM"
            StopRequest.note(self._requested)
            log.warning("%s: the sweep is stopping; stopping after this frame", self._requested)
        return self._requested

    def _handle(self, number: int, _frame: Any) -> None:
        self._requested = signal.Signals(number).name
        StopRequest.note(self._requested)
        signal.signal(number, default_action(number))
        if not self.deferred:
            log.warning("%s: stopping", self.requested)
            raise Interrupted(self.requested)
        log.warning("%s: stopping after this frame (again to stop at once)", self.requested)

    @classmethod
    def note(cls, name: str) -> None:
        """Record that this process was asked to stop (its first signal's name is kept)."""
        cls.received = cls.received or name

    def restore(self) -> None:
        if self._previous_mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._previous_mask)
            self._previous_mask = None
        for number, previous in self._previous.items():
            signal.signal(number, previous)
        self._previous = {}


def default_action(number: int) -> Any:
    """What a signal does once a stop was asked: SIGINT raises KeyboardInterrupt where it lands, SIGTERM ends the
    process."""
    return signal.default_int_handler if number == signal.SIGINT else signal.SIG_DFL


class Interrupted(KeyboardInterrupt):
    """The run stopped by a signal (`StopRequest`): raised at once while the tracker starts (`run_job` writes the
    outputs), and by a single run's entry point once they are written. A KeyboardInterrupt, so that no ``except
    Exception`` on the way swallows it."""


class SweepStop:
    """In a sweep's own process, the first SIGINT or SIGTERM (a terminal sends it to the jobs' processes too) waits
    for the running jobs, which stop after their current frame and write their outputs, marked interrupted; the jobs
    queued behind them do not start, and the sweep then ends. A second one stops at once.

    No job raises the stop out of a launcher's worker process: joblib would end the other workers, jobs still
    writing their outputs among them. A signal landing in a worker still starting, or idle between jobs, would break
    the pool the same way: so joblib's workers block the signals from their start (`block_stops_in_workers`) and
    take them only while they run a job (`StopRequest`). A signal sent to the sweep's process alone (``kill <pid>``,
    a scheduler's SIGTERM), or reaching a worker before its first job, reaches the jobs through a file named by the
    sweep's process id (`file`), which every running job checks once a frame and every queued job before it starts.
    The id reaches the workers in the environment, which they inherit."""

    PID_VARIABLE = "ARTICULATED_TRACKING_SWEEP_PID"

    @classmethod
    def file(cls) -> Path | None:
        """The file that says the sweep stops (None: a job whose process did not inherit the sweep's environment,
        a remote Ray worker's, say: it stops on the signals it gets alone)."""
        pid = os.environ.get(cls.PID_VARIABLE)
        return None if pid is None else Path(tempfile.gettempdir()) / f"articulated-tracking-sweep-{pid}.stop"

    @classmethod
    def stopping(cls) -> bool:
        """This process, or the sweep's, was asked to stop (a job queued behind the running ones does not start)."""
        path = cls.file()
        return StopRequest.received is not None or (path is not None and path.exists())

    @classmethod
    def in_sweep_process(cls) -> bool:
        return os.environ.get(cls.PID_VARIABLE) == str(os.getpid())

    @classmethod
    def install(cls) -> None:
        os.environ[cls.PID_VARIABLE] = str(os.getpid())  # before any worker starts: they inherit it
        cls.remove_file()  # left by an earlier process of this id, killed
        for number in StopRequest.SIGNALS:
            signal.signal(number, cls._first)
        cls.block_stops_in_workers()

    @classmethod
    def _first(cls, number: int, _frame) -> None:
        name = signal.Signals(number).name
        log.warning("%s: the sweep stops once its running jobs have written their outputs", name)
        StopRequest.note(name)
        signal.signal(number, default_action(number))
        if (path := cls.file()) is not None:
            write_text(path, name)

    @staticmethod
    def block_stops_in_workers() -> None:
        """Hydra's joblib launcher asks for the backend by name: the name, in this process, now makes workers whose
        first act is to block the signals (a builtin function, unpickled before the jobs' own modules are imported).
        The window left is a worker's interpreter starting, before that act: a Ctrl-C then still ends the sweep with
        joblib's traceback (its workers ignoring the signals from exec on would close it, but an ignored signal is
        lost in this process's other threads while it starts them)."""
        blocking = functools.partial(
            LokyBackend, initializer=signal.pthread_sigmask, initargs=(signal.SIG_BLOCK, StopRequest.SIGNALS)
        )
        joblib.register_parallel_backend("loky", blocking)

    @classmethod
    def remove_file(cls) -> None:
        if cls.in_sweep_process() and (path := cls.file()) is not None:
            path.unlink(missing_ok=True)
