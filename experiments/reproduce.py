"""``make reproduce [SCALE=paper]``: regenerate what the papers report, into ``reports/``, summed up in
``reports/report.md``: a table of the steps with the minutes each took, then each step's tables beside the papers'
numbers, its figures and recordings, the machine and the commit.

The steps (`STEPS`; each says what it runs and writes): paper 1's figures and its seeds table
(`experiments.paper_1`), paper 2's experiment A with its control and its realism sweep (`experiments.experiment_a`);
with ``--scale paper`` also experiment B on real held-out motion (`experiments.real_motion`), the plug-board's
comparison of every tracker on every model (`experiments.combinations`), tree filtering's cost against its
dictionary's size (`experiments.bench.scale`) and the real-motion benchmark (`experiments.benchmark`).

``--readme`` copies the steps table of the last ``reports/report.md`` into the README (its timings taken from a
report, not typed by hand).
"""

from __future__ import annotations

import argparse
import datetime
import subprocess
import time
from pathlib import Path

import pandas as pd

from eval.runs import machine, markdown
from experiments import benchmark, combinations, experiment_a, paper_1, real_motion
from experiments.bench import scale
from experiments.cli_runs import exit_interrupted, write_text
from experiments.generated import README, markers, write_block
from experiments.steps import Section, Step

REPORTS = Path("reports")
STEPS: tuple[Step, ...] = (
    *paper_1.STEPS,
    *experiment_a.STEPS,
    real_motion.STEP,
    combinations.STEP,
    scale.STEP,
    benchmark.STEP,
)
README_COMMAND = "python -m experiments.reproduce --readme"
STEPS_BLOCK = "steps"  # report.md's steps table, between these markers


def run_steps(scale: str) -> list[tuple[Step, Section, float]]:
    """Every step of ``scale`` (``default``: the papers' tables and figures; ``paper`` adds the rest), timed."""
    done = []
    for step in STEPS:
        if step.scale == "default" or scale == "paper":
            start = time.perf_counter()
            section = step.run(REPORTS)
            done.append((step, section, (time.perf_counter() - start) / 60))
    return done


def steps_table(done: list[tuple[Step, Section, float | None]]) -> str:
    rows = [
        {
            "step": step.title,
            "presets": ", ".join(f"`{preset}`" for preset in step.presets),
            "writes (in reports/)": ", ".join(f"`{output}`" for output in step.outputs),
            "minutes": NOT_IN_REPORT if minutes is None else f"{minutes:.1f}",
        }
        for step, _, minutes in done
    ]
    return markdown(pd.DataFrame(rows))


NOT_IN_REPORT = "not in that report"  # the minutes of a step the report was made without (added since)


def commit() -> str:
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head.stdout.strip() + (" with uncommitted changes" if dirty else "")


def write_report(done: list[tuple[Step, Section, float]], minutes: float, scale: str) -> Path:
    when = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    begin, end = markers(STEPS_BLOCK, "make reproduce")
    text = (
        "# Reproduction report\n\n"
        f"Machine: {machine()}. Commit: {commit()}. Made {when} by `make reproduce"
        f"{' SCALE=paper' if scale == 'paper' else ''}` in {minutes:.1f} min (the steps below; setup not "
        "counted).\n\n"
        f"{begin}\n{steps_table(done)}\n{end}\n\n" + "\n".join(section.markdown for _, section, _ in done)
    )
    return write_text(REPORTS / "report.md", text)


def readme_from_report(report: Path = REPORTS / "report.md", readme: Path = README) -> None:
    """The steps table of ``report`` into the README's block."""
    begin, end = markers(STEPS_BLOCK, "make reproduce")
    text = report.read_text()
    if begin not in text:
        raise SystemExit(f"{report} has no steps table: run make reproduce first")
    table = text.split(begin, 1)[1].split(end, 1)[0].strip()
    minutes = {row.split(" | ")[0].lstrip("| "): row.rstrip(" |").rsplit(" | ", 1)[1] for row in table.splitlines()[2:]}
    known = [(step, Section("", ""), float(minutes[step.title]) if step.title in minutes else None) for step in STEPS]
    write_block(readme, "reproduce", README_COMMAND, steps_table(known))
    print(f"wrote the steps table of {report} into {readme}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--scale", choices=("default", "paper"), default="default", help="paper: also real motion at paper scale"
    )
    parser.add_argument("--readme", action="store_true", help="copy the last report's steps table into README.md")
    args = parser.parse_args(argv)
    if args.readme:
        return readme_from_report()
    start = time.perf_counter()
    REPORTS.mkdir(exist_ok=True)
    try:
        done = run_steps(args.scale)
    except KeyboardInterrupt as interrupt:  # the run under way wrote its outputs, marked interrupted
        exit_interrupted(interrupt)
    for _, section, _ in done:
        print(section.console)
    report = write_report(done, (time.perf_counter() - start) / 60, args.scale)
    print(f"\nreport: {report} ({(time.perf_counter() - start) / 60:.1f} min)")


if __name__ == "__main__":
    main()
