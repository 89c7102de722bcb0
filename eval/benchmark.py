"""The real-motion benchmark's tables (`experiments.benchmark`): one row per test clip and tracker setup, and per
setup the mean ± std over clips.

A clip is scored on the frames where every camera of every setup's rig saw the whole subject (``in_view_<view>``
of each run's ``frames.parquet``: `tracker.geometry.cameras.wholly_in_view`), the same frames for every setup: a
dancer who crosses the stage leaves a camera's view, and the error of a pose no camera could see measures nothing. Each
setup still tracks the clip whole (a frame it could not use, ``failed``, keeps the last estimate), so its scored
frames after the subject comes back show whether it found him again.

The floor of a clip is the dictionary's: the root-aligned MPJPE of the sample nearest the truth at every frame
(`tracker.evaluation.dictionary`), read from a run of that clip that searched the dictionary; every setup of the
clip is held against it on the same frames, a setup that searches none (AbIS) included, since every dictionary is
built from the same clips for the same subject. ``aligned / floor`` below 1 is what no dictionary search can reach.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from eval.runs import collect

# Column -> the per-frame column of frames.parquet it averages (mm or degrees), each rounded to one decimal.
MEASURES = {
    "MPJPE mm": "joint_error_mm",
    "root-aligned mm": "joint_error_aligned_mm",
    "PA-MPJPE mm": "joint_error_pa_mm",
    "floor mm": "floor_mm",
    "joint angle °": "joint_angle_error_deg",
    "root orientation °": "root_orientation_error_deg",
}
# Column -> how it sums up the estimation time (frames.parquet's estimate_ms) over the scored frames: a typical
# frame, and the mean, which counts the frames a tracker spent longer on (the hybrid's searched again,
# tracker.rescue_ratio). A frame the tracker could not use took no estimation time.
TIMINGS = {"estimation ms/frame": "median", "mean ms/frame": "mean"}
COLUMNS = ["clip", "tracker", "status", "frames", "scored", "failed", *MEASURES, *TIMINGS, "aligned / floor"]


def frame_table(run: Path) -> pd.DataFrame:
    """A run's frames, one row each (its first part's), with ``seen``: every view saw the whole subject (True for
    runs written before the runs said so), and ``floor_mm`` where the run judged a dictionary."""
    table = pd.read_parquet(run / "frames.parquet")
    if "frame" not in table:  # a run that failed before its first frame
        return pd.DataFrame({"seen": pd.Series(dtype=bool)}, index=pd.Index([], name="frame"))
    frames = table.drop_duplicates("frame").set_index("frame")
    views = [column for column in frames.columns if column.startswith("in_view_")]
    frames["seen"] = frames[views].all(axis=1) if views else True
    floor = json.loads((run / "metrics.json").read_text()).get("floor_per_frame_mm")
    if floor is not None:
        frames["floor_mm"] = np.asarray(floor, dtype=np.float64)[: len(frames)]
    return frames


def benchmark_table(root: Path, labels: dict[str, str]) -> pd.DataFrame:
    """One row per clip (``root/<clip>/``) and setup (``labels``: folder -> what the row says), clip by clip in the
    setups' order, each measure the mean over the clip's scored frames."""
    runs = collect([root])
    if runs.empty:
        return pd.DataFrame(columns=COLUMNS)
    runs["clip"] = [Path(run).parent.name for run in runs["run"]]
    runs["folder"] = [Path(run).name for run in runs["run"]]
    runs = runs[runs["folder"].isin(list(labels))]
    rows = []
    for clip in sorted(runs["clip"].unique()):
        of_clip = runs[runs["clip"] == clip]
        frames = {run: frame_table(Path(run)) for run in of_clip["run"]}
        scored = scored_frames([frames[run] for run in of_clip[of_clip["status"] == "ok"]["run"]])
        floors = [table["floor_mm"] for table in frames.values() if "floor_mm" in table]
        floor = floors[0] if floors else pd.Series(np.nan, index=scored)
        for folder, label in labels.items():
            for run in of_clip[of_clip["folder"] == folder].to_dict("records"):
                table = frames[run["run"]]
                rows.append(clip_row(clip, label, run, table.assign(floor_mm=floor.reindex(table.index)), scored))
    return pd.DataFrame(rows, columns=COLUMNS)


def scored_frames(tables: list[pd.DataFrame]) -> pd.Index:
    """The frames every table has and saw the whole subject in."""
    if not tables:
        return pd.Index([])
    seen = tables[0].index[tables[0]["seen"]]
    for table in tables[1:]:
        seen = seen.intersection(table.index[table["seen"]])
    return seen


def clip_row(clip: str, label: str, run: dict, frames: pd.DataFrame, scored: pd.Index) -> dict:
    """One setup on one clip: each measure's mean over the ``scored`` frames the run has."""
    kept = frames.loc[frames.index.intersection(scored)]
    failed = int((frames["failure"] != "").sum()) if "failure" in frames else 0
    row = {"clip": clip, "tracker": label, "status": run["status"], "frames": len(frames)}
    row |= {"scored": len(kept), "failed": failed}  # failed: frames with no estimate (the last one counts)
    for column, name in MEASURES.items():
        row[column] = round(float(kept[name].mean()), 1) if name in kept and len(kept) else np.nan
    times = kept["estimate_ms"] if "estimate_ms" in kept and len(kept) else None
    for column, statistic in TIMINGS.items():
        row[column] = round(float(times.agg(statistic)), 1) if times is not None else np.nan
    aligned = kept["joint_error_aligned_mm"].mean() if "joint_error_aligned_mm" in kept else np.nan
    row["aligned / floor"] = round(float(aligned / kept["floor_mm"].mean()), 2) if len(kept) else np.nan
    return row


def summary_table(per_clip: pd.DataFrame, labels: dict[str, str]) -> pd.DataFrame:
    """Per setup, in ``labels``' order: the clips it finished, and each measure's mean ± std over those clips."""
    rows = []
    for label in labels.values():
        runs = per_clip[per_clip["tracker"] == label]
        if runs.empty:
            continue
        done = runs[runs["status"] == "ok"]
        row = {"tracker": label, "clips": f"{len(done)} of {len(runs)}"}
        row["scored frames"] = f"{int(done['scored'].sum())} of {int(done['frames'].sum())}"
        row["failed frames"] = f"{int(done['failed'].sum())} of {int(done['frames'].sum())}"
        for column in (*MEASURES, *TIMINGS, "aligned / floor"):
            values = done[column].astype(float).dropna()
            digits = 2 if column == "aligned / floor" else 1
            row[column] = f"{values.mean():.{digits}f} ± {values.std(ddof=0):.{digits}f}" if len(values) else ""
        rows.append(row)
    return pd.DataFrame(rows)
