"""Sweep benchmarks: ``python -m experiments.bench.sweeps speed|resume [--launchers joblib basic ray]``.

Both sweep the six Fig 4(c) cells (``experiment=tbf_table4c cost=xor,wxor,nwxor motion=dm1,dm2``) through the real
CLI into a scratch folder (``--out``, default ``multirun/bench_sweeps``), on a warm sample cache (run the sweep
once first, or ``make reproduce``).

``speed``: the same sweep on each launcher in turn, in this one run: wall time of each, the ratio of each to the
first launcher (``basic`` runs the jobs one after another) and whether every job's ``metrics.json`` is
byte-identical across launchers.

``resume``: the sweep on joblib, killed with SIGKILL (the launcher and its workers, as one process group) once
``--finished`` jobs have written their metrics, then the same command again: how many jobs are complete, lost
or recomputed (a finished job's ``metrics.json`` rewritten), and the temporaries left before and after.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from experiments.bench.common import json_line

SWEEP = ("experiment=tbf_table4c", "cost=xor,wxor,nwxor", "motion=dm1,dm2")
JOBS = 6


def sweep_command(sweep_dir: Path, launcher: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "experiments.run",
        "-m",
        *SWEEP,
        f"hydra/launcher={launcher}",
        f"hydra.sweep.dir={sweep_dir}",
    ]


def metrics_files(sweep_dir: Path) -> dict[str, Path]:
    return {path.parent.name: path for path in sorted(sweep_dir.glob("*/metrics.json"))}


def speed(out: Path, launchers: list[str]) -> dict:
    times, contents = {}, {}
    for launcher in launchers:
        sweep_dir = out / launcher
        subprocess.run(["rm", "-rf", str(sweep_dir)], check=True)
        start = time.perf_counter()
        subprocess.run(
            sweep_command(sweep_dir, launcher), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        times[launcher] = time.perf_counter() - start
        contents[launcher] = {job: path.read_bytes() for job, path in metrics_files(sweep_dir).items()}
        print(f"{launcher:>7}: {times[launcher]:6.1f} s for {len(contents[launcher])} jobs", flush=True)
    first, identical = launchers[0], {}
    for launcher in launchers[1:]:
        same = contents[launcher] == contents[first] and len(contents[first]) == JOBS
        print(f"{first} / {launcher}: {times[first] / times[launcher]:.2f}x; metrics.json byte-identical: {same}")
        identical[launcher] = same
    return {"seconds": times, "jobs": JOBS, "metrics_identical_to_first": identical}


def resume(out: Path, finished: int) -> dict:
    sweep_dir = out / "resume"
    subprocess.run(["rm", "-rf", str(sweep_dir)], check=True)
    process = subprocess.Popen(
        sweep_command(sweep_dir, "joblib"), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    while len(metrics_files(sweep_dir)) < finished:
        if process.poll() is not None:
            raise SystemExit("the sweep ended before it could be killed")
        time.sleep(0.5)
    time.sleep(5)  # the other jobs are well into their frames
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    before = {job: (path.stat().st_mtime_ns, path.read_bytes()) for job, path in metrics_files(sweep_dir).items()}
    temporaries = len(list(sweep_dir.glob("*/.*.tmp")))
    print(
        f"killed with {len(before)} of {JOBS} jobs finished ({', '.join(sorted(before))}), {temporaries} "
        "temporaries left",
        flush=True,
    )
    start = time.perf_counter()
    subprocess.run(sweep_command(sweep_dir, "joblib"), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    after = metrics_files(sweep_dir)
    recomputed = sum(after[job].stat().st_mtime_ns != stamp for job, (stamp, _) in before.items() if job in after)
    lost = sum(job not in after for job in before)
    left = len(list(sweep_dir.glob("*/.*.tmp")))
    rerun_s = time.perf_counter() - start
    print(
        f"re-run: {rerun_s:.0f} s; {len(after)} of {JOBS} complete, {lost} lost, {recomputed} "
        f"finished jobs recomputed, {left} temporaries left"
    )
    return {
        "finished_before_kill": len(before),
        "temporaries_after_kill": temporaries,
        "rerun_s": rerun_s,
        "complete": len(after),
        "lost": lost,
        "recomputed": recomputed,
        "temporaries_left": left,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", choices=["speed", "resume"])
    parser.add_argument("--launchers", nargs="+", default=["basic", "joblib"], help="speed: the first is the base")
    parser.add_argument("--finished", type=int, default=2, help="resume: kill once this many jobs finished")
    parser.add_argument("--out", type=Path, default=Path("multirun/bench_sweeps"))
    parser.add_argument("--json", action="store_true", help="end with one JSON line of the figures")
    args = parser.parse_args()
    figures = speed(args.out, args.launchers) if args.target == "speed" else resume(args.out, args.finished)
    if args.json:
        print(json_line(f"sweeps {args.target}", figures), flush=True)


if __name__ == "__main__":
    main()
