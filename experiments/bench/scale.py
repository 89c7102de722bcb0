"""``python -m experiments.bench scale [--turns 1,2,4,8] [--experiments tbf_paper_scale,tbf_multi_view]
[--frames N] [overrides]``: how tree filtering's cost grows with its dictionary.

Each preset (one per rig: 1 and 3 cameras) with dictionaries of the same clips, mirrored, turned about the vertical
by each of ``--turns`` evenly spaced angles (the presets' own: 4, ~52k samples), so each is about twice the last:
~13k, 26k, 52k and 104k samples. For each, in a
fresh cache folder, two runs of the same measuring process (``--cell``): cold (the dictionary and tree built) and
warm (loaded): the samples, the start's seconds (the build, then the load), the peak resident memory of the
process and its build workers summed (sampled every `SAMPLE_S`) and its anonymous part (without the pages of
mapped files), the cache's disk, and the filter's median ms per frame over the preset's first ``--frames`` frames
(silhouettes extracted before, untimed). Then, per rig, the exponent of ms/frame against samples (least squares in
log-log). Writes ``reports/scale.md``, ``scale.csv`` and ``scale.png``; the cache folders are removed once measured.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import psutil

from eval.runs import markdown
from experiments.bench.tbf import observations, start_tracker, stepped_ms
from experiments.cli_runs import run_child, write_text
from experiments.components import build, compose
from experiments.loop import frame_threads
from experiments.steps import Section, Step

log = logging.getLogger(__name__)

SAMPLE_S = 0.2  # how often the process tree's memory is read
REPORTS = Path("reports")
CACHE = Path(".cache")  # the cells' fresh cache folders go inside (the same disk as a user's cache)


def turns_deg(count: int) -> list[float]:
    """``count`` angles evenly spaced around the vertical, in (-180, 180] (4: 0, 90, 180, -90)."""
    return [float(a - 360 if a > 180 else a) for a in (360.0 * k / count for k in range(count))]


def measure_cell(experiment: str, frames: int, overrides: list[str]) -> dict[str, float]:
    """In this process: the tracker started (its dictionary built or loaded) and stepped through ``frames``."""
    run = build(compose([f"experiment={experiment}", *overrides]))
    tracker, frames = run.tracker, min(frames, run.settings.frames)
    start = time.perf_counter()
    start_tracker(run)
    start_s = time.perf_counter() - start
    observed = observations(run, frames)
    with frame_threads():  # as a run steps it
        per_frame = [stepped_ms(tracker, observation) for observation in observed]
    samples, views = len(tracker.filter.samples), len(run.cameras)
    return {"samples": samples, "views": views, "start_s": start_s, "ms_per_frame": statistics.median(per_frame)}


class PeakMemory:
    """The largest resident memory of a process and its descendants summed, sampled every `SAMPLE_S` while open: all
    of it, and its anonymous part (without the pages of mapped files, such as a memory-mapped sample set, which the
    kernel drops when memory is short)."""

    def __init__(self, pid: int) -> None:
        self.peak_bytes, self.peak_anonymous_bytes = 0, 0
        self._process, self._done = psutil.Process(pid), threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        while not self._done.wait(SAMPLE_S):
            try:
                tree = [self._process, *self._process.children(recursive=True)]
                memory = [p.memory_info() for p in tree if p.is_running()]
            except psutil.Error:  # a worker ended between the listing and the reading
                continue
            self.peak_bytes = max(self.peak_bytes, sum(m.rss for m in memory))
            self.peak_anonymous_bytes = max(self.peak_anonymous_bytes, sum(m.rss - m.shared for m in memory))

    def close(self) -> tuple[float, float]:
        """The peaks in GiB: resident, anonymous."""
        self._done.set()
        self._thread.join()
        return self.peak_bytes / 2**30, self.peak_anonymous_bytes / 2**30


def run_cell(experiment: str, frames: int, overrides: list[str]) -> dict[str, float]:
    """`measure_cell` in a process of its own (a fresh interpreter), with its peak memory in GiB. A stop asked of
    this process is passed on to it, and waited for (`run_child`)."""
    command = [sys.executable, "-m", "experiments.bench", "scale", "--cell", f"--frames={frames}"]
    watched: list[PeakMemory] = []
    with tempfile.TemporaryFile() as output:
        try:
            status = run_child(
                [*command, f"--experiments={experiment}", *overrides],
                stdout=output,
                stderr=subprocess.DEVNULL,
                started=lambda process: watched.append(PeakMemory(process.pid)),
            )
        finally:
            peak_gib, anonymous_gib = watched[0].close() if watched else (0.0, 0.0)
        output.seek(0)
        last_line = output.read().decode().strip().splitlines()[-1:]
    if status != 0 or not last_line:
        raise SystemExit(f"scale: experiment={experiment} {' '.join(overrides)} failed ({status})")
    return {**json.loads(last_line[0]), "peak_gib": peak_gib, "anonymous_gib": anonymous_gib}


def disk_gib(folder: Path) -> float:
    return sum(path.stat().st_size for path in folder.rglob("*") if path.is_file()) / 2**30


def scale_rows(experiments: list[str], turns: list[int], frames: int, overrides: list[str]) -> pd.DataFrame:
    rows = []
    for experiment in experiments:
        for count in turns:
            CACHE.mkdir(exist_ok=True)
            with tempfile.TemporaryDirectory(prefix="scale_", dir=CACHE) as cache:
                cell = [*overrides, f"tracker.samples.clip_turns_deg={turns_deg(count)}", f"tracker.cache_dir={cache}"]
                cold = run_cell(experiment, frames, cell)
                disk = disk_gib(Path(cache))
                warm = run_cell(experiment, frames, cell)
            rows.append(
                {
                    "experiment": experiment,
                    "views": cold["views"],
                    "turns": count,
                    "samples": cold["samples"],
                    "build_s": cold["start_s"],
                    "build_peak_gib": cold["peak_gib"],
                    "build_anonymous_gib": cold["anonymous_gib"],
                    "disk_gib": disk,
                    "load_s": warm["start_s"],
                    "run_peak_gib": warm["peak_gib"],
                    "run_anonymous_gib": warm["anonymous_gib"],
                    "ms_per_frame": warm["ms_per_frame"],
                }
            )
            log.info(
                "  %s, %d turns: %d samples, built in %.0f s (peak %.2f GiB, %.3f GiB on disk); %.2f ms/frame "
                "(run peak %.2f GiB)",
                *(rows[-1][key] for key in ("experiment", "turns", "samples", "build_s", "build_peak_gib")),
                *(rows[-1][key] for key in ("disk_gib", "ms_per_frame", "run_peak_gib")),
            )
    return pd.DataFrame(rows)


def exponents(table: pd.DataFrame) -> dict[str, float]:
    """Per preset, the slope of log(ms/frame) against log(samples) (NaN with fewer than two sizes)."""
    slopes = {}
    for experiment, rows in table.groupby("experiment", sort=False):
        fit = len(rows) > 1 and rows["samples"].nunique() > 1
        slopes[experiment] = (
            float(np.polyfit(np.log(rows["samples"]), np.log(rows["ms_per_frame"]), 1)[0]) if fit else float("nan")
        )
    return slopes


def plot(table: pd.DataFrame, slopes: dict[str, float], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    for experiment, rows in table.groupby("experiment", sort=False):
        label = f"{experiment} ({rows['views'].iloc[0]} view(s)): exponent {slopes[experiment]:.2f}"
        axes[0].loglog(rows["samples"], rows["ms_per_frame"], "o-", label=label)
        axes[1].loglog(rows["samples"], rows["build_peak_gib"], "o-", label=f"{experiment}: build")
        axes[1].loglog(rows["samples"], rows["run_peak_gib"], "s--", label=f"{experiment}: run")
    axes[0].set(xlabel="samples", ylabel="ms / frame (median)", title="tree filtering per frame")
    axes[1].set(xlabel="samples", ylabel="peak resident memory (GiB)", title="memory")
    ticks = sorted(table["samples"].unique())
    for axis in axes:
        axis.set_xticks(ticks, [f"{count / 1000:.0f}k" for count in ticks], minor=False)
        axis.set_xticks([], minor=True)
        axis.legend(fontsize=7)
        axis.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def write_reports(table: pd.DataFrame, reports: Path) -> tuple[dict[str, float], str]:
    """``scale.csv``, ``scale.png`` and ``scale.md`` in ``reports``; the exponents and the markdown of the table."""
    slopes = exponents(table)
    reports.mkdir(parents=True, exist_ok=True)
    write_text(reports / "scale.csv", table.to_csv(index=False))
    plot(table, slopes, reports / "scale.png")
    summary = "\n".join(f"- {name}: ms/frame grows as samples^{slope:.2f}" for name, slope in slopes.items())
    text = f"{markdown(table.round(3))}\n\n{summary}\n"
    write_text(reports / "scale.md", f"# Tree filtering against its dictionary's size\n\n{text}")
    return slopes, text


def run(args: argparse.Namespace) -> dict:
    if args.cell:  # the measuring process: its figures as its last line
        print(json.dumps(measure_cell(args.experiments[0], args.frames, args.overrides)), flush=True)
        return {}
    experiments, turns = args.experiments or list(STEP.presets), args.turns or STEP_TURNS
    table = scale_rows(experiments, turns, args.frames, args.overrides)
    slopes, text = write_reports(table, REPORTS)
    log.info("%s\nwrote %s", text, REPORTS / "scale.md")
    return {"rows": table.to_dict("records"), "exponents": slopes}


def scale_step(reports: Path) -> Section:
    table = scale_rows(list(STEP.presets), STEP_TURNS, STEP_FRAMES, [])
    _, text = write_reports(table, reports)
    section = (
        "### Tree filtering against its dictionary's size\n\n"
        f"Each preset with dictionaries of the same clips turned {', '.join(map(str, STEP_TURNS))} times about the "
        f"vertical, each built cold in a fresh cache and then loaded; ms/frame is the median over the first "
        f"{STEP_FRAMES} frames; memory is the peak resident of the process and its build workers "
        "(`python -m experiments.bench scale`).\n\n" + text + "\n![scale](scale.png)\n"
    )
    return Section(f"\nScaling:\n{text}", section)


STEP_TURNS, STEP_FRAMES = [1, 2, 4, 8], 45  # ~13k to ~104k samples; the held-out clip whole at 15 fps
STEP = Step(
    "Tree filtering against its dictionary's size (SCALE=paper): time, memory and disk from ~13k to ~104k samples, "
    "1 and 3 cameras",
    ("tbf_paper_scale", "tbf_multi_view"),
    ("scale.md", "scale.csv", "scale.png"),
    scale_step,
    scale="paper",
)
