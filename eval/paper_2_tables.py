"""Paper 2's tables from its runs: Fig 4(c) (Fail / Error / Success per cost and motion model, beside the paper's
counts, with MPJPE), its counts at other bounds of the rule, and Fig 6(d) (capture, estimation and total ms per
frame, beside the paper's PC and Cell). A run belongs to Fig 4(c) when it scored swings, and to Fig 6(d) when it
timed a capture and an estimation stage: whatever its tracker. ``runs``: the table of `eval.runs.collect`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.evaluation.body import OUTCOMES, count_outcomes
from tracker.registry import REGISTRIES

# Fig 4(c) of paper 2: swings out of 24 (fail, error, success).
PAPER_4C = {
    ("wxor", "dm1"): (24, 0, 0),
    ("wxor", "dm2"): (24, 0, 0),
    ("nwxor", "dm1"): (7, 7, 10),
    ("nwxor", "dm2"): (0, 10, 14),
}

# Fig 6(d): ms per frame (min, max, average).
PAPER_6D = {
    "PC (2x Opteron 280, 4 cores)": {"capture": (21, 29, 22), "estimation": (21, 236, 104), "total": (43, 261, 127)},
    "Cell (3.2 GHz, 7 SPE)": {"capture": (20, 53, 23), "estimation": (17, 169, 62), "total": (39, 202, 86)},
}


def _finished(runs: pd.DataFrame, *columns: str) -> pd.DataFrame:
    """The finished runs that have a value in every one of ``columns``."""
    if "status" not in runs or not set(columns) <= set(runs.columns):
        return runs.iloc[:0]
    return runs[(runs["status"] == "ok") & runs[list(columns)].notna().all(axis=1)]


def table_4c(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per experiment and cell (cost, motion) of the finished runs that scored swings (experiment A), cells
    in the order the costs and motion models are registered: the number of runs (the subject's seeds), each
    outcome's count (``mean ± std`` over the runs, the count itself for one run), the Success count of the dictionary's
    floor (the sample nearest the truth in 3-D taken as the estimate, where the tracker reports it), MPJPE, MPJPE
    root-aligned and its floor (root-aligned too; means), the distribution of
    the swings' largest errors (median and 90th percentile over every swing of every run, degrees), and the paper's
    counts for the cell."""
    scored = _finished(runs, "fail", "cost", "motion")
    if scored.empty:
        return pd.DataFrame()
    rows = []
    for (experiment, cost, motion), group in _cells(scored):
        paper = PAPER_4C.get((cost, motion))
        errors = np.concatenate([np.asarray(e, float) for e in group["swing_max_error_deg"]])
        row = {"experiment": experiment, "cost": cost, "motion": motion, "runs": len(group)}
        row.update({outcome: _mean_std(group[outcome]) for outcome in OUTCOMES})
        if "floor_success" in group and group["floor_success"].notna().all():
            row["floor_success"] = _mean_std(group["floor_success"])
        row.update(
            {
                "mpjpe_mm": round(float(group["mpjpe_mm"].mean()), 1),
                "mpjpe_aligned_mm": _mean_of(group, "mpjpe_root_aligned_mm"),
                "mpjpe_floor_mm": _mean_of(group, "mpjpe_floor_mm"),
                "max_err_median_deg": round(float(np.median(errors)), 1) if len(errors) else None,
                "max_err_p90_deg": round(float(np.percentile(errors, 90)), 1) if len(errors) else None,
                "paper_fail": paper[0] if paper else None,
                "paper_error": paper[1] if paper else None,
                "paper_success": paper[2] if paper else None,
            }
        )
        rows.append(row)
    table = pd.DataFrame(rows)
    for column in ("paper_fail", "paper_error", "paper_success"):
        table[column] = table[column].astype("Int64")  # counts, blank where the paper has no such cell
    return table


