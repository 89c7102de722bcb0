"""Paper 2 on real motion the samples never held: each held-out clip's errors against the dictionary's floor, the
ablation of each part of the build, and the pictures (Fig 5's strip, the error against the floor per frame).

Runs are laid out ``<root>/<clip>/<variant>/`` (`experiments.real_motion`); every number comes from the run's
``metrics.json`` and ``timings.json``, as `eval.tables.collect` reads them.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from eval.body_figures import error_caption, posture_strip
from eval.figures import pyplot, save_png
from eval.tables import collect


def runs_by_clip(root: Path, folders: dict[str, str]) -> Iterator[tuple[str, str, Any]]:
    """Each run in ``root/<clip>/<folder>/`` (``folders``: folder -> what its row says), clip by clip and in the
    folders' order: the clip, the row's label and the run (a row of `eval.tables.collect`)."""
    runs = collect([root])
    runs["clip"] = [Path(run).parent.name for run in runs["run"]]
    runs["folder"] = [Path(run).name for run in runs["run"]]
    for clip in sorted(runs["clip"].unique()):
        for folder, label in folders.items():
            for run in runs[(runs["clip"] == clip) & (runs["folder"] == folder)].itertuples():
                yield clip, label, run


def real_motion_table(root: Path, variants: dict[str, str]) -> pd.DataFrame:
    """One row per clip and variant (``variants``: folder -> what the row says), in the variants' order."""
    rows = []
    for clip, label, run in runs_by_clip(root, variants):
        rows.append(
            {
                "clip": clip,
                "build": label,
                "frames": run.frames,
                "samples": run.samples,
                "MPJPE mm": round(run.mpjpe_mm, 1),
                "root-aligned mm": round(run.mpjpe_root_aligned_mm, 1),
                "floor mm": round(run.mpjpe_floor_mm, 1),
                "aligned / floor": round(run.mpjpe_root_aligned_mm / run.mpjpe_floor_mm, 2),
                "joint angle °": round(run.joint_angle_error_deg, 1),
                "floor joint angle °": round(run.joint_angle_floor_deg, 1),
                "ambiguous frames": f"{run.ambiguous_frames} of {run.frames}",
                "estimation ms (median)": round(getattr(run, "estimate_ms_median", np.nan), 1),
            }
        )
    return pd.DataFrame(rows)


def error_against_floor(run_dir: Path, out: Path) -> Path:
    """Per frame: the joint error (absolute and root-aligned) against the dictionary's floor, with the frames
    where the silhouette cost itself prefers the estimate to the floor's sample shaded (ambiguous)."""
    plt = pyplot()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    table = pd.read_parquet(run_dir / "frames.parquet").drop_duplicates("frame")
    figure, axis = plt.subplots(figsize=(10, 2.8))
    for frame, ambiguous in zip(table["frame"], metrics["ambiguous_per_frame"], strict=True):
        if ambiguous:
            axis.axvspan(frame - 0.5, frame + 0.5, color="#d62728", alpha=0.12, linewidth=0)
    axis.plot(table["frame"], table["joint_error_mm"], color="#1f77b4", linewidth=1.0, label="MPJPE")
    axis.plot(table["frame"], table["joint_error_aligned_mm"], color="#ff7f0e", linewidth=1.0, label="root-aligned")
    axis.plot(
        table["frame"],
        metrics["floor_per_frame_mm"],
        color="black",
        linewidth=1.0,
        linestyle="--",
        label="floor (3-D nearest sample)",
    )
    axis.set_xlabel("frame (shaded: the silhouette cost prefers the estimate to the floor's sample)")
    axis.set_ylabel("mm")
    axis.set_title(
        f"{run_dir.parent.name}: MPJPE {metrics['mpjpe_mm']:.0f} mm, root-aligned "
        f"{metrics['mpjpe_root_aligned_mm']:.0f} mm, floor {metrics['mpjpe_floor_mm']:.0f} mm; "
        f"{metrics['ambiguous_frames']} of {metrics['frames_done']} frames ambiguous",
        fontsize=9,
        loc="left",
    )
    axis.legend(loc="upper right", fontsize=8, ncol=3)
    return save_png(plt, figure, out)


def fig5_strip(run_dir: Path, out: Path, count: int = 7) -> Path:
    """Paper 2's Fig 5 for one clip: ``count`` frames spread over the run with the estimate drawn over the input."""
    frames = pd.read_parquet(run_dir / "frames.parquet", columns=["frame"])["frame"].unique()
    picked = np.unique(np.linspace(0, len(frames) - 1, count).round().astype(int))
    return posture_strip(run_dir, [int(frames[k]) for k in picked], out, caption=error_caption)
