"""Tables from run directories: ``python -m eval.tables <sweep or run dir> [...] [--out reports]``.

Every ``metrics.json`` under the given directories becomes one row keyed by its Hydra choices and its job's
overrides; the sweep table (`sweep_table`, printed, and written as ``sweep.csv``) groups the runs that differ only
in ``seed`` and gives each numeric metric as mean ± std over those seeds. Runs of paper 2's experiment A give
the Fig 4(c) table (Fail / Error / Success per cost and motion model, next to the
paper's counts, plus MPJPE) as ``table4c.md`` / ``table4c.csv``, and the Fig 6(d) table (capture, estimation and
total ms per frame: min / max / average over every frame of those runs, next to the paper's PC and Cell columns)
as ``table6d.md``. Both name the machine. A run belongs to Fig 4(c) when it scored swings, and to Fig 6(d) when
it timed a capture and an estimation stage: whatever its tracker.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.atomic import atomic_path
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


_NOT_METRICS = {"seed", "frames", "frames_done"}


def collect(directories: list[Path]) -> pd.DataFrame:
    """One row per run: its choices, its overrides other than ``seed``, seed, status, every top-level numeric
    metric, the swing counts where it scored swings, and its stage timings (medians, ``timings.json``)."""
    rows = []
    for directory in directories:
        for path in sorted(Path(directory).rglob("metrics.json")):
            metrics = json.loads(path.read_text())
            swings = metrics.get("swings", {})
            numbers = {
                k: v
                for k, v in metrics.items()
                if isinstance(v, int | float) and not isinstance(v, bool) and k not in _NOT_METRICS
            }
            timings_path = path.parent / "timings.json"
            timings = json.loads(timings_path.read_text()) if timings_path.exists() else {}
            rows.append(
                {
                    **metrics.get("choices", {}),
                    "overrides": " ".join(_overrides(path.parent)),
                    "seed": metrics.get("seed"),
                    "status": metrics.get("status"),
                    "frames": metrics.get("frames_done"),
                    **numbers,
                    "fail": swings.get("fail"),
                    "error": swings.get("error"),
                    "success": swings.get("success"),
                    "samples": metrics.get("samples"),
                    **timings,
                    "run": str(path.parent),
                    "floor_success": metrics.get("swings_floor", {}).get("success"),
                    "swing_followed": metrics.get("swing_details", {}).get("followed", []),
                    "swing_max_error_deg": metrics.get("swing_details", {}).get("max_error_deg", []),
                }
            )
    return pd.DataFrame(rows)


def _overrides(run: Path) -> list[str]:
    """The job's command-line overrides (Hydra's ``.hydra/overrides.yaml``) other than ``seed``."""
    path = run / ".hydra" / "overrides.yaml"
    if not path.exists():
        return []
    lines = [line.removeprefix("- ").strip() for line in path.read_text().splitlines() if line.startswith("- ")]
    return sorted(line for line in lines if not line.startswith("seed="))


def sweep_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per set of runs that differ only in seed: the key (choices and overrides), the number of runs
    and of finished ones, the seeds, and each numeric metric as ``mean ± std`` over the finished runs (the
    value alone for one run)."""
    if runs.empty:
        return pd.DataFrame()
    keys = [c for c in runs.columns if c in (*REGISTRIES, "experiment")]
    keys.append("overrides")
    skip = {*keys, "seed", "status", "frames", "run", "samples"}
    metrics = [c for c in runs.columns if c not in skip and pd.api.types.is_numeric_dtype(runs[c])]
    rows = []
    for key, group in runs.fillna({k: "" for k in keys}).groupby(keys, sort=True, dropna=False):
        finished = group[group["status"] == "ok"]
        row = dict(zip(keys, key, strict=True))
        row.update(
            {
                "runs": len(group),
                "ok": len(finished),
                "seeds": ",".join(str(s) for s in sorted(group["seed"].dropna().astype(int))),
            }
        )
        for column in metrics:
            values = finished[column].dropna()
            if len(values) == 1:
                row[column] = f"{values.iloc[0]:.4g}"
            elif len(values) > 1:
                row[column] = f"{values.mean():.4g} ± {values.std(ddof=1):.2g}"
        rows.append(row)
    return pd.DataFrame(rows)


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


def machine() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"


def write_reports(runs: pd.DataFrame, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    written = []
    four_c = table_4c(runs)
    if not four_c.empty:
        with atomic_path(out / "table4c.csv") as temporary:
            four_c.to_csv(temporary, index=False)
        text = (
            "# Fig 4(c): right-arm swings tracked (of the swings in each run)\n\n"
            f"Machine: {machine()}. Swings are scored by the rule of `tracker/evaluation/body.py` "
            "(the paper counted by eye); counts are mean ± std over a cell's runs.\n\n"
            + markdown(four_c)
            + "\n\n## Success at other bounds of a swing's largest error (the rule's: 20 degrees)\n\n"
            + markdown(table_4c_bounds(runs))
            + "\n"
        )
        with atomic_path(out / "table4c.md") as temporary:
            temporary.write_text(text)
        written += [out / "table4c.md", out / "table4c.csv"]
    six_d = table_6d(runs)
    if not six_d.empty:
        text = (
            "# Fig 6(d): processing time (ms per frame)\n\n"
            f"Ours: {machine()}, over every frame of the runs, grouped by the number of pose samples "
            "(capture = silhouette extraction at 320x240; estimation = the tracker's step). The paper's "
            "columns are its own machines, for its 57,136 samples.\n\n" + markdown(six_d.round(2)) + "\n"
        )
        with atomic_path(out / "table6d.md") as temporary:
            temporary.write_text(text)
        written.append(out / "table6d.md")
    return written


def markdown(table: pd.DataFrame) -> str:
    header = "| " + " | ".join(map(str, table.columns)) + " |"
    rule = "|" + "---|" * len(table.columns)
    lines = ["| " + " | ".join("" if pd.isna(v) else str(v) for v in row) + " |" for row in table.itertuples(False)]
    return "\n".join([header, rule, *lines])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("directories", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, default=Path("reports"))
    args = parser.parse_args()
    runs = collect(args.directories)
    if runs.empty:
        raise SystemExit(f"no metrics.json under {', '.join(map(str, args.directories))}")
    sweep = sweep_table(runs)
    print(markdown(sweep))
    args.out.mkdir(parents=True, exist_ok=True)
    with atomic_path(args.out / "sweep.csv") as temporary:
        sweep.to_csv(temporary, index=False)
    print(f"wrote {args.out / 'sweep.csv'}")
    four_c = table_4c(runs)
    if not four_c.empty:
        print(markdown(four_c))
    for path in write_reports(runs, args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
