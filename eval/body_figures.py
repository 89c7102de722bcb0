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

from eval.plotting import pyplot, save_png
from eval.recordings import read_rgb_frames
from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.evaluation.body import SwingRule, outcome
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_shapes import standard_shape
from tracker.models.body_skeleton import JOINT_INDEX, JOINT_NAMES, PART_BONES, PART_COLORS
from tracker.models.makehuman import build_body
from tracker.registry import build_chosen, chosen_entries

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


def estimated_body(metrics: dict) -> BodyMesh:
    """The body a run's estimated poses belong to: the tracker's own standard body where it chose one (tree
    filtering, ``body`` in its metrics), else the run's model (AbIS tracks the subject's own mesh)."""
    config = metrics["config"]
    if "body" in metrics:
        return build_body(triangles=config["tracker"]["body_triangles"], shape=standard_shape(metrics["body"]["name"]))
    return chosen_entries(config)["model"].build(config["model"])


def posture_strip(run_dir: Path, frames: Sequence[int], out: Path, caption=swing_caption) -> Path:
    """Paper 2's Fig 4(b) and Fig 5: the input frames of the run's first camera with the estimated posture's
    skeleton drawn over them (`estimated_body`, projected by the camera; bones in their part's colour), each titled
    by ``caption(frame, its frames.parquet row)``."""
    plt = pyplot()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    camera = build_chosen(metrics["config"])["rig"][0]
    body = estimated_body(metrics)
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


def fig5_strip(run_dir: Path, out: Path, count: int = 7) -> Path:
    """Paper 2's Fig 5 for one clip: ``count`` frames spread over the run with the estimate drawn over the input."""
    frames = pd.read_parquet(run_dir / "frames.parquet", columns=["frame"])["frame"].unique()
    picked = np.unique(np.linspace(0, len(frames) - 1, count).round().astype(int))
    return posture_strip(run_dir, [int(frames[k]) for k in picked], out, caption=error_caption)


def error_against_floor(run_dir: Path, out: Path, label: str | None = None) -> Path:
    """Per frame: the joint error (absolute and root-aligned), against the dictionary's floor where the tracker
    searched one, with the frames where its own cost prefers the estimate to the floor's sample shaded
    (ambiguous). ``label``: what the title calls the run (its folder's name)."""
    plt = pyplot()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    table = pd.read_parquet(run_dir / "frames.parquet").drop_duplicates("frame")
    figure, axis = plt.subplots(figsize=(10, 2.8))
    for frame, ambiguous in zip(table["frame"], metrics.get("ambiguous_per_frame", ()), strict=False):
        if ambiguous:
            axis.axvspan(frame - 0.5, frame + 0.5, color="#d62728", alpha=0.12, linewidth=0)
    axis.plot(table["frame"], table["joint_error_mm"], color="#1f77b4", linewidth=1.0, label="MPJPE")
    axis.plot(table["frame"], table["joint_error_aligned_mm"], color="#ff7f0e", linewidth=1.0, label="root-aligned")
    title = f"{label or run_dir.name}: MPJPE {metrics['mpjpe_mm']:.0f} mm"
    title += f", root-aligned {metrics['mpjpe_root_aligned_mm']:.0f} mm"
    if "floor_per_frame_mm" in metrics:
        axis.plot(
            table["frame"], metrics["floor_per_frame_mm"], "k--", linewidth=1.0, label="floor (3-D nearest sample)"
        )
        axis.set_xlabel("frame (shaded: the tracker's cost prefers the estimate to the floor's sample)")
        title += (
            f", floor {metrics['mpjpe_floor_mm']:.0f} mm; "
            f"{metrics['ambiguous_frames']} of {metrics['frames_done']} frames ambiguous"
        )
    else:
        axis.set_xlabel("frame")
    axis.set_ylabel("mm")
    axis.set_title(title, fontsize=9, loc="left")
    axis.legend(loc="upper right", fontsize=8, ncol=3)
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
