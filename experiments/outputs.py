"""A run's tables and summary: each frame -> rows of ``frames.parquet``, the rows -> ``metrics.json``, ``timings.json``.

Rows: one per frame and part, frame-major. Columns: ``frame``, ``part``, ``visible_px_<view>`` (label pixels),
``in_view_<view>`` (the view holds the whole object: `tracker.geometry.cameras.wholly_in_view`), the stage timings
``<stage>_ms`` (frame-level, repeated on each part's row), for runs that capture silhouettes ``silhouette_iou_<view>``
(extracted silhouette vs render mask); the model's evaluation columns (truth, and with an estimate the estimate and
its errors: `tracker.evaluation`); with a tracker's result its own columns (`tracker.protocol.StepResult`) and
``failure`` (empty when the frame was used). Angles are radians here; the summary reports their errors in degrees.

Metrics: the run's status, choices, seed, frames, views, tracker and resolved config; what the tracker built
(`Tracker.describe`); per part and view the smallest visible fraction; the silhouettes' quality; the model's
accuracy figures; the failed frames; the tracker's own figures from its own columns (`Tracker.summarize`); for a
tracker that searches a dictionary, what its samples allow (`tracker.evaluation.dictionary`). No timing, so that
the same seed gives the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from experiments.components import Components
from tracker.evaluation.dictionary import judge_dictionary
from tracker.observe.silhouettes import CapturedFrame
from tracker.protocol import RenderedFrame, StepResult

# Columns of every run's table that a tracker's own summary reads beside those its results named.
RUN_COLUMNS = ("frame", "part", "failure")


@dataclass
class RunLog:
    """What the frame loop gathers for the outputs: the table's rows, each frame's stage timings (ms), and the names
    of the columns the tracker's results added."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    timings: list[dict[str, float]] = field(default_factory=list)
    tracker_columns: set[str] = field(default_factory=set)

    def add(self, rows: list[dict[str, Any]], timings: dict[str, float], result: StepResult | None) -> None:
        self.rows.extend(rows)
        self.timings.append(timings)
        if result is not None:
            self.tracker_columns.update(result.part_columns, result.frame_columns)


def frame_rows(
    frame: RenderedFrame,
    components: Components,
    result: StepResult | None,
    captured: CapturedFrame | None = None,
    evaluated: tuple[dict, dict] = ({}, {}),
) -> list[dict[str, Any]]:
    """One row per part for ``frame``, the tracker's ``result`` for it (None: nothing estimated) and the model's
    evaluation of it (``evaluated``: per-part and per-frame columns)."""
    part_columns: dict[str, Any] = dict(evaluated[0])
    frame_columns: dict[str, Any] = {f"{stage}_ms": ms for stage, ms in frame.timings_ms.items()}
    frame_columns.update({f"in_view_{view}": seen for view, seen in frame.in_view.items()})
    if captured is not None:
        frame_columns.update({f"silhouette_iou_{view}": value for view, value in captured.iou.items()})
    frame_columns.update(evaluated[1])
    if result is not None:
        part_columns.update(result.part_columns)
        frame_columns.update(result.frame_columns, failure=result.failure or "")
    rows = []
    for k, part in enumerate(components.model.part_names):
        row: dict[str, Any] = {"frame": frame.frame, "part": part}
        row.update({name: values[k] for name, values in part_columns.items()})
        row.update({f"visible_px_{view}": int(pixels[k]) for view, pixels in frame.visible_px.items()})
        rows.append({**row, **frame_columns})
    return rows


def summarize(
    cfg: DictConfig,
    choices: dict[str, str],
    components: Components | None,
    table: pd.DataFrame,
    frames_done: int,
    status: str,
    tracker_columns: set[str] = frozenset(),
) -> dict[str, Any]:
    """The run's metrics.json content (see the module docstring); ``tracker_columns``: those the tracker's results
    added to ``table``."""
    metrics: dict[str, Any] = {
        "status": status,
        "choices": dict(sorted(choices.items())),
        "seed": int(cfg.seed),
        "frames": int(cfg.frames),
        "frames_done": frames_done,
        "views": components.views if components else [],
        "tracker": components.tracker.name if components else None,
        "config": OmegaConf.to_container(cfg, resolve=True),
    }
    if components is None:
        return metrics
    metrics.update(components.tracker.describe())
    if not table.empty:
        columns = {name: table[name].to_numpy() for name in table.columns}
        metrics["min_visible_fraction"] = min_visible_fraction(table, components.views)
        metrics.update(silhouette_quality(table))
        if components.evaluation is not None:
            metrics.update(components.evaluation.summarize(components.model, columns))
        if "failure" in table.columns:  # the tracker estimated
            metrics.update(failed_frames(table))
            own = {name: values for name, values in columns.items() if name in tracker_columns or name in RUN_COLUMNS}
            metrics.update(components.tracker.summarize(own))
            if components.tracker.dictionary is not None and components.evaluation is not None:
                metrics.update(
                    judge_dictionary(components.evaluation, components.model, components.tracker.dictionary, columns)
                )
    return metrics


def min_visible_fraction(table: pd.DataFrame, views: list[str]) -> dict[str, dict[str, float]]:
    """Per part and view: the fewest label pixels over the run relative to the most (0 = fully hidden at times)."""
    fractions: dict[str, dict[str, float]] = {}
    for part, rows in table.groupby("part", sort=False):
        fractions[part] = {}
        for view in views:
            pixels = rows[f"visible_px_{view}"]
            fractions[part][view] = round(float(pixels.min() / pixels.max()), 4) if pixels.max() > 0 else 0.0
    return fractions


def silhouette_quality(table: pd.DataFrame) -> dict[str, Any]:
    """Per view, the mean and the worst IoU of the extracted silhouettes against the render masks."""
    columns = [c for c in table.columns if c.startswith("silhouette_iou_")]
    frames = table.drop_duplicates("frame")
    return (
        {
            "silhouette_iou": {
                c.removeprefix("silhouette_iou_"): {"mean": float(frames[c].mean()), "min": float(frames[c].min())}
                for c in columns
            }
        }
        if columns
        else {}
    )


def failed_frames(table: pd.DataFrame) -> dict[str, Any]:
    """How many frames the tracker could not use, and the first of them with its reason."""
    failed = table.loc[table["failure"] != "", ["frame", "failure"]].drop_duplicates("frame")
    figures: dict[str, Any] = {"failed_frames": len(failed)}
    if len(failed):
        figures["first_failure"] = f"frame {int(failed.iloc[0]['frame'])}: {failed.iloc[0]['failure']}"
    return figures


def timing_summary(timings: list[dict[str, float]], views: list[str]) -> dict[str, float]:
    """timings.json: the median ms of every stage over the frames (frame 0 lacks some stages), and per view."""
    if not timings:
        return {}
    stages = timings[-1].keys()
    summary = {f"{stage}_ms_median": float(np.median([t[stage] for t in timings if stage in t])) for stage in stages}
    if views and "render_ms_median" in summary:
        summary["render_ms_per_view_median"] = summary["render_ms_median"] / len(views)
    return summary
