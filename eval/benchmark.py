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

Where a setup loses to the floor (`losses`): its excess, the root-aligned error less the floor, split by the scored
frames it comes from: those where the estimate faces away from the subject (``turned``: the root's orientation off
by `TURNED_DEG` or more: one silhouette looks much the same from the front and from the back), those where the pose is
lost (``lost``: beyond `LOST` times the frame's floor, not turned), and the rest (``near``). The three add up to the
excess; each is its frames' excess summed over all the scored frames, so a column says how many millimetres of the
mean those frames cost. Of the turned and lost frames, those where the tracker's own cost preferred its sample to
the floor's are ambiguous (the cost's loss: no search of the samples would have found the floor's there); the rest
are the search's.
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
TURNED_DEG = 90.0  # a root orientation error this large: the estimate faces away from the subject
LOST = 2.0  # a root-aligned error beyond this many times the frame's floor: the pose is lost, not merely off
LOSS_MM = ["excess mm", "turned mm", "lost mm", "near mm"]  # what `losses` adds to a clip's row (and frame counts)
LOSS_FRAMES = ["turned frames", "lost frames", "ambiguous frames"]  # ambiguous: of the turned or lost
CSV_COLUMNS = [*COLUMNS, *LOSS_MM, *LOSS_FRAMES]  # a clip's row in the csv; the markdown shows `COLUMNS`
LOSS_LEGEND = (
    f"the root-aligned error less the floor, mm, from the frames turned (root orientation off by {TURNED_DEG:g}° "
    f"or more), lost (beyond {LOST:g}x the floor) and near it (the rest), each summed over all the scored frames; "
    "mean over clips; the share of the scored frames turned or lost, and of those the share where the tracker's own "
    "cost preferred its sample to the floor's (ambiguous: no search of these samples would have done better; "
    "the hybrid's, its filter's sample)"
)


def frame_table(run: Path) -> pd.DataFrame:
    """A run's frames, one row each (its first part's), with ``seen``: every view saw the whole subject (True for
    runs written before the runs said so), and where the run judged a dictionary ``floor_mm`` and ``ambiguous``
    (its own cost preferred its sample to the floor's: `tracker.evaluation.dictionary`)."""
    table = pd.read_parquet(run / "frames.parquet")
    if "frame" not in table:  # a run that failed before its first frame
        return pd.DataFrame({"seen": pd.Series(dtype=bool)}, index=pd.Index([], name="frame"))
    frames = table.drop_duplicates("frame").set_index("frame")
    views = [column for column in frames.columns if column.startswith("in_view_")]
    frames["seen"] = frames[views].all(axis=1) if views else True
    metrics = json.loads((run / "metrics.json").read_text())
    if (floor := metrics.get("floor_per_frame_mm")) is not None:
        frames["floor_mm"] = np.asarray(floor, dtype=np.float64)[: len(frames)]
    if (ambiguous := metrics.get("ambiguous_per_frame")) is not None:
        frames["ambiguous"] = np.asarray(ambiguous, dtype=bool)[: len(frames)]
    return frames


def benchmark_table(root: Path, labels: dict[str, str]) -> pd.DataFrame:
    """One row per clip (``root/<clip>/``) and setup (``labels``: folder -> what the row says), clip by clip in the
    setups' order, each measure the mean over the clip's scored frames."""
    runs = collect([root])
    if runs.empty:
        return pd.DataFrame(columns=CSV_COLUMNS)
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
    return pd.DataFrame(rows, columns=CSV_COLUMNS)


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
    return row | losses(kept)


def losses(kept: pd.DataFrame) -> dict:
    """The scored frames' excess over the floor (mm, per scored frame) split into turned, lost and near frames (see
    the module), how many frames were turned or lost, and of those how many ambiguous (NaN: the run judged no
    dictionary); NaN and 0 where the run has no such measures."""
    needed = {"joint_error_aligned_mm", "floor_mm", "root_orientation_error_deg"}
    if not len(kept) or not needed <= set(kept.columns):
        return dict.fromkeys(LOSS_MM, np.nan) | {"turned frames": 0, "lost frames": 0, "ambiguous frames": np.nan}
    aligned, floor = kept["joint_error_aligned_mm"], kept["floor_mm"]
    excess = aligned - floor
    turned = kept["root_orientation_error_deg"] >= TURNED_DEG
    lost = ~turned & (aligned > LOST * floor)
    near = ~turned & ~lost
    split = {"excess mm": excess.mean()} | {
        name: excess[frames].sum() / len(kept) for name, frames in zip(LOSS_MM[1:], (turned, lost, near), strict=True)
    }
    ambiguous = kept["ambiguous"].astype(bool) & (turned | lost) if "ambiguous" in kept else None
    return {name: round(float(mm), 1) for name, mm in split.items()} | {
        "turned frames": int(turned.sum()),
        "lost frames": int(lost.sum()),
        "ambiguous frames": np.nan if ambiguous is None else int(ambiguous.sum()),
    }


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


def loss_table(per_clip: pd.DataFrame, labels: dict[str, str]) -> pd.DataFrame:
    """Per setup: where its excess over the floor comes from (`losses`), each mm column's mean over the clips it
    finished, and the share of its scored frames that were turned or lost."""
    rows = []
    for label in labels.values():
        done = per_clip[(per_clip["tracker"] == label) & (per_clip["status"] == "ok")]
        if done.empty or done["excess mm"].isna().all():
            continue
        row = {"tracker": label, **{column: round(float(done[column].mean()), 1) for column in LOSS_MM}}
        scored = max(int(done["scored"].sum()), 1)
        row |= {f"{column} %": round(100 * float(done[column].sum()) / scored, 1) for column in LOSS_FRAMES[:2]}
        astray = int(done["turned frames"].sum() + done["lost frames"].sum())
        ambiguous = done["ambiguous frames"].astype(float)
        known = astray and not ambiguous.isna().any()
        row["of them ambiguous %"] = round(100 * float(ambiguous.sum()) / astray, 1) if known else np.nan
        rows.append(row)
    return pd.DataFrame(rows)