SWING_BOUNDS_DEG = (10.0, 15.0, 20.0, 30.0, 45.0, 60.0)  # the rule's bound on a swing's largest error, swept


def table_4c_bounds(runs: pd.DataFrame, bounds: tuple[float, ...] = SWING_BOUNDS_DEG) -> pd.DataFrame:
    """Per experiment and cell: the swings followed (not Fail) and the Success count at each of ``bounds`` for the
    rule's largest error (the rule's own is 20 degrees), mean over the runs: whether an ordering of cells is real
    or an effect of the bound."""
    scored = _finished(runs, "fail", "cost", "motion")
    if scored.empty:
        return pd.DataFrame()
    rows = []
    for (experiment, cost, motion), group in _cells(scored):
        row = {
            "experiment": experiment,
            "cost": cost,
            "motion": motion,
            "runs": len(group),
            "followed": round(float(np.mean([sum(f) for f in group["swing_followed"]])), 1),
        }
        for bound in bounds:
            counts = [
                count_outcomes({"followed": f, "max_error_deg": e}, bound)["success"]
                for f, e in zip(group["swing_followed"], group["swing_max_error_deg"], strict=True)
            ]
            row[f"success <= {bound:g} deg"] = round(float(np.mean(counts)), 1)
        rows.append(row)
    return pd.DataFrame(rows)


def table_order(runs: pd.DataFrame) -> pd.DataFrame:
    """``runs`` by experiment (as named), then their cells (cost, motion) in the order the costs and motion models
    are registered."""
    order = {name: k for kind in ("cost", "motion") for k, name in enumerate(REGISTRIES[kind].names())}
    columns = [c for c in ("experiment", "cost", "motion") if c in runs]
    return runs.sort_values(columns, key=lambda c: c if c.name == "experiment" else c.map(order), kind="stable")


def _cells(scored: pd.DataFrame):
    """The runs grouped by experiment, cost and motion, in `table_order`."""
    scored = scored.assign(experiment=scored.get("experiment", pd.Series("", index=scored.index)).fillna(""))
    return table_order(scored).groupby(["experiment", "cost", "motion"], sort=False)


def _mean_of(group: pd.DataFrame, column: str) -> float | None:
    return round(float(group[column].mean()), 1) if column in group else None


def _mean_std(values: pd.Series) -> int | str:
    values = values.astype(float)
    if len(values) == 1:
        return int(values.iloc[0])
    return f"{values.mean():.1f} ± {values.std(ddof=1):.1f}"


def table_6d(runs: pd.DataFrame) -> pd.DataFrame:
    """Capture, estimation and total ms per frame over every frame of the finished runs that captured and
    estimated, one group of rows per sample-set size (the paper's timings are for its 57,136 samples)."""
    timed = _finished(runs, "capture_ms_median", "estimate_ms_median")
    if timed.empty:
        return pd.DataFrame()
    rows = []
    for samples, group in timed.groupby(timed["samples"].fillna(0).astype(int), sort=True):
        every = pd.concat(
            [
                pd.read_parquet(Path(run) / "frames.parquet").drop_duplicates("frame")[["capture_ms", "estimate_ms"]]
                for run in group["run"]
            ]
        )
        every["total_ms"] = every["capture_ms"] + every["estimate_ms"]
        for name, column in (("capture", "capture_ms"), ("estimation", "estimate_ms"), ("total", "total_ms")):
            values = every[column]
            rows.append(
                {
                    "samples": samples or None,
                    "runs": len(group),
                    "frames": len(every),
                    "stage": name,
                    "min": values.min(),
                    "max": values.max(),
                    "avg": values.mean(),
                    **{
                        f"{machine} {stat}": figures[name][k]
                        for machine, figures in PAPER_6D.items()
                        for k, stat in enumerate(("min", "max", "avg"))
                    },
                }
            )
    table = pd.DataFrame(rows)
    table["samples"] = table["samples"].astype("Int64")
    return table
