"""A run's tables and summary: frame results -> ``frames.parquet`` rows, and the rows -> ``metrics.json`` figures.

Rows: one per frame and part. Columns: for the DSQ arm ``truth_<param>``, for the body ``truth_pose`` (the pose
vector, a list; the same on each part's row); ``visible_px_<view>``; frame-level stage timings ``<stage>_ms``
(repeated on each part's row); for body scenes ``silhouette_iou_<view>`` (extracted silhouette vs render mask).
With an estimating tracker also ``est_<param>``, ``surface_error_mm`` (mean distance between the part's
estimated and true model samples, matched by their surface coordinates) and, for AbIS, the pair counts
``<count>`` (all views) and ``<count>_<view>``, ``pairs``, ``cost`` (eq 8 at the end of the fit), ``iterations``
and ``failure``. Angles are radians here; the summary reports their errors in degrees.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from tracker.abis.correspondences import COUNT_NAMES
from tracker.abis.tracker import AbisResult
from tracker.models.body_mesh import BodyMesh
from tracker.models.dsq import ANGLE_NAMES, PARAM_NAMES
from tracker.observe.silhouettes import CapturedFrame
from tracker.sequence import FrameInput
from tracker.tbf.evaluation import joint_error_mm, right_arm_swing_deg, score_swings
from tracker.tbf.tracker import TbfResult

PAPER_PART = 1  # paper 1's "part 2" (1-based), our index 1: the forearm


def frame_rows(frame: FrameInput, model: Any, result: object | None,
               captured: CapturedFrame | None = None) -> list[dict[str, Any]]:  # fmt: skip
    """One row per part for ``frame`` (and the tracker's ``result`` for it, if any)."""
    frame_columns = {f"{stage}_ms": ms for stage, ms in frame.timings_ms.items()}
    if captured is not None:
        frame_columns.update({f"silhouette_iou_{view}": value for view, value in captured.iou.items()})
    if isinstance(model, BodyMesh):
        return _body_rows(frame, model, result, frame_columns)
    estimate = getattr(result, "estimate", None)
    if estimate is not None:
        true_points, estimated_points = model.sample_points(frame.truth), model.sample_points(estimate)
    rows = []
    for k, part in enumerate(model.part_names):
        row: dict[str, Any] = {"frame": frame.frame, "part": part}
        row.update({f"truth_{name}": float(frame.truth[k, i]) for i, name in enumerate(PARAM_NAMES)})
        row.update({f"visible_px_{view}": int(pixels[k]) for view, pixels in frame.visible_px.items()})
        if estimate is not None:
            row.update({f"est_{name}": float(estimate[k, i]) for i, name in enumerate(PARAM_NAMES)})
            distance = np.linalg.norm(estimated_points[k] - true_points[k], axis=1)
            row["surface_error_mm"] = 1e3 * float(distance.mean())
        if isinstance(result, AbisResult):
            row.update(_abis_columns(result, k))
        row.update(frame_columns)
        rows.append(row)
    return rows


def _body_rows(frame: FrameInput, body: BodyMesh, result: object | None,
               frame_columns: dict[str, Any]) -> list[dict[str, Any]]:  # fmt: skip
    """The body's rows: the pose (a list) and, with a TBF estimate, its pose, joint error, right-arm angles, the
    tree search's counts per level, the posterior entropy and the estimate's occlusion flags (eq 3)."""
    columns = {"truth_pose": frame.truth.tolist(), "swing_truth_deg": right_arm_swing_deg(body, frame.truth),
               **frame_columns}  # fmt: skip
    occluded = None
    if isinstance(result, TbfResult):
        columns.update(est_pose=result.estimate.tolist(), swing_est_deg=right_arm_swing_deg(body, result.estimate),
                       joint_error_mm=joint_error_mm(body, frame.truth, result.estimate),
                       joint_error_aligned_mm=joint_error_mm(body, frame.truth, result.estimate, root_aligned=True),
                       failure=result.failure or "")  # fmt: skip
        if result.filter is not None:
            found = result.filter
            columns.update(est_sample=found.sample, entropy=found.entropy, prior_terms=found.prior_terms)
            for level, (evaluated, kept) in enumerate(zip(found.nodes_evaluated, found.nodes_kept, strict=True)):
                columns[f"nodes_level{level + 1}"], columns[f"kept_level{level + 1}"] = evaluated, kept
            occluded = found.occluded
    rows = []
    for k, part in enumerate(body.part_names):
        row = {"frame": frame.frame, "part": part}
        row.update({f"visible_px_{view}": int(pixels[k]) for view, pixels in frame.visible_px.items()})
        if occluded is not None:
            row["occluded_est"] = bool(occluded[k])
        rows.append({**row, **columns})
    return rows


def _abis_columns(result: AbisResult, part: int) -> dict[str, Any]:
    columns: dict[str, Any] = {}
    for index, name in enumerate(COUNT_NAMES):
        per_view = {view: int(counts[part, index]) for view, counts in result.counts.items()}
        columns[name] = sum(per_view.values())
        columns.update({f"{name}_{view}": value for view, value in per_view.items()})
    columns["pairs"] = int(sum(pairs[part] for pairs in result.pairs.values()))
    columns["cost"] = float(result.cost[part])
    columns["iterations"] = int(result.iterations[part])
    columns["failure"] = result.failure or ""
    return columns


def silhouette_quality(table: pd.DataFrame) -> dict[str, Any]:
    """Per view, the mean and the worst IoU of the extracted silhouettes against the render masks."""
    columns = [c for c in table.columns if c.startswith("silhouette_iou_")]
    frames = table.drop_duplicates("frame")
    return {"silhouette_iou": {c.removeprefix("silhouette_iou_"): {"mean": float(frames[c].mean()),
                                                                  "min": float(frames[c].min())} for c in columns}
            } if columns else {}  # fmt: skip


def body_tracking(table: pd.DataFrame) -> dict[str, Any]:
    """A TBF run's figures: MPJPE (mm), the Fig 4(c) swing outcomes, and the tree search's mean effort."""
    if "joint_error_mm" not in table.columns or table.empty:
        return {}
    frames = table.drop_duplicates("frame").sort_values("frame")
    figures: dict[str, Any] = {
        "mpjpe_mm": float(frames["joint_error_mm"].mean()),
        "mpjpe_root_aligned_mm": float(frames["joint_error_aligned_mm"].mean()),
        "swings": score_swings(frames["swing_truth_deg"].to_numpy(), frames["swing_est_deg"].to_numpy()),
        "swing_error_deg_mean": float((frames["swing_est_deg"] - frames["swing_truth_deg"]).abs().mean()),
        "failed_frames": int((frames["failure"] != "").sum()),
    }
    levels = sorted(c for c in frames.columns if c.startswith("nodes_level"))
    figures["nodes_evaluated_mean"] = [float(frames[c].mean()) for c in levels]
    figures["pruned_fraction_mean"] = [float(1 - frames[c.replace("nodes", "kept")].sum() / frames[c].sum())
                                       for c in levels]  # fmt: skip
    return figures


def accuracy(table: pd.DataFrame) -> dict[str, Any]:
    """RMS error of every parameter of every part (angles in degrees), paper 1's part-2 figures, surface error."""
    if "est_a" not in table.columns or table.empty:
        return {}
    rms: dict[str, dict[str, float]] = {}
    for part, rows in table.groupby("part", sort=False):
        rms[part] = {}
        for name in PARAM_NAMES:
            error = rows[f"est_{name}"].to_numpy() - rows[f"truth_{name}"].to_numpy()
            if name in ANGLE_NAMES:
                error = np.degrees(np.angle(np.exp(1j * error)))  # wrapped to (-180, 180]
            rms[part][f"{name}_deg" if name in ANGLE_NAMES else name] = float(np.sqrt(np.mean(error**2)))
    parts = list(rms)
    paper_part = table[table["part"] == parts[PAPER_PART]] if len(parts) > PAPER_PART else table.iloc[:0]
    figures: dict[str, Any] = {
        "rms": rms,
        "mean_surface_error_mm": float(table["surface_error_mm"].mean()),
    }
    if not paper_part.empty:
        figures["part2_b1_rms"] = rms[parts[PAPER_PART]]["b1"]
        figures["part2_b1_range"] = float(np.ptp(paper_part["truth_b1"].to_numpy()))
        figures["part2_r2_rms_deg"] = rms[parts[PAPER_PART]]["r2_deg"]
    if "failure" in table.columns:
        failed = table.loc[table["failure"] != "", ["frame", "failure"]].drop_duplicates("frame")
        figures["failed_frames"] = len(failed)
        if len(failed):
            figures["first_failure"] = f"frame {int(failed.iloc[0]['frame'])}: {failed.iloc[0]['failure']}"
    return figures
