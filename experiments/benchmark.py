"""The real-motion benchmark: every row (a tracker setup) on every test clip of a split, whole, each clip with a
subject of its own, into ``reports/benchmark/<clip>/<row>/``; the table ``reports/benchmark.md`` / ``.csv`` (per
clip, then mean ± std over clips: `eval.benchmark`), and per clip and row Fig 5's strip and the error against the
dictionary's floor.

    python -m experiments.benchmark [--split cmu] [--rows tbf_1_view ...] [--clips test|validation] [--reports reports]

``--clips validation`` runs the split's validation clips instead, into ``reports/benchmark_validation/`` and
``reports/benchmark_validation.md``: where a setting is chosen, never on the test clips.

The split (`experiments.benchmark_split`, ``conf/benchmark/cmu.yaml``) is checked before anything runs. Every
row that searches a dictionary (its tracker has ``samples``) builds it from the split's dictionary clips, at the
split's rate; a subject drawn per clip (`Split.subject`) is tracked by each row's own choice of body (the presets':
the nearest standard body). A run finished earlier with the same overrides and the same config they compose today
is kept, so adding a row or a clip runs only what is new (a preset changed since runs again); a failed run is a row
of the table, marked failed, and the others go on.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import yaml
from omegaconf import open_dict

from eval.benchmark import COLUMNS, LOSS_LEGEND, benchmark_table, loss_table, summary_table
from eval.body_figures import error_against_floor, fig5_strip
from eval.runs import markdown
from experiments.benchmark_split import Row, Split, SplitError, load_split
from experiments.cli_runs import exit_interrupted, run_child, write_text
from experiments.components import compose
from experiments.job import finished_metrics
from experiments.steps import Section, Step
from tracker.motion.mocap import available_frames, read_clip

# Kept in the runs: the first view's images for Fig 5; no meshes or parameters (long clips).
RECORDING = ("record.meshes_every=0", "record.parameters=false")


def searches_dictionary(row: Row) -> bool:
    """Whether the row's tracker builds its samples from clips (its config has ``tracker.samples``)."""
    return "samples" in compose([f"experiment={row.experiment}", *row.overrides]).tracker


def clip_overrides(split: Split, clip: str, dictionary: bool) -> list[str]:
    """The overrides that track ``clip`` whole with its own subject, from the split's dictionary if ``dictionary``."""
    true_fps = split.true_rate(clip)
    frames = available_frames(read_clip(clip, true_fps), 0.0, split.fps)
    subject = split.subject(clip)
    overrides = [
        f"scene.path={clip}",
        f"scene.fps={split.fps}",
        f"scene.true_fps={'null' if true_fps is None else true_fps}",
        f"frames={min(frames, split.max_frames or frames)}",
        *(f"model.shape.{name}={getattr(subject, name)}" for name in ("gender", "muscle", "weight", "height")),
    ]
    if dictionary:
        rates = ",".join(f"{{files:'{rate.files}',fps:{rate.fps}}}" for rate in split.true_fps)
        overrides += [
            f"tracker.samples.clips=[{','.join(split.clips('dictionary'))}]",
            f"tracker.samples.clip_true_fps=[{rates}]",
            f"tracker.samples.clip_fps={split.fps}",
        ]
    return overrides


def finished_with(run_dir: Path, overrides: list[str]) -> bool:
    """Whether ``run_dir`` holds a finished run of these very overrides that composes the same config today (kept: a
    benchmark resumes; a preset changed since, or a default, runs again)."""
    recorded = run_dir / ".hydra" / "overrides.yaml"
    if not recorded.exists() or yaml.safe_load(recorded.read_text()) != overrides:
        return False
    config = compose(overrides)
    with open_dict(config):
        del config["hydra"]  # a run's own config holds no hydra node (`experiments.run`)
    return finished_metrics(config, run_dir) is not None


def run_row(row: Row, run_dir: Path, overrides: list[str]) -> None:
    """One run through the real command line; a failure is recorded in its ``metrics.json``, not raised."""
    command = [f"experiment={row.experiment}", *overrides, *row.overrides, *RECORDING]
    if finished_with(run_dir, command):
        print(f"  kept: {run_dir}", flush=True)
        return
    run_child([sys.executable, "-m", "experiments.run", *command, f"hydra.run.dir={run_dir}"])


