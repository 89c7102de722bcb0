"""``make reproduce [SCALE=paper]``: regenerate what the papers report, into ``reports/``, summed up in
``reports/report.md`` (tables beside the papers' numbers, figures embedded, machine and commit named).

Paper 1 (AbIS, `experiments.paper_1`): the 3-part DSQ arm tracked from 3 orthogonal views with Levenberg-Marquardt
and with the paper's steepest descent, in the paper's elbow swing (``reports/abis_lm``, ``abis_sd``; Fig 8 and Fig 9
also at the top of ``reports/``) and in the upper arm's sweep in front of the forearm (``reports/abis_occlusion_lm``,
``_sd``: Fig 6-9); the seeds table over 10 seeds x optimiser x selection in both (``reports/abis_seeds.md``, the runs
in ``reports/abis_seeds/``).

Paper 2 (silhouette tree-based filtering): experiment A (24 right-arm swings, side-on) under the paper's
conditions (``experiment=tbf_table4c``: a subject unlike the standard bodies, a person's variation at three seeds,
samples from a capture session) swept over the cost and the motion model (XOR, wXOR and nwXOR with DM1 and DM2; the
paper has no XOR row) into ``reports/tbf_table4c/<job>/``, one job per core; the clean control
(``tbf_table4c_clean``) into ``reports/tbf_table4c_clean/``; a sweep of realism (DM2, three costs) into
``reports/tbf_realism/``. ``reports/table4c.md`` / ``.csv`` (Fig 4c, with each cell's largest errors and the counts
at other bounds) and ``reports/table6d.md`` (Fig 6d) come from them (`eval.tables`), and the figures
``fig4c_swings.png``, ``fig4b_strip.png``, ``fig4c_realism.png`` and ``fig4c_why.png`` (`eval.body_figures`; the
realism knob, the pictures and the report's text: `experiments.experiment_a`).

``--scale paper`` also tracks real motion the samples never held (`experiments.real_motion`: ``experiment=
tbf_paper_scale``, ~52,000 samples from 23 real clips, each held-out clip whole and an ablation row per part of the
build) into ``reports/tbf_real/``, with ``reports/tbf_real.md`` and Fig 5 per clip; its whole-build runs add their
timings to Fig 6(d). And the plug-board's comparison (`experiments.combinations`): those clips tracked from 1, 2
and 3 cameras, and paper 1's arm by AbIS and by tree filtering, in ``reports/combinations.md``.
"""

from __future__ import annotations

import argparse
import datetime
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from eval.paper_2_tables import table_4c
from eval.runs import collect, machine
from eval.tables import write_reports
from experiments.cli_runs import LIGHT_RECORDING, run_sweep
from experiments.combinations import combinations
from experiments.experiment_a import experiment_a_figures, paper_2_markdown, realism_overrides
from experiments.paper_1 import paper_1
from experiments.real_motion import HELD_OUT, real_motion
from tracker.atomic import atomic_path

REPORTS = Path("reports")
TBF_CELLS = ("cost=xor,wxor,nwxor", "motion=dm1,dm2")  # the paper's 4 cells, and XOR beyond it
REALISM_LEVELS = (0.0, 0.25, 0.5)  # swept below the experiment itself (1)
# Runs kept for their tables record lightly (`experiments.cli_runs.LIGHT_RECORDING`); the two cells the paper
# compares keep images, meshes and parameters.
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
        run_sweep(
            "tbf_table4c",
            directory,
            "cost=xor,wxor,nwxor",
            "motion=dm2",
            "scene.body.seed=0",
            *realism_overrides(level),
            *LIGHT_RECORDING,
        )
    directories = [experiment_dir, control_dir]
    real_console, real_markdown = real_motion(REPORTS) if paper_scale else ("", "")
    if paper_scale:
        directories += [REPORTS / "tbf_real" / Path(clip).stem / "full" for clip in HELD_OUT]
    runs = collect(directories)
    written = write_reports(runs, REPORTS)
    figures = experiment_a_figures(runs, collect(list(realism_dirs.values())), REPORTS)
    four_c = table_4c(runs)
    rows = "\n".join(
        f"  {r.experiment:>17} {r.cost:>5} + {r.motion}: fail {r.fail}, error {r.error}, "
        f"success {r.success}  "
        + (
            "(paper: no such row)"
            if pd.isna(r.paper_fail)
            else f"(paper: {r.paper_fail}, {r.paper_error}, {r.paper_success})"
        )
        + f", MPJPE {r.mpjpe_mm} mm"
        for r in four_c.itertuples()
    )
    seconds = time.perf_counter() - start
    console = (
        f"\nPaper 2 (silhouette tree-based filtering), {len(runs)} runs in {seconds:.0f} s:\n{rows}\n"
        + "\n".join(f"  {path}" for path in [*written, *figures.values()])
        + real_console
    )
    return Section(console, paper_2_markdown(runs, seconds, figures, REPORTS) + real_markdown)


def commit() -> str:
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head.stdout.strip() + (" with uncommitted changes" if dirty else "")


def write_report(sections: list[Section], seconds: float, scale: str) -> Path:
    when = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    text = (
        "# Reproduction report\n\n"
        f"Machine: {machine()}. Commit: {commit()}. Made {when} by `make reproduce"
        f"{' SCALE=paper' if scale == 'paper' else ''}` in {seconds / 60:.1f} min.\n\n"
        + "\n".join(section.markdown for section in sections)
    )
    path = REPORTS / "report.md"
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--scale",
        choices=("default", "paper"),
        default="default",
        help="paper: also real held-out motion at the paper's scale (~52,000 samples)",
    )
    args = parser.parse_args(argv)
    start = time.perf_counter()
    REPORTS.mkdir(exist_ok=True)
    sections = [Section(*paper_1(REPORTS)), paper_2(args.scale == "paper")]
    if args.scale == "paper":
        sections.append(Section(*combinations(REPORTS)))
    for section in sections:
        print(section.console)
    report = write_report(sections, time.perf_counter() - start, args.scale)
    print(f"\nreport: {report} ({(time.perf_counter() - start) / 60:.1f} min)")


if __name__ == "__main__":
    main()
