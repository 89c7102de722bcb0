"""Paper 1 in `experiments.reproduce`: AbIS on the DSQ arm in its two scenes with both optimisers (Fig 6-9), and the
seeds table (10 seeds x optimiser x selection in each scene), with its part of ``report.md``.

Scenes: ``abis_fig8_fig9``, the paper's elbow swing (the forearm hides end-on behind the upper arm in the left
view); ``abis_occlusion``, the upper arm sweeping in front of the still forearm in the front view, where the
z-buffer's selection has pairs to discard.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pandas as pd

from eval.abis_tables import B1_TARGET_PERCENT, R2_TARGET_DEG, abis_runs, seeds_table
from eval.figures import write_figures
from eval.runs import markdown
from experiments.cli_runs import LIGHT_RECORDING, run_experiment, run_sweep
from tracker.atomic import atomic_path

SCENES = {"abis_fig8_fig9": "the elbow swing", "abis_occlusion": "the upper arm's sweep"}
RUN_NAMES = {"abis_fig8_fig9": "abis", "abis_occlusion": "abis_occlusion"}  # reports/<name>_<optimiser>/
SEEDS = 10
SEEDS_SWEEP = (
    f"seed=range({SEEDS})",
    "tracker.fit.optimizer=lm,sd",
    "tracker.selection=zbuffer,none",
    *LIGHT_RECORDING,
)


def paper_1(reports: Path) -> tuple[str, str]:
    """Run paper 1's experiments into ``reports``; returns what the command prints and the report's section."""
    start = time.perf_counter()
    lines, rows, figures = [], [], {}
    for experiment, scene in SCENES.items():
        for optimizer in ("lm", "sd"):
            print(f"paper 1: AbIS in {scene} with {optimizer} ...", flush=True)
            run_dir = run_experiment(
                experiment, reports / f"{RUN_NAMES[experiment]}_{optimizer}", f"tracker.fit.optimizer={optimizer}"
            )
            written = write_figures(run_dir)
            metrics = json.loads((run_dir / "metrics.json").read_text())
            timing = json.loads((run_dir / "timings.json").read_text())
            b1_mm, b1_pct = metrics["part2_b1_rms"] * 1e3, 100 * metrics["part2_b1_rms"] / metrics["part2_b1_range"]
            lines.append(
                f"  {scene}, {optimizer}: part2_b1_rms {b1_mm:.1f} mm ({b1_pct:.1f}% of the b1 range), "
                f"part2_r2_rms {metrics['part2_r2_rms_deg']:.2f} deg, estimation "
                f"{timing['estimate_ms_median']:.0f} ms/frame (median), recording {run_dir / 'run.rrd'}"
            )
            rows.append(
                {
                    "scene": scene,
                    "optimiser": optimizer,
                    "part 2 b1 RMS (mm)": round(b1_mm, 1),
                    "b1 RMS (% of its range)": round(b1_pct, 1),
                    "part 2 r2 RMS (deg)": round(metrics["part2_r2_rms_deg"], 2),
                    "point-to-surface (mm)": round(metrics["mean_surface_distance_mm"], 1),
                    "estimation (ms/frame, median)": round(timing["estimate_ms_median"], 1),
                    "recording": f"`{run_dir.relative_to(reports) / 'run.rrd'}`",
                }
            )
            if optimizer == "lm":
                figures[experiment] = {path.stem: path.relative_to(reports) for path in written}
    for stem in ("fig8_part2_b1_r2", "fig9_part2_correspondences"):  # the paper's scene's, at the top of reports/
        shutil.copyfile(reports / figures["abis_fig8_fig9"][stem], reports / f"{stem}.png")
    seeds_dir = reports / "abis_seeds"
    shutil.rmtree(seeds_dir, ignore_errors=True)
    for experiment, scene in SCENES.items():
        print(f"paper 1: {SEEDS} seeds x optimiser x selection in {scene}, one job per core ...", flush=True)
        run_sweep(experiment, seeds_dir / experiment, *SEEDS_SWEEP)
    seeds = seeds_table(abis_runs([seeds_dir]))
    seeds_md = _write_seeds(seeds, reports)
    seconds = time.perf_counter() - start
    console = (
        f"\nPaper 1 (AbIS), {metrics['frames_done']} frames x 3 views per run, in {seconds:.0f} s:\n"
        + "\n".join(lines)
        + "\nseeds:\n"
        + markdown(seeds)
        + f"\n  {seeds_md}\n"
        f"Open a recording with: .venv/bin/rerun {reports / 'abis_lm' / 'run.rrd'}"
    )
    return console, _section(rows, seeds, figures, metrics, seconds)


def _write_seeds(seeds: pd.DataFrame, reports: Path) -> Path:
    with atomic_path(reports / "abis_seeds.csv") as temporary:
        seeds.to_csv(temporary, index=False)
    with atomic_path(reports / "abis_seeds.md") as temporary:
        temporary.write_text("# Paper 1: AbIS over seeds\n\n" + _seeds_caption() + markdown(seeds) + "\n")
    return reports / "abis_seeds.md"


def _seeds_caption() -> str:
    return (
        f"Each row: {SEEDS} seeds (the seed draws the textures and the frame-0 noise). Fig 8's targets: part 2's "
        f"b1 RMS within {B1_TARGET_PERCENT:g}% of its range and r2 RMS within {R2_TARGET_DEG:g} deg. Selection "
        "`zbuffer` is the paper's model-image selection; `none` keeps every pair through occlusion and pairs "
        "features with any sample facing the camera (bottom-up tracking). The last column counts part 2's pairs "
        "that left, per run: discarded for occlusion, lost by the feature tracker, discarded as false.\n\n"
    )


def _section(rows: list[dict], seeds: pd.DataFrame, figures: dict, metrics: dict, seconds: float) -> str:
    swing, sweep = figures["abis_fig8_fig9"], figures["abis_occlusion"]
    return (
        f"## Paper 1: AbIS on the DSQ arm (Yonemoto et al. 1997)\n\n"
        f"{metrics['frames_done']} frames per run, 3 orthogonal views at 320x240, seed {metrics['seed']}, "
        f"{seconds:.0f} s in all. The paper shows its accuracy as curves (Fig 8) and pairs (Fig 9); the numbers "
        "are ours. Two scenes: the paper's elbow swing (`experiment=abis_fig8_fig9`), and the upper arm "
        "sweeping in front of the still forearm in the front view (`experiment=abis_occlusion`), where the "
        "model's selection has pairs to discard.\n\n" + markdown(pd.DataFrame(rows)) + "\n\n"
        "### The elbow swing\n\n"
        f"![Fig 8: part 2's bending b1 and rotation r2, truth and estimate]({swing['fig8_part2_b1_r2']})\n\n"
        f"![Fig 9: part 2's image-model correspondences]({swing['fig9_part2_correspondences']})\n\n"
        "### The upper arm's sweep in front of the forearm\n\n"
        f"![Fig 6: the input images from the three views]({sweep['fig6_input_views']})\n\n"
        f"![Fig 7: the estimated model rendered from the same views]({sweep['fig7_estimated_views']})\n\n"
        f"![Fig 8 in the sweep]({sweep['fig8_part2_b1_r2']})\n\n"
        f"![Fig 9 in the sweep: part 2's pairs; grey where it is hidden in a view]"
        f"({sweep['fig9_part2_correspondences']})\n\n"
        "### Over seeds, with and without the model's selection\n\n" + _seeds_caption() + markdown(seeds) + "\n"
    )
