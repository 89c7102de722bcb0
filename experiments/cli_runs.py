"""Running experiments through the real command line, as a user would: one run, or a Hydra multirun (one job per
core), each failing loudly if a run did not finish."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tracker.atomic import atomic_path

# Runs kept for their tables: the tracker's and the errors' series only (~0.7 MB), no images, meshes or parameters.
LIGHT_RECORDING = ("record.images=false", "record.meshes_every=0", "record.parameters=false")


def run_experiment(name: str, run_dir: Path, *overrides: str) -> Path:
    """Run ``experiment=<name>`` into ``run_dir``; fail loudly if it failed."""
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    ended = subprocess.run(command, check=False)
    if ended.returncode != 0 and not (run_dir / "metrics.json").exists():  # it said why above; stop with one line
        raise SystemExit(f"{run_dir}: the run ended with exit status {ended.returncode} (its log: {run_dir}/run.log)")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{run_dir}: {metrics['status']}")
    return run_dir


def run_sweep(sweep_dir: Path, *overrides: str) -> None:
    """A Hydra multirun of ``overrides`` (``experiment=...`` among them) into ``sweep_dir`` (one folder per job);
    fail if a job failed."""
    command = [sys.executable, "-m", "experiments.run", "-m", f"hydra.sweep.dir={sweep_dir}", *overrides]
    ended = subprocess.run(command, check=False)
    if ended.returncode != 0:
        raise SystemExit(f"{sweep_dir}: the sweep ended with exit status {ended.returncode}")
    for metrics_path in sorted(sweep_dir.glob("*/metrics.json")):
        status = json.loads(metrics_path.read_text())["status"]
        if status != "ok":
            raise SystemExit(f"{metrics_path.parent}: {status}")


def write_text(path: Path, text: str) -> Path:
    """``text`` into ``path``, atomically."""
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return path
