"""``make reproduce``: regenerate what the papers report, into ``reports/``.

Paper 1 (AbIS): the 3-part DSQ arm tracked from 3 orthogonal views with Levenberg-Marquardt and with the paper's
steepest descent; Fig 8 and Fig 9 of the LM run in ``reports/``, each run's figures, recording and tables in
``reports/<run>/``.

Paper 2 (silhouette tree-based filtering): experiment A (24 right-arm swings, side-on) swept over the cost and
the motion model (XOR, wXOR and nwXOR with DM1 and DM2; the paper has no XOR row) into
``reports/tbf_table4c/<cell>/``, one job per core;
``reports/table4c.md`` / ``.csv`` (Fig 4c) and ``reports/table6d.md`` (Fig 6d) from them (`eval.tables`).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from eval.figures import write_figures
from eval.tables import collect, table_4c, write_reports

REPORTS = Path("reports")


def run_experiment(name: str, run_name: str, *overrides: str) -> Path:
    """Run ``experiment=<name>`` through the real CLI into ``reports/<run_name>``; fail loudly if it failed."""
    run_dir = REPORTS / run_name
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    subprocess.run(command, check=True)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{run_name}: {metrics['status']}")
    return run_dir


TBF_CELLS = ("cost=xor,wxor,nwxor", "motion=dm1,dm2")  # the paper's 4 cells, and XOR beyond it


def run_sweep(name: str, sweep_dir: Path, *overrides: str) -> None:
    """A Hydra multirun of ``experiment=<name>`` into ``sweep_dir`` (one folder per job); fail if a job failed."""
    command = [sys.executable, "-m", "experiments.run", "-m", f"experiment={name}", f"hydra.sweep.dir={sweep_dir}",
               *overrides]  # fmt: skip
    subprocess.run(command, check=True)
    for metrics_path in sorted(sweep_dir.glob("*/metrics.json")):
        status = json.loads(metrics_path.read_text())["status"]
        if status != "ok":
            raise SystemExit(f"{metrics_path.parent}: {status}")


def paper_2() -> str:
    start = time.perf_counter()
    sweep_dir = REPORTS / "tbf_table4c"
    shutil.rmtree(sweep_dir, ignore_errors=True)
    run_sweep("tbf_table4c", sweep_dir, *TBF_CELLS)
    runs = collect([sweep_dir])
    written = write_reports(runs, REPORTS)
    four_c = table_4c(runs)
    rows = "\n".join(f"  {r.cost:>5} + {r.motion}: fail {r.fail}, error {r.error}, success {r.success}  "
                     + ("(paper: no such row)" if pd.isna(r.paper_fail) else
                        f"(paper: {r.paper_fail}, {r.paper_error}, {r.paper_success})") + f", MPJPE {r.mpjpe_mm} mm"
                     for r in four_c.itertuples())  # fmt: skip
    return (f"\nPaper 2 (silhouette tree-based filtering), experiment A, {len(runs)} runs in "
            f"{time.perf_counter() - start:.0f} s:\n{rows}\n" + "\n".join(f"  {path}" for path in written))


def main() -> None:
    print(paper_1())
    print(paper_2())


def paper_1() -> str:
    start = time.perf_counter()
    lines = []
    for optimizer in ("lm", "sd"):
        run_dir = run_experiment("abis_fig8_fig9", f"abis_{optimizer}", f"tracker.fit.optimizer={optimizer}")
        figures = write_figures(run_dir)
        metrics = json.loads((run_dir / "metrics.json").read_text())
        timing = json.loads((run_dir / "timings.json").read_text())
        lines.append(
            f"  {optimizer}: part2_b1_rms {metrics['part2_b1_rms'] * 1e3:.1f} mm "
            f"({100 * metrics['part2_b1_rms'] / metrics['part2_b1_range']:.1f}% of the b1 range), "
            f"part2_r2_rms {metrics['part2_r2_rms_deg']:.2f} deg, "
            f"estimation {timing['estimate_ms_median']:.0f} ms/frame (median), "
            f"recording {run_dir / 'run.rrd'}"
        )
        if optimizer == "lm":
            for figure in figures[1:]:
                shutil.copyfile(figure, REPORTS / figure.name)
    return (
        f"\nPaper 1 (AbIS), {metrics['frames_done']} frames x 3 views, in {time.perf_counter() - start:.0f} s:\n"
        + "\n".join(lines)
        + f"\nFig 8: {REPORTS / 'fig8_part2_b1_r2.png'}\nFig 9: {REPORTS / 'fig9_part2_correspondences.png'}\n"
        f"Open a recording with: .venv/bin/rerun {REPORTS / 'abis_lm' / 'run.rrd'}"
    )


if __name__ == "__main__":
    main()
