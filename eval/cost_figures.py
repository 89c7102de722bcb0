"""Why a silhouette cost goes wrong (paper 2's experiment A): at a run's worst frame, the observation as the filter
saw it with the cost's weight map, and the sample the filter chose against the sample nearest the truth in 3-D,
each drawn against the observation with its distance under the run's cost."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from eval.plotting import pyplot, save_png
from eval.recordings import read_images
from tracker.evaluation.body import nearest_in_3d
from tracker.registry import build_chosen
from tracker.tbf.alignment import shifted
from tracker.tbf.costs import weight_map
from tracker.tbf.samples import LEVEL_RESOLUTIONS
from tracker.tbf.scoring import ObservationScorer


def competing_samples(runs: Mapping[str, Path], out: Path) -> Path:
    """Why a cost goes wrong, for the worst frame of each run (label -> run folder, recorded with images): the
    observed silhouette as the filter saw it (moved onto the samples' feet) with the cost's weight map d_P, then the
    sample the filter chose and the sample nearest the truth in 3-D, each drawn against the observation (grey both,
    red only the observation, blue only the sample) with its distance under the run's cost. When the chosen
    sample's distance is the smaller, the cost itself preferred the wrong posture."""
    plt = pyplot()
    figure, axes = plt.subplots(len(runs), 3, figsize=(9.0, 3.0 * len(runs)), squeeze=False)
    for row, (label, run_dir) in enumerate(runs.items()):
        subject, tracker, table = _restarted_tracker(run_dir)
        frame = int((table["swing_est_deg"] - table["swing_truth_deg"]).abs().idxmax())
        observed = read_images(run_dir / "run.rrd", f"/world/cameras/{tracker.cameras[0].name}/image/silhouette")[frame]
        du, dv = (
            int(table.loc[frame, c]) if c in table and pd.notna(table.loc[frame, c]) else 0
            for c in ("align_du_px", "align_dv_px")
        )
        observed = shifted(observed.astype(bool), du, dv)
        stack = tracker.samples.sets[0].silhouettes(LEVEL_RESOLUTIONS[-1])  # experiment A: one camera
        scores = ObservationScorer(tracker.cost, observed, stack.window).scores(stack)
        chosen = int(table.loc[frame, "est_sample"])
        nearest = int(
            nearest_in_3d(
                subject,
                np.asarray(table.loc[frame, "truth_pose"])[None],
                tracker.dictionary.model,
                tracker.samples.poses,
            )[0][0]
        )
        axes[row, 0].imshow(weight_map(tracker.cost, observed, stack.window), cmap="magma")
        axes[row, 0].set_title(f"{label}, frame {frame}: observed, d_P", fontsize=8)
        for column, (name, index) in enumerate((("chosen", chosen), ("nearest in 3-D", nearest)), start=1):
            model = np.zeros_like(observed)
            u0, v0, u1, v1 = stack.window
            model[v0:v1, u0:u1] = stack.mask(index)
            overlay = np.full(observed.shape + (3,), 255, np.uint8)
            overlay[observed & model] = (150, 150, 150)
            overlay[observed & ~model] = (220, 40, 40)
            overlay[~observed & model] = (40, 90, 220)
            axes[row, column].imshow(overlay)
            swing = tracker.dictionary.model.right_arm_swing_deg(tracker.samples.poses[index])
            axes[row, column].set_title(
                f"{name}: arm {swing:.0f}° (truth {table.loc[frame, 'swing_truth_deg']:.0f}°), d = {scores[index]:.4g}",
                fontsize=8,
            )
        for axis in axes[row]:
            axis.set_xticks([]), axis.set_yticks([])
            axis.set_xlim(stack.window[0], stack.window[2]), axis.set_ylim(stack.window[3], stack.window[1])
    return save_png(plt, figure, out)


def _restarted_tracker(run_dir: Path):
    """The run's subject and its tracker started again from the run's config (its samples and tree come from the
    cache), and the run's table one row per frame."""
    built = build_chosen(json.loads((run_dir / "metrics.json").read_text())["config"])
    table = pd.read_parquet(run_dir / "frames.parquet").drop_duplicates("frame").set_index("frame")
    subject, tracker = built["model"], built["tracker"]
    tracker.start(subject, built["rig"], np.asarray(table.iloc[0]["truth_pose"]), np.random.default_rng(0))
    return subject, tracker, table
