"""Paper 1's steps of `experiments.reproduce`: AbIS on the DSQ arm in its two scenes with both optimisers (Fig 6-9),
and the seeds table (10 seeds x optimiser x selection in each scene), each with its part of ``report.md``.

Scenes: ``abis_fig8_fig9``, the paper's elbow swing (the forearm hides end-on behind the upper arm in the left
view); ``abis_occlusion``, the upper arm sweeping in front of the still forearm in the front view, where the
z-buffer's selection has pairs to discard. The figures' four runs (seed 0, the paper's selection) are also the
seeds table's seed-0 rows of that selection: each run is made once.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd

from eval.abis_tables import B1_TARGET_PERCENT, R2_TARGET_DEG, abis_runs, seeds_table
from eval.figures import write_figures
from eval.runs import markdown
from experiments.cli_runs import LIGHT_RECORDING, run_sweep, write_text
from experiments.steps import Section, Step

SCENES = {"abis_fig8_fig9": "the elbow swing", "abis_occlusion": "the upper arm's sweep"}
OPTIMIZERS = ("lm", "sd")
SEEDS = 10
FIGURES = "abis"  # reports/abis/<experiment>_<optimizer>/: the figures' runs, recorded whole
SEEDS_DIR = "abis_seeds"
BOTH_SCENES = ("experiment=" + ",".join(SCENES), "tracker=abis")  # the tracker named: a sweep composes without them
NAMED_BY_SCENE = "hydra.sweep.subdir=${hydra:runtime.choices.experiment}_${tracker.fit.optimizer}"


def figures_step(reports: Path) -> Section:
    """The four figure runs (one job per core), every figure each supports, and Fig 8-9 of the elbow swing on top."""
    root = reports / FIGURES
    shutil.rmtree(root, ignore_errors=True)
    print("paper 1: AbIS in both scenes with both optimisers, one job per core ...", flush=True)
    run_sweep(root, *BOTH_SCENES, f"tracker.fit.optimizer={','.join(OPTIMIZERS)}", NAMED_BY_SCENE)
    rows, figures = [], {}
    for experiment, scene in SCENES.items():
        for optimizer in OPTIMIZERS:
            run_dir = root / f"{experiment}_{optimizer}"
            written = write_figures(run_dir)
            rows.append(_row(run_dir, scene, optimizer, reports))
            if optimizer == "lm":
                figures[experiment] = {path.stem: path.relative_to(reports) for path in written}
    for stem in ("fig8_part2_b1_r2", "fig9_part2_correspondences"):  # the paper's scene's, at the top of reports/
        shutil.copyfile(reports / figures["abis_fig8_fig9"][stem], reports / f"{stem}.png")
    table = pd.DataFrame(rows)
    console = f"\nPaper 1 (AbIS):\n{markdown(table)}\nOpen a recording with: .venv/bin/rerun {rows[0]['recording']}"
    return Section(console, _figures_section(table, figures))


def _row(run_dir: Path, scene: str, optimizer: str, reports: Path) -> dict:
    metrics = json.loads((run_dir / "metrics.json").read_text())
    timing = json.loads((run_dir / "timings.json").read_text())
    b1_mm, b1_pct = metrics["part2_b1_rms"] * 1e3, 100 * metrics["part2_b1_rms"] / metrics["part2_b1_range"]
    return {
        "scene": scene,
        "optimiser": optimizer,
        "frames": metrics["frames_done"],
        "part 2 b1 RMS (mm)": round(b1_mm, 1),
        "b1 RMS (% of its range)": round(b1_pct, 1),
        "part 2 r2 RMS (deg)": round(metrics["part2_r2_rms_deg"], 2),
        "point-to-surface (mm)": round(metrics["mean_surface_distance_mm"], 1),
        "estimation (ms/frame, median)": round(timing["estimate_ms_median"], 1),
        "recording": f"`{run_dir.relative_to(reports) / 'run.rrd'}`",
    }


def _figures_section(table: pd.DataFrame, figures: dict) -> str:
    swing, sweep = figures["abis_fig8_fig9"], figures["abis_occlusion"]
    return (
        "## Paper 1: AbIS on the DSQ arm (Yonemoto et al. 1997)\n\n"
        "3 orthogonal views at 320x240, seed 0. The paper shows its accuracy as curves (Fig 8) and pairs (Fig 9); "
        "the numbers are ours. Two scenes: the paper's elbow swing (`experiment=abis_fig8_fig9`), and the upper "
        "arm sweeping in front of the still forearm in the front view (`experiment=abis_occlusion`), where the "
        "model's selection has pairs to discard.\n\n" + markdown(table) + "\n\n"
        "### The elbow swing\n\n"
        f"![Fig 8: part 2's bending b1 and rotation r2, truth and estimate]({swing['fig8_part2_b1_r2']})\n\n"
        f"![Fig 9: part 2's image-model correspondences]({swing['fig9_part2_correspondences']})\n\n"
        "### The upper arm's sweep in front of the forearm\n\n"
        f"![Fig 6: the input images from the three views]({sweep['fig6_input_views']})\n\n"
        f"![Fig 7: the estimated model rendered from the same views]({sweep['fig7_estimated_views']})\n\n"
        f"![Fig 8 in the sweep]({sweep['fig8_part2_b1_r2']})\n\n"
        f"![Fig 9 in the sweep: part 2's pairs; grey where it is hidden in a view]"
        f"({sweep['fig9_part2_correspondences']})\n"
    )


def seeds_step(reports: Path) -> Section:
    """Every seed, optimiser and selection in both scenes, one job per core, but the figures' four runs (the seed-0
    rows of the paper's selection), which the table reads where they are."""
    root = reports / SEEDS_DIR
    shutil.rmtree(root, ignore_errors=True)
    optimizers = f"tracker.fit.optimizer={','.join(OPTIMIZERS)}"
    print(f"paper 1: {SEEDS} seeds x optimiser x selection in both scenes, one job per core ...", flush=True)
    run_sweep(root / "zbuffer", *BOTH_SCENES, f"seed=range(1,{SEEDS})", optimizers, *LIGHT_RECORDING)
    run_sweep(
        root / "none", *BOTH_SCENES, f"seed=range({SEEDS})", optimizers, "tracker.selection=none", *LIGHT_RECORDING
    )
    seeds = seeds_table(abis_runs([reports / FIGURES, root]))
    text = _seeds_caption() + markdown(seeds)
    write_text(reports / "abis_seeds.md", "# Paper 1: AbIS over seeds\n\n" + text + "\n")
    write_text(reports / "abis_seeds.csv", seeds.to_csv(index=False))
    return Section(
        f"\nPaper 1 over seeds:\n{markdown(seeds)}",
        f"### Over seeds, with and without the model's selection\n\n{text}\n",
    )


def _seeds_caption() -> str:
    return (
        f"Each row: {SEEDS} seeds (the seed draws the textures and the frame-0 noise). Fig 8's targets: part 2's "
        f"b1 RMS within {B1_TARGET_PERCENT:g}% of its range and r2 RMS within {R2_TARGET_DEG:g} deg. Selection "
        "`zbuffer` is the paper's model-image selection; `none` keeps every pair through occlusion and pairs "
        "features with any sample facing the camera (bottom-up tracking). The last column counts part 2's pairs "
        "that left, per run: discarded for occlusion, lost by the feature tracker, discarded as false.\n\n"
    )


STEPS = (
    Step(
        "Paper 1, Fig 6-9: the arm by AbIS with both optimisers, in the elbow swing and the upper arm's sweep",
        ("abis_fig8_fig9", "abis_occlusion"),
        ("fig8_part2_b1_r2.png", "fig9_part2_correspondences.png", f"{FIGURES}/"),
        figures_step,
    ),
    Step(
        f"Paper 1, over seeds: {SEEDS} seeds x optimiser x selection in both scenes",
        ("abis_fig8_fig9", "abis_occlusion"),
        ("abis_seeds.md",),
        seeds_step,
    ),
)