def frames_done(run_dir: Path) -> int:
    """How many frames the run in ``run_dir`` tracked (0 when it failed before its first, or never started)."""
    metrics = run_dir / "metrics.json"
    return int(json.loads(metrics.read_text()).get("frames_done", 0)) if metrics.exists() else 0


def run_benchmark(split: Split, rows: dict[str, Row], reports: Path, clips: str = "test") -> Section:
    """Every row on every clip of the list ``clips`` (test, or validation: where settings are chosen), one run after
    another (a paper-scale run takes much of the memory); then the tables and figures."""
    name = "benchmark" if clips == "test" else f"benchmark_{clips}"
    root = reports / name
    dictionary = {folder: searches_dictionary(row) for folder, row in rows.items()}
    figures = []
    for clip in split.clips(clips):
        for folder, row in rows.items():
            run_dir = root / Path(clip).stem / folder
            print(f"benchmark: {clip}, {row.label} ...", flush=True)
            run_row(row, run_dir, clip_overrides(split, clip, dictionary[folder]))
            if frames_done(run_dir):
                figures += [
                    fig5_strip(run_dir, run_dir / "fig5.png"),
                    error_against_floor(run_dir, run_dir / "error_against_floor.png", f"{clip}, {row.label}"),
                ]
    labels = {folder: row.label for folder, row in split.rows.items()}  # runs of other rows kept earlier too
    per_clip = benchmark_table(root, labels)
    summary = summary_table(per_clip, labels)
    write_text(reports / f"{name}.csv", per_clip.to_csv(index=False))
    where = f"Where each setup loses to the floor ({LOSS_LEGEND}):\n\n" + markdown(loss_table(per_clip, labels))
    text = markdown(summary) + "\n\n" + where + "\n\n" + markdown(per_clip[COLUMNS])
    write_text(reports / f"{name}.md", f"# Real-motion benchmark, {clips} clips\n\n" + text + "\n")
    section = (
        f"### The real-motion benchmark, {clips} clips\n\n"
        f"Every row on the {clips} clips ({', '.join(split.clips(clips))}), whole at {split.fps:g} fps; the "
        "dictionaries from the split's dictionary clips only. Mean ± std over clips, then per clip.\n\n" + text + "\n"
    )
    return Section(f"\nReal-motion benchmark:\n{text}\n" + "\n".join(f"  {f}" for f in figures), section)


def benchmark_step(reports: Path) -> Section:
    split = load_split("cmu")
    return run_benchmark(split, split.rows, reports)


STEP = Step(
    "The real-motion benchmark (SCALE=paper): every tracker setup on 5 test clips the dictionaries never held, "
    "each with a subject of its own",
    tuple(dict.fromkeys(row.experiment for row in load_split("cmu").rows.values())),
    ("benchmark.md", "benchmark.csv", "benchmark/<clip>/<row>/"),
    benchmark_step,
    scale="paper",
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", default="cmu", help="a split in conf/benchmark/ or a YAML file of one")
    parser.add_argument("--rows", nargs="+", help="the split's rows to run (default: every row)")
    parser.add_argument("--clips", choices=("test", "validation"), default="test", help="which of the split's clips")
    parser.add_argument("--reports", type=Path, default=Path("reports"))
    args = parser.parse_args(argv)
    try:
        split = load_split(args.split)
        unknown = [name for name in args.rows or () if name not in split.rows]
        if unknown:
            raise SplitError(f"--rows {unknown[0]}: not a row of the split: allowed {', '.join(split.rows)}")
    except SplitError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    rows = {name: row for name, row in split.rows.items() if not args.rows or name in args.rows}
    try:
        print(run_benchmark(split, rows, args.reports, args.clips).console)
    except KeyboardInterrupt as interrupt:  # the run under way wrote its outputs, marked interrupted: run it again
        exit_interrupted(interrupt)


if __name__ == "__main__":
    main()
