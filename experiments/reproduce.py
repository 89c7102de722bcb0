"""``make reproduce [SCALE=paper]``: regenerate what the papers report, into ``reports/``, summed up in
``reports/report.md`` (tables beside the papers' numbers, figures embedded, machine and commit named).

Paper 1 (AbIS): the 3-part DSQ arm tracked from 3 orthogonal views with Levenberg-Marquardt and with the paper's
steepest descent; Fig 8 and Fig 9 of the LM run in ``reports/``, each run's figures, recording and tables in
``reports/<run>/``.

Paper 2 (silhouette tree-based filtering): experiment A (24 right-arm swings, side-on) under the paper's
conditions (``experiment=tbf_table4c``: a subject unlike the standard bodies, a person's variation at three seeds,
samples from a capture session) swept over the cost and the motion model (XOR, wXOR and nwXOR with DM1 and DM2; the
paper has no XOR row) into ``reports/tbf_table4c/<job>/``, one job per core; the clean control
(``tbf_table4c_clean``) into ``reports/tbf_table4c_clean/``; a sweep of realism (DM2, three costs) into
``reports/tbf_realism/``. ``reports/table4c.md`` / ``.csv`` (Fig 4c, with each cell's largest errors and the counts
at other bounds) and ``reports/table6d.md`` (Fig 6d) come from them (`eval.tables`), and the figures
``fig4c_swings.png``, ``fig4b_strip.png``, ``fig4c_realism.png`` and ``fig4c_why.png`` (`eval.body_figures`; the
realism knob, the pictures and the report's text: `experiments.experiment_a`).

``--scale paper`` also runs ``experiment=tbf_paper_scale`` (about 58,000 samples; the first run renders them in
~1.5 min) into ``reports/tbf_paper_scale/``, which adds its timings to Fig 6(d) and its MPJPE on the held-out clip
to the report.
"""

from __future__ import annotations

import argparse
import datetime
import json
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from eval.figures import write_figures
from eval.tables import collect, machine, markdown, table_4c, write_reports
from experiments.experiment_a import experiment_a_figures, paper_2_markdown, realism_overrides
from tracker.atomic import atomic_path

REPORTS = Path("reports")
TBF_CELLS = ("cost=xor,wxor,nwxor", "motion=dm1,dm2")  # the paper's 4 cells, and XOR beyond it
REALISM_LEVELS = (0.0, 0.25, 0.5)  # swept below the experiment itself (1)
# Runs kept for their tables: the tracker's and the errors' series only (~0.7 MB); the two cells the paper compares
# keep images, meshes and parameters.
LIGHT_RECORDING = ("record.images=false", "record.meshes_every=0", "record.parameters=false")
# Experiment A: 6 cells x 3 seeds of the subject's variation, in four multiruns (Hydra sweeps a grid) so that
# only wXOR and nwXOR with DM2 on the first subject are recorded whole. Folder under reports/tbf_table4c -> overrides.
EXPERIMENT_A_SWEEPS = {
    "recorded": ("cost=wxor,nwxor", "motion=dm2", "scene.body.seed=0"),
    "seed0_xor": ("cost=xor", "motion=dm1,dm2", "scene.body.seed=0", *LIGHT_RECORDING),
    "seed0_dm1": ("cost=wxor,nwxor", "motion=dm1", "scene.body.seed=0", *LIGHT_RECORDING),
    "seeds_1_2": (*TBF_CELLS, "scene.body.seed=1,2", *LIGHT_RECORDING),
}


@dataclass(frozen=True)
class Section:
    console: str  # what the command prints
    markdown: str  # its part of report.md


def run_experiment(name: str, run_name: str, *overrides: str) -> Path:
    """Run ``experiment=<name>`` through the real CLI into ``reports/<run_name>``; fail loudly if it failed."""
    run_dir = REPORTS / run_name
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    subprocess.run(command, check=True)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{run_name}: {metrics['status']}")
    return run_dir


def run_sweep(name: str, sweep_dir: Path, *overrides: str) -> None:
    """A Hydra multirun of ``experiment=<name>`` into ``sweep_dir`` (one folder per job); fail if a job failed."""
    command = [sys.executable, "-m", "experiments.run", "-m", f"experiment={name}", f"hydra.sweep.dir={sweep_dir}",
               *overrides]  # fmt: skip
    subprocess.run(command, check=True)
    for metrics_path in sorted(sweep_dir.glob("*/metrics.json")):
        status = json.loads(metrics_path.read_text())["status"]
        if status != "ok":
            raise SystemExit(f"{metrics_path.parent}: {status}")


