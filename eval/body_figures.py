"""Paper 2's experiment A as pictures: the right arm's angle per cell with each swing's verdict (Fig 4c's
evidence), frames with the estimated posture drawn over the input (Fig 4b), success against realism, and the
samples a cost weighed at its worst frame (why it went wrong).

Verdict colours: Success green, Error orange, Fail red (`tracker.evaluation.body`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from eval.figures import pyplot, save_png
from eval.recordings import read_images, read_rgb_frames
from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.evaluation.body import SwingRule, nearest_in_3d, outcome
from tracker.models.body_shapes import standard_shape
from tracker.models.body_skeleton import JOINT_INDEX, JOINT_NAMES, PART_BONES, PART_COLORS
from tracker.models.makehuman import build_body
from tracker.registry import REGISTRIES, build_chosen
from tracker.tbf.alignment import shifted
from tracker.tbf.costs import weight_map
from tracker.tbf.samples import LEVEL_RESOLUTIONS
from tracker.tbf.scoring import ObservationScorer

VERDICT_COLORS = {"success": "#2ca02c", "error": "#ff7f0e", "fail": "#d62728"}
# The skeleton drawn: every bone from its parent down to the hands and feet (fingers and toes left out).
_DRAWN = [name for name in JOINT_NAMES if not any(s in name for s in ("Finger", "Index", "Thumb", "Toe"))]


def swing_traces(runs: Mapping[str, Path], out: Path, bound_deg: float = SwingRule.max_error_deg) -> Path:
    """One panel per run (label -> run folder): the right arm's angle over time, truth against estimate, each
    swing shaded by its verdict at the rule's bound."""
    plt = pyplot()
    figure, axes = plt.subplots(len(runs), 1, figsize=(12, 1.9 * len(runs)), sharex=True, squeeze=False)
    for axis, (label, run_dir) in zip(axes[:, 0], runs.items(), strict=True):
        frames = pd.read_parquet(run_dir / "frames.parquet").drop_duplicates("frame")
        details = json.loads((run_dir / "metrics.json").read_text())["swing_details"]
        verdicts = [
            outcome(followed, error, bound_deg)
            for followed, error in zip(details["followed"], details["max_error_deg"], strict=True)
        ]
        for start, stop, verdict in zip(details["start"], details["stop"], verdicts, strict=True):
            axis.axvspan(start - 0.5, stop - 0.5, color=VERDICT_COLORS[verdict], alpha=0.18, linewidth=0)
        axis.plot(frames["frame"], frames["swing_truth_deg"], color="black", linewidth=1.0, label="truth")
        axis.plot(frames["frame"], frames["swing_est_deg"], color="#1f77b4", linewidth=1.0, label="estimate")
        counts = {verdict: verdicts.count(verdict) for verdict in VERDICT_COLORS}
        axis.set_ylabel("deg")
        axis.set_title(
            f"{label}: success {counts['success']}, error {counts['error']}, fail {counts['fail']}",
            fontsize=9,
            loc="left",
        )
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=2)
    axes[-1, 0].set_xlabel("frame (shading: each swing's verdict, green success / orange error / red fail)")
    return save_png(plt, figure, out)


def swing_caption(frame: int, row: pd.Series) -> str:
    return f"frame {frame}: truth {row['swing_truth_deg']:.0f}°, estimate {row['swing_est_deg']:.0f}°"


def error_caption(frame: int, row: pd.Series) -> str:
    return f"frame {frame}: {row['joint_error_mm']:.0f} mm ({row['joint_error_aligned_mm']:.0f} aligned)"


def posture_strip(run_dir: Path, frames: Sequence[int], out: Path, caption=swing_caption) -> Path:
    """Paper 2's Fig 4(b) and Fig 5: the input frames with the estimated posture's skeleton drawn over them (the
    tracker's standard body, projected by the run's camera; bones in their part's colour), each titled by
    ``caption(frame, its frames.parquet row)``."""
    plt = pyplot()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    config = metrics["config"]
    rigs = REGISTRIES["rig"]
    camera = rigs.build(rigs.entry_for(config["rig"]["_target_"]).name, config["rig"])[0]
    body_name = metrics.get("body", {}).get("name", "base")
    body = build_body(triangles=config["tracker"]["body_triangles"], shape=standard_shape(body_name))
    table = pd.read_parquet(run_dir / "frames.parquet").drop_duplicates("frame").set_index("frame")
    images = read_rgb_frames(run_dir / "run.rrd", camera.name)
    part_of = {bone: part for part, bones in enumerate(PART_BONES.values()) for bone in bones}
    figure, axes = plt.subplots(1, len(frames), figsize=(1.9 * len(frames), 2.6), squeeze=False)
    for axis, frame in zip(axes[0], frames, strict=True):
        image = images[frame]
        axis.imshow(image)
        truth_pixels, _ = camera.project(body.joint_positions(np.asarray(table.loc[frame, "truth_pose"])))
        middle = np.nanmean(truth_pixels[:, 0])
        axis.set_xlim(max(middle - 0.3 * image.shape[1], 0), min(middle + 0.3 * image.shape[1], image.shape[1]))
        estimate = table.loc[frame, "est_pose"]
        if estimate is not None and len(estimate):
            pixels, _ = camera.project(body.joint_positions(np.asarray(estimate)))
            for name in _DRAWN:
                parent = body.parents[JOINT_INDEX[name]]
                if parent < 0:
                    continue
                (u0, v0), (u1, v1) = pixels[parent], pixels[JOINT_INDEX[name]]
                axis.plot([u0, u1], [v0, v1], color=np.array(PART_COLORS[part_of[name]]) / 255, linewidth=2)
        axis.set_title(caption(frame, table.loc[frame]), fontsize=7)
        axis.set_xticks([]), axis.set_yticks([])
    return save_png(plt, figure, out)


def realism_plot(table: pd.DataFrame, out: Path) -> Path:
    """Each cost's swings (of 24) against the realism knob: Success solid, followed (Success or Error) dashed.
    ``table``: columns ``realism``, ``cost``, ``success``, ``followed``."""
    plt = pyplot()
    figure, axis = plt.subplots(figsize=(6.4, 3.6))
    for k, (cost, group) in enumerate(table.sort_values("realism").groupby("cost", sort=False)):
        color = f"C{k}"
        axis.plot(group["realism"], group["success"], "o-", color=color, label=f"{cost}: success")
        axis.plot(group["realism"], group["followed"], "s--", color=color, alpha=0.7, label=f"{cost}: followed")
    axis.set_xlabel("realism (0: a clean swing and a standard-body subject; 1: the full experiment)")
    axis.set_ylabel("swings of 24")
    axis.set_ylim(-0.5, 24.5)
    axis.legend(fontsize=7, ncol=2)
    return save_png(plt, figure, out)


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
