"""Running experiments through the real command line, as a user would: one run, or a Hydra multirun (one job per
core), each failing loudly if a run did not finish; a stop asked of the command is passed on to the run under way
(`run_child`)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, NoReturn

from tracker.atomic import atomic_path

# Runs kept for their tables: the tracker's and the errors' series only (~0.7 MB), no images, meshes or parameters.
LIGHT_RECORDING = ("record.images=false", "record.meshes_every=0", "record.parameters=false")


def run_experiment(name: str, run_dir: Path, *overrides: str) -> Path:
    """Run ``experiment=<name>`` into ``run_dir``; fail loudly if it failed."""
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    status = run_child(command)
    if status != 0 and not (run_dir / "metrics.json").exists():  # it said why above; stop with one line
        raise SystemExit(f"{run_dir}: the run ended with exit status {status} (its log: {run_dir}/run.log)")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{run_dir}: {metrics['status']}")
    return run_dir


def run_sweep(sweep_dir: Path, *overrides: str) -> None:
    """A Hydra multirun of ``overrides`` (``experiment=...`` among them) into ``sweep_dir`` (one folder per job);
    fail if a job failed."""
    command = [sys.executable, "-m", "experiments.run", "-m", f"hydra.sweep.dir={sweep_dir}", *overrides]
    status = run_child(command)
    if status != 0:
        raise SystemExit(f"{sweep_dir}: the sweep ended with exit status {status}")
    for metrics_path in sorted(sweep_dir.glob("*/metrics.json")):
        status = json.loads(metrics_path.read_text())["status"]
        if status != "ok":
            raise SystemExit(f"{metrics_path.parent}: {status}")


def write_text(path: Path, text: str) -> Path:
    """``text`` into ``path``, atomically."""
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return path


def run_child(
    command: Sequence[str],
    stdout: IO[bytes] | int | None = None,
    stderr: IO[bytes] | int | None = None,
    started: Callable[[subprocess.Popen], object] | None = None,
) -> int:
    """Run ``command`` (a run, a sweep or a measuring process of ours) to its end; its exit status. It leads a
    process group of its own, so that a terminal's Ctrl-C or a scheduler's SIGTERM reaches this process alone, which
    passes it on to the child's group as a terminal would: a run stops as it does on its own (after its current frame,
    its outputs written and marked interrupted; a second signal stops it at once). This process waits for it, neither
    leaving it running nor killing it, and then raises KeyboardInterrupt with the signal's name (`exit_interrupted`).
    ``stdout``, ``stderr``: where the child's outputs go (as `subprocess.Popen` takes them; None: this process's);
    ``started`` is called with the child once it runs (to watch it)."""
    received: list[int] = []
    passed_on = 0
    process: subprocess.Popen | None = None

    def pass_on(number: int | None = None, _frame: object = None) -> None:
        nonlocal passed_on
        if number is not None:
            received.append(number)
        while process is not None and passed_on < len(received):  # also those that came while it started
            passed_on += 1  # counted before it is sent: a signal landing here does not send it twice
            try:
                os.killpg(process.pid, received[passed_on - 1])
            except ProcessLookupError:  # it has just ended
                pass

    handled = (signal.SIGINT, signal.SIGTERM) if threading.current_thread() is threading.main_thread() else ()
    previous = {number: signal.signal(number, pass_on) for number in handled}
    try:
        if not received:
            process = subprocess.Popen(list(command), stdout=stdout, stderr=stderr, process_group=0)
            pass_on()
            if started is not None:
                started(process)
            status = process.wait()
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    if received:
        raise KeyboardInterrupt(signal.Signals(received[0]).name)
    return status


def exit_interrupted(interrupt: KeyboardInterrupt) -> NoReturn:
    """End a command stopped by a signal as a run ends: one line, ``interrupted by <signal>``, and the exit status
    128 + its number (a KeyboardInterrupt that names no signal: SIGINT)."""
    name = str(interrupt) if str(interrupt) in signal.Signals.__members__ else "SIGINT"
    print(f"interrupted by {name}", file=sys.stderr)
    sys.exit(128 + signal.Signals[name].value)
