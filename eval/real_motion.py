"""Paper 2 on real motion the samples never held: each held-out clip's errors against the dictionary's floor, the
ablation of each part of the build, and the pictures (Fig 5's strip, the error against the floor per frame).

Runs are laid out ``<root>/<clip>/<variant>/`` (`experiments.real_motion`); every number comes from the run's
``metrics.json`` and ``timings.json``, as `eval.tables.collect` reads them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from eval.runs import collect


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