def paper_1() -> Section:
    start = time.perf_counter()
    lines, rows = [], []
    for optimizer in ("lm", "sd"):
        print(f"paper 1: AbIS with {optimizer} ...", flush=True)
        run_dir = run_experiment("abis_fig8_fig9", f"abis_{optimizer}", f"tracker.fit.optimizer={optimizer}")
        figures = write_figures(run_dir)
        metrics = json.loads((run_dir / "metrics.json").read_text())
        timing = json.loads((run_dir / "timings.json").read_text())
        b1_mm, b1_pct = metrics["part2_b1_rms"] * 1e3, 100 * metrics["part2_b1_rms"] / metrics["part2_b1_range"]
        lines.append(f"  {optimizer}: part2_b1_rms {b1_mm:.1f} mm ({b1_pct:.1f}% of the b1 range), part2_r2_rms "
                     f"{metrics['part2_r2_rms_deg']:.2f} deg, estimation {timing['estimate_ms_median']:.0f} ms/frame "
                     f"(median), recording {run_dir / 'run.rrd'}")  # fmt: skip
        rows.append({"optimiser": optimizer, "part 2 b1 RMS (mm)": round(b1_mm, 1),
                     "b1 RMS (% of its range)": round(b1_pct, 1),
                     "part 2 r2 RMS (deg)": round(metrics["part2_r2_rms_deg"], 2),
                     "estimation (ms/frame, median)": round(timing["estimate_ms_median"], 1),
                     "recording": f"`{run_dir.relative_to(REPORTS) / 'run.rrd'}`"})  # fmt: skip
        if optimizer == "lm":
            for figure in figures[1:]:
                shutil.copyfile(figure, REPORTS / figure.name)
    seconds = time.perf_counter() - start
    console = (f"\nPaper 1 (AbIS), {metrics['frames_done']} frames x 3 views, in {seconds:.0f} s:\n" + "\n".join(lines)
               + f"\nFig 8: {REPORTS / 'fig8_part2_b1_r2.png'}\nFig 9: {REPORTS / 'fig9_part2_correspondences.png'}\n"
               f"Open a recording with: .venv/bin/rerun {REPORTS / 'abis_lm' / 'run.rrd'}")  # fmt: skip
    text = (f"## Paper 1: AbIS on the DSQ arm (Yonemoto et al. 1997)\n\n"
            f"{metrics['frames_done']} frames, 3 orthogonal views at 320x240, seed {metrics['seed']}, {seconds:.0f} s. "
            "The paper shows its accuracy as curves (Fig 8) and pairs (Fig 9); the numbers are ours.\n\n"
            + markdown(pd.DataFrame(rows)) + "\n\n"
            "![Fig 8: part 2's bending b1 and rotation r2, truth and estimate](fig8_part2_b1_r2.png)\n\n"
            "![Fig 9: part 2's image-model correspondences](fig9_part2_correspondences.png)\n")  # fmt: skip
    return Section(console, text)


def paper_2(paper_scale: bool) -> Section:
    start = time.perf_counter()
    experiment_dir, control_dir = REPORTS / "tbf_table4c", REPORTS / "tbf_table4c_clean"
    realism_dirs = {level: REPORTS / "tbf_realism" / f"realism_{level:g}" for level in REALISM_LEVELS}
    for directory in (experiment_dir, control_dir, REPORTS / "tbf_realism"):
        shutil.rmtree(directory, ignore_errors=True)
    for folder, overrides in EXPERIMENT_A_SWEEPS.items():
        print(f"paper 2: experiment A, {folder}, one job per core ...", flush=True)
        run_sweep("tbf_table4c", experiment_dir / folder, *overrides)
    print("paper 2: the clean control, 6 cells ...", flush=True)
    run_sweep("tbf_table4c_clean", control_dir, *TBF_CELLS, *LIGHT_RECORDING)
    for level, directory in realism_dirs.items():
        print(f"paper 2: realism {level:g}, 3 costs with dm2 ...", flush=True)
        run_sweep("tbf_table4c", directory, "cost=xor,wxor,nwxor", "motion=dm2", "scene.body.seed=0",
                  *realism_overrides(level), *LIGHT_RECORDING)  # fmt: skip
    directories = [experiment_dir, control_dir]
    if paper_scale:
        print("paper 2 at paper scale (the first run renders ~58,000 samples) ...", flush=True)
        directories.append(run_experiment("tbf_paper_scale", "tbf_paper_scale"))
    runs = collect(directories)
    written = write_reports(runs, REPORTS)
    figures = experiment_a_figures(runs, collect(list(realism_dirs.values())), REPORTS)
    four_c = table_4c(runs)
    rows = "\n".join(f"  {r.experiment:>17} {r.cost:>5} + {r.motion}: fail {r.fail}, error {r.error}, "
                     f"success {r.success}  "
                     + ("(paper: no such row)" if pd.isna(r.paper_fail) else
                        f"(paper: {r.paper_fail}, {r.paper_error}, {r.paper_success})") + f", MPJPE {r.mpjpe_mm} mm"
                     for r in four_c.itertuples())  # fmt: skip
    seconds = time.perf_counter() - start
    console = (f"\nPaper 2 (silhouette tree-based filtering), {len(runs)} runs in {seconds:.0f} s:\n{rows}\n"
               + "\n".join(f"  {path}" for path in [*written, *figures.values()]))  # fmt: skip
    return Section(console, paper_2_markdown(runs, seconds, figures, REPORTS))


def commit() -> str:
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head.stdout.strip() + (" with uncommitted changes" if dirty else "")


def write_report(sections: list[Section], seconds: float, scale: str) -> Path:
    when = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    text = ("# Reproduction report\n\n"
            f"Machine: {machine()}. Commit: {commit()}. Made {when} by `make reproduce"
            f"{' SCALE=paper' if scale == 'paper' else ''}` in {seconds / 60:.1f} min.\n\n"
            + "\n".join(section.markdown for section in sections))  # fmt: skip
    path = REPORTS / "report.md"
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scale", choices=("default", "paper"), default="default",
                        help="paper: also the paper-scale preset (~58,000 samples)")  # fmt: skip
    args = parser.parse_args(argv)
    start = time.perf_counter()
    REPORTS.mkdir(exist_ok=True)
    sections = [paper_1(), paper_2(args.scale == "paper")]
    for section in sections:
        print(section.console)
    report = write_report(sections, time.perf_counter() - start, args.scale)
    print(f"\nreport: {report} ({(time.perf_counter() - start) / 60:.1f} min)")


if __name__ == "__main__":
    main()
