"""The real-motion benchmark's tables (`experiments.benchmark`): one row per test clip and tracker setup, from each
run's ``metrics.json`` and ``timings.json`` (`eval.runs.collect`), and per setup the mean ± std over clips. A
frame the tracker could not use (``failed``: the subject out of a camera's view, say) keeps the last estimate, and
its error counts.

The floor of a clip is the dictionary's: the root-aligned MPJPE of the sample nearest the truth at every frame
(`tracker.evaluation.dictionary`), read from a run of that clip that searched the dictionary; every setup of the
clip is held against it, a setup that searches none (AbIS) included, since every dictionary is built from the same
clips for the same subject. ``aligned / floor`` below 1 is what no dictionary search can reach.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from eval.runs import collect

# Column -> the metric it shows (mm, degrees or ms), each rounded to one decimal.
MEASURES = {
    "MPJPE mm": "mpjpe_mm",
    "root-aligned mm": "mpjpe_root_aligned_mm",
    "PA-MPJPE mm": "pa_mpjpe_mm",
    "floor mm": "mpjpe_floor_mm",
    "joint angle °": "joint_angle_error_deg",
    "root orientation °": "root_orientation_error_deg",
    "estimation ms/frame": "estimate_ms_median",
}


def benchmark_table(root: Path, labels: dict[str, str]) -> pd.DataFrame:
    """One row per clip (``root/<clip>/``) and setup (``labels``: folder -> what the row says), clip by clip in the
    setups' order."""
    runs = collect([root])
    if runs.empty:
        return pd.DataFrame(columns=["clip", "tracker", "status", "frames", "failed", *MEASURES, "aligned / floor"])
    runs["clip"] = [Path(run).parent.name for run in runs["run"]]
    runs["folder"] = [Path(run).name for run in runs["run"]]
    floors = runs.dropna(subset=["mpjpe_floor_mm"]).groupby("clip")["mpjpe_floor_mm"].first()
    rows = []
    for clip in sorted(runs["clip"].unique()):
        for folder, label in labels.items():
            for run in runs[(runs["clip"] == clip) & (runs["folder"] == folder)].to_dict("records"):
                floor = floors.get(clip, np.nan)  # the clip's, whether or not this row searched a dictionary
                failed = run.get("failed_frames", 0)
                failed = 0 if pd.isna(failed) else int(failed)  # frames with no estimate: the last one counts
                row = {
                    "clip": clip,
                    "tracker": label,
                    "status": run["status"],
                    "frames": run["frames"],
                    "failed": failed,
                }
                row |= {column: round(float(run.get(metric, np.nan)), 1) for column, metric in MEASURES.items()}
                row["floor mm"] = round(float(floor), 1)
                row["aligned / floor"] = round(run.get("mpjpe_root_aligned_mm", np.nan) / floor, 2)
                rows.append(row)
    return pd.DataFrame(rows)


def summary_table(per_clip: pd.DataFrame, labels: dict[str, str]) -> pd.DataFrame:
    """Per setup, in ``labels``' order: the clips it finished, and each measure's mean ± std over those clips."""
    rows = []
    for label in labels.values():
        runs = per_clip[per_clip["tracker"] == label]
        if runs.empty:
            continue
        done = runs[runs["status"] == "ok"]
        row = {"tracker": label, "clips": f"{len(done)} of {len(runs)}"}
        row["failed frames"] = f"{int(done['failed'].sum())} of {int(done['frames'].sum())}"
        for column in (*MEASURES, "aligned / floor"):
            values = done[column].astype(float).dropna()
            digits = 2 if column == "aligned / floor" else 1
            row[column] = f"{values.mean():.{digits}f} ± {values.std(ddof=0):.{digits}f}" if len(values) else ""
        rows.append(row)
    return pd.DataFrame(rows)
