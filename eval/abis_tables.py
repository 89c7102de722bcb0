"""Paper 1's seeds table: how often AbIS reaches Fig 8's accuracy over seeds, per scene, optimiser and selection.

A run reaches Fig 8's targets when part 2's b1 RMS is within `B1_TARGET_PERCENT` of b1's range over the run and its
r2 RMS within `R2_TARGET_DEG` (the accuracy the paper's Fig 8 shows by eye). ``python -m eval.abis_tables <dirs>``
prints the table of every AbIS run under the folders.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd

from eval.runs import markdown
from tracker.presentation import PAPER_PART

B1_TARGET_PERCENT = 10.0
R2_TARGET_DEG = 3.0
SELECTION_ORDER = {"zbuffer": 0, "none": 1}  # the paper's first, then its ablation


def abis_runs(directories: list[Path]) -> pd.DataFrame:
    """One row per finished AbIS run under ``directories``: scene, optimiser, selection, seed, part 2's b1 RMS (%
    of its range) and r2 RMS, failed frames, the mean point-to-surface distance, and part 2's pairs that left for
    occlusion, lost or as false matches (all views, all frames)."""
    rows = []
    for directory in directories:
        for path in sorted(Path(directory).rglob("metrics.json")):
            metrics = json.loads(path.read_text())
            if metrics.get("choices", {}).get("tracker") != "abis" or "part2_b1_rms" not in metrics:
                continue
            tracker = metrics["config"]["tracker"]
            table = pd.read_parquet(path.parent / "frames.parquet")
            part = table[table["part"] == table["part"].drop_duplicates().iloc[PAPER_PART]]
            rows.append(
                {
                    "scene": metrics["choices"]["scene"],
                    "optimiser": tracker["fit"]["optimizer"],
                    "selection": tracker["selection"],
                    "seed": metrics["seed"],
                    "b1_percent": 100 * metrics["part2_b1_rms"] / metrics["part2_b1_range"],
                    "r2_deg": metrics["part2_r2_rms_deg"],
                    "failed_frames": metrics["failed_frames"],
                    "surface_distance_mm": metrics["mean_surface_distance_mm"],
                    **{count: int(part[count].sum()) for count in ("discarded_occlusion", "lost", "discarded_error")},
                }
            )
    return pd.DataFrame(rows)


def seeds_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Per scene (in the order the runs first name them), optimiser and selection: the seeds that reach Fig 8's
    targets (of those run), b1 and r2 RMS (median and worst), failed frames, the median point-to-surface distance
    and part 2's pairs leaving per run."""
    rows = []
    order = {"scene": {scene: k for k, scene in enumerate(runs["scene"].unique())}, "selection": SELECTION_ORDER}
    runs = runs.sort_values(
        ["scene", "optimiser", "selection"],
        key=lambda column: column.map(order[column.name]) if column.name in order else column,
        kind="stable",
    )
    for (scene, optimiser, selection), group in runs.groupby(["scene", "optimiser", "selection"], sort=False):
        reached = (group["b1_percent"] <= B1_TARGET_PERCENT) & (group["r2_deg"] <= R2_TARGET_DEG)
        rows.append(
            {
                "scene": scene,
                "optimiser": optimiser,
                "selection": selection,
                "seeds at Fig 8's targets": f"{int(reached.sum())}/{len(group)}",
                "b1 RMS % of range (median, worst)": _median_worst(group["b1_percent"], 1),
                "r2 RMS deg (median, worst)": _median_worst(group["r2_deg"], 2),
                "failed frames": int(group["failed_frames"].sum()),
                "point-to-surface mm (median)": round(float(group["surface_distance_mm"].median()), 1),
                "part 2 pairs per run: occlusion / lost / false": " / ".join(
                    f"{group[count].mean():.0f}" for count in ("discarded_occlusion", "lost", "discarded_error")
                ),
            }
        )
    return pd.DataFrame(rows)


def _median_worst(values: pd.Series, digits: int) -> str:
    return f"{values.median():.{digits}f} ({values.max():.{digits}f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("directories", nargs="+", type=Path)
    runs = abis_runs(parser.parse_args().directories)
    if runs.empty:
        raise SystemExit("no finished AbIS runs there")
    print(markdown(seeds_table(runs)))


if __name__ == "__main__":
    main()
