"""The plug-board's comparison tables (`experiments.combinations`): the held-out real clips tracked by tree filtering
from 1, 2 and 3 cameras, and paper 1's arm by AbIS and by tree filtering."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from eval.real_motion import runs_by_clip
from eval.runs import collect


def body_table(root: Path, rows: dict[str, str]) -> pd.DataFrame:
    """One row per clip and build (``rows``: folder -> what the row says) of the runs under ``root/<clip>/``."""
    table = []
    for clip, label, run in runs_by_clip(root, rows):
        table.append(
            {
                "clip": clip,
                "tracker and views": label,
                "frames": run.frames,
                "MPJPE mm": round(run.mpjpe_mm, 1),
                "root-aligned mm": round(run.mpjpe_root_aligned_mm, 1),
                "floor mm": _rounded(run, "mpjpe_floor_mm", 1),
                "aligned / floor": _rounded(run, "mpjpe_floor_mm", 2, run.mpjpe_root_aligned_mm),
                "joint angle °": round(run.joint_angle_error_deg, 1),
                "ambiguous frames": (
                    f"{int(run.ambiguous_frames)} of {run.frames}"
                    if pd.notna(getattr(run, "ambiguous_frames", np.nan))
                    else "—"
                ),
                "estimation ms (median)": round(getattr(run, "estimate_ms_median", np.nan), 1),
            }
        )
    return pd.DataFrame(table)


def arm_table(runs: dict[str, Path]) -> pd.DataFrame:
    """One row per tracker of paper 1's arm (``runs``: what the row says -> run folder): part 2's b1 and r2."""
    collected = collect(list(runs.values())).set_index("run")
    table = []
    for name, folder in runs.items():
        run = collected.loc[str(folder)]
        table.append(
            {
                "tracker": name,
                "frames": run["frames"],
                "b1 RMS": round(run["part2_b1_rms"], 4),
                "b1 RMS % of range": round(100 * run["part2_b1_rms"] / run["part2_b1_range"], 1),
                "r2 RMS °": round(run["part2_r2_rms_deg"], 2),
                "floor b1 RMS": _value(run, "floor_part2_b1_rms", 4),
                "floor r2 RMS °": _value(run, "floor_part2_r2_rms_deg", 2),
                "surface error mm": round(run["mean_surface_error_mm"], 1),
                "estimation ms (median)": round(run["estimate_ms_median"], 1),
            }
        )
    return pd.DataFrame(table)


def _rounded(run, column: str, digits: int, numerator: float | None = None) -> float | str:
    value = getattr(run, column, np.nan)
    if pd.isna(value):
        return "—"
    return round(value if numerator is None else numerator / value, digits)


def _value(row: pd.Series, column: str, digits: int) -> float | str:
    return round(row[column], digits) if column in row and pd.notna(row[column]) else "—"
