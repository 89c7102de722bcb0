"""Paper 2's steps of `experiments.reproduce`: experiment A under the paper's conditions swept over the cost, the
motion model and the subject's seed, its clean control (Fig 4(c), 6(d) and their pictures), and a sweep of its
realism; each with its part of ``report.md``.

Runs kept for their tables record lightly (`experiments.cli_runs.LIGHT_RECORDING`); the two cells the paper
compares (wXOR and nwXOR with DM2, first subject) keep images, meshes and parameters. Hydra sweeps a grid, so
experiment A is four multiruns.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pandas as pd

from eval.body_figures import posture_strip, realism_plot, swing_traces
from eval.cost_figures import competing_samples
from eval.paper_2_tables import table_4c, table_4c_bounds, table_6d, table_order
from eval.runs import collect, markdown
from eval.tables import write_reports
from experiments.cli_runs import LIGHT_RECORDING, run_sweep
from experiments.components import compose
from experiments.steps import Section, Step
from tracker.models.body_shapes import STANDARD_BODIES, MacroShape
from tracker.models.makehuman import build_body, nearest_standard_body

EXPERIMENT, CONTROL = "tbf_table4c", "tbf_table4c_clean"
TBF_CELLS = ("cost=xor,wxor,nwxor", "motion=dm1,dm2")  # the paper's 4 cells, and XOR beyond it
# Folder under reports/tbf_table4c -> its multirun's overrides: 6 cells x 3 seeds of the subject's variation.
EXPERIMENT_A_SWEEPS = {
    "recorded": ("cost=wxor,nwxor", "motion=dm2", "scene.body.seed=0"),
    "seed0_xor": ("cost=xor", "motion=dm1,dm2", "scene.body.seed=0", *LIGHT_RECORDING),
    "seed0_dm1": ("cost=wxor,nwxor", "motion=dm1", "scene.body.seed=0", *LIGHT_RECORDING),
    "seeds_1_2": (*TBF_CELLS, "scene.body.seed=1,2", *LIGHT_RECORDING),
}
REALISM_LEVELS = (0.0, 0.25, 0.5)  # swept below the experiment itself (1)
STRIP_FRAMES = (200, 206, 212, 218, 224, 230, 236)  # Fig 4(b): one swing of frames 200-240


def paper_2_markdown(runs: pd.DataFrame, figures: dict[str, Path], reports: Path) -> str:
    """Paper 2's part of report.md: Fig 4(c) under the paper's conditions and its control, the counts at other
    bounds, the figures, Fig 6(d), the recordings (named relative to ``reports``)."""
    four_c, bounds, six_d = table_4c(runs), table_4c_bounds(runs), table_6d(runs)
    experiment = runs[runs["experiment"] == "tbf_table4c"]
    first = json.loads((Path(experiment["run"].iloc[0]) / "metrics.json").read_text())
    text = (
        "## Paper 2: silhouette tree-based filtering (Okada & Stenger)\n\n"
        f"{len(runs)} runs. Swings are scored by the fixed rule of `tracker/evaluation/body.py` "
        "(the paper counted by eye); one parameter set serves every cell.\n\n"
        "### Fig 4(c): right-arm swings (of 24), under the paper's conditions\n\n"
        "`experiment=tbf_table4c`: a subject no standard body matches, swinging 24 times with a person's "
        "variation (three seeds of it: counts are mean ± std), tracked with samples from a capture session that "
        f"never held his motion. Chosen body: {_body_line(first)}. {int(first['samples']):,} samples, tree "
        f"{' / '.join(f'{n:,}' for n in first['tree_nodes'])} nodes (T_l {first['tree_thresholds']}, chosen for "
        "the paper's share of nodes per level). `tbf_table4c_clean` is the control: the subject is the model "
        "and the swing lies on the samples' grid.\n\n" + markdown(four_c) + "\n\n"
        "Success at other bounds of a swing's largest error (the rule's: 20°), and the swings followed "
        "(Success or Error):\n\n"
        + markdown(bounds)
        + "\n\n"
        + "".join(f"![{name}]({path.name})\n\n" for name, path in figures.items())
        + "### Fig 6(d): ms per frame\n\n"
        + markdown(six_d.round(2))
        + "\n"
    )
    named = [
        f"`{Path(r.run).relative_to(reports) / 'run.rrd'}` ({r.experiment}: {r.cost} + {r.motion})"
        for r in runs.itertuples()
    ]
    text += "\nRecordings: " + ", ".join(named) + "\n"
    return text


def _body_line(metrics: dict) -> str:
    body = metrics["body"]
    return (
        f"`{body['name']}` ({body['stature_m']:.3f} m, chest {body['chest_girth_m']:.3f} m) for a subject of "
        f"{body['subject_stature_m']:.3f} m, chest {body['subject_chest_girth_m']:.3f} m"
    )


def realism_overrides(level: float) -> list[str]:
    """``experiment=tbf_table4c`` at realism ``level`` (1: as it is): the subject's variation and the capture's
    natural variation scaled by ``level``, and the subject's shape moved from his nearest standard body (0: that
    body itself, so no mismatch) toward his own by ``level``."""
    cfg = compose(["experiment=tbf_table4c"])
    subject = MacroShape(**cfg.model.shape)
    standard = STANDARD_BODIES[
        nearest_standard_body(build_body(triangles=cfg.model.triangles, shape=subject), cfg.tracker.body_triangles)
    ]
    shape = {
        f.name: getattr(standard, f.name) + level * (getattr(subject, f.name) - getattr(standard, f.name))
        for f in dataclasses.fields(MacroShape)
    }
    return [
        f"scene.body.variation={level:g}",
        f"tracker.samples.capture.amplitude={level:g}",
        *(f"model.shape.{name}={value:.6g}" for name, value in shape.items()),
    ]


def experiment_a_figures(runs: pd.DataFrame, out: Path) -> dict[str, Path]:
    """The pictures of experiment A (`eval.body_figures`): each cell's swings (first subject's seed), the estimate
    over the input for nwXOR + DM2, and why wXOR and nwXOR erred where they erred most; PNGs in ``out``."""
    cells = first_subject_cells(runs)
    traces = swing_traces(cells, out / "fig4c_swings.png")
    strip_run = cells.get("nwxor + dm2", next(iter(cells.values())))
    strip = posture_strip(strip_run, STRIP_FRAMES, out / "fig4b_strip.png")
    recorded = {label: cells[label] for label in ("wxor + dm2", "nwxor + dm2") if label in cells}
    why = competing_samples(recorded, out / "fig4c_why.png")
    return {
        "Fig 4(c): the right arm's angle, truth and estimate, each swing's verdict (subject seed 0)": traces,
        "Fig 4(b): the estimated posture over the input (nwXOR + DM2, subject seed 0)": strip,
        "Why: at each cost's worst frame, the observation and its weights, the sample chosen and the sample "
        "nearest the truth in 3-D, with their distances (subject seed 0)": why,
    }


def first_subject_cells(runs: pd.DataFrame) -> dict[str, Path]:
    """Cell (``cost + motion``) -> its run of experiment A on the subject's first seed, in the table's order."""
    first_seed = runs["overrides"].str.split().map(lambda overrides: "scene.body.seed=0" in overrides)
    experiment = runs[(runs["experiment"] == EXPERIMENT) & first_seed]
    return {f"{r.cost} + {r.motion}": Path(r.run) for r in table_order(experiment).itertuples()}


def realism_figure(runs: pd.DataFrame, realism_runs: pd.DataFrame, out: Path) -> Path:
    """Success and swings followed against realism, each cost with DM2 on the subject's first seed: the realism
    sweep's runs, and experiment A's own (realism 1)."""
    experiment = runs[runs["run"].isin([str(path) for path in first_subject_cells(runs).values()])]
    points = [
        {"realism": 1.0, "cost": r.cost, "success": r.success, "followed": r.success + r.error}
        for r in experiment[experiment["motion"] == "dm2"].itertuples()
    ]
    for level, group in realism_runs.groupby(realism_runs["overrides"].map(_realism_of)):
        points += [
            {"realism": level, "cost": r.cost, "success": r.success, "followed": r.success + r.error}
            for r in group.itertuples()
        ]
    return realism_plot(pd.DataFrame(points), out / "fig4c_realism.png")


def _realism_of(overrides: str) -> float:
    return float(next(o.split("=")[1] for o in overrides.split() if o.startswith("scene.body.variation=")))


def experiment_a_step(reports: Path) -> Section:
    """Experiment A under the paper's conditions and its clean control, one job per core; Fig 4(c) and 6(d)."""
    experiment_dir, control_dir = reports / EXPERIMENT, reports / CONTROL
    for directory in (experiment_dir, control_dir):
        shutil.rmtree(directory, ignore_errors=True)
    for folder, overrides in EXPERIMENT_A_SWEEPS.items():
        print(f"paper 2: experiment A, {folder}, one job per core ...", flush=True)
        run_sweep(experiment_dir / folder, f"experiment={EXPERIMENT}", *overrides)
    print("paper 2: the clean control, 6 cells ...", flush=True)
    run_sweep(control_dir, f"experiment={CONTROL}", *TBF_CELLS, *LIGHT_RECORDING)
    runs = collect([experiment_dir, control_dir])
    written = write_reports(runs, reports)
    figures = experiment_a_figures(runs, reports)
    console = f"\nPaper 2, experiment A ({len(runs)} runs):\n{markdown(table_4c(runs))}\n" + "\n".join(
        f"  {path}" for path in [*written, *figures.values()]
    )
    return Section(console, paper_2_markdown(runs, figures, reports))


def realism_step(reports: Path) -> Section:
    """Experiment A at lower realism (each cost with DM2, the subject's first seed); success against realism."""
    root = reports / "tbf_realism"
    shutil.rmtree(root, ignore_errors=True)
    for level in REALISM_LEVELS:
        print(f"paper 2: realism {level:g}, 3 costs with dm2 ...", flush=True)
        run_sweep(
            root / f"realism_{level:g}",
            f"experiment={EXPERIMENT}",
            "cost=xor,wxor,nwxor",
            "motion=dm2",
            "scene.body.seed=0",
            *realism_overrides(level),
            *LIGHT_RECORDING,
        )
    figure = realism_figure(collect([reports / EXPERIMENT]), collect([root]), reports)
    caption = "Success (solid) and swings followed (dashed) against realism (DM2, subject seed 0)"
    return Section(f"  {figure}", f"### Realism\n\n![{caption}]({figure.name})\n")


STEPS = (
    Step(
        "Paper 2, Fig 4(c) and 6(d): experiment A, 6 cells x 3 subject seeds, and its clean control",
        (EXPERIMENT, CONTROL),
        ("table4c.md", "table6d.md", "fig4c_swings.png", "fig4b_strip.png", "fig4c_why.png"),
        experiment_a_step,
    ),
    Step(
        "Paper 2, realism: experiment A's three costs at lower realism",
        (EXPERIMENT,),
        ("fig4c_realism.png",),
        realism_step,
    ),
)
