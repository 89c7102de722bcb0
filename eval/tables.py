"""Tables from run directories: ``python -m eval.tables <sweep or run dir> [...] [--out reports]``.

Every ``metrics.json`` under the given directories becomes one row keyed by its Hydra choices and its job's
overrides (`eval.runs.collect`); the sweep table (`sweep_table`, printed, and written as ``sweep.csv``) groups the
runs that differ only in ``seed`` and gives each numeric metric as mean ± std over those seeds. Runs of paper 2's
experiment A also give ``table4c.md`` / ``table4c.csv`` and ``table6d.md`` (`eval.paper_2_tables`), naming the
machine.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from eval.paper_2_tables import table_4c, table_4c_bounds, table_6d
from eval.runs import collect, machine, markdown
from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.atomic import atomic_path
from tracker.registry import REGISTRIES


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


def write_reports(runs: pd.DataFrame, out: Path) -> list[Path]:
    """Fig 4(c)'s and Fig 6(d)'s tables of ``runs`` into ``out``, where the runs make them."""
    out.mkdir(parents=True, exist_ok=True)
    return write_table_4c(runs, out) + write_table_6d(runs, out)


def write_table_4c(runs: pd.DataFrame, out: Path) -> list[Path]:
    """``table4c.md`` and ``.csv`` (none when no run scored swings)."""
    four_c = table_4c(runs)
    if four_c.empty:
        return []
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
    return [out / "table4c.md", out / "table4c.csv"]


def write_table_6d(runs: pd.DataFrame, out: Path) -> list[Path]:
    """``table6d.md`` (none when no run timed a capture and an estimation)."""
    six_d = table_6d(runs)
    if six_d.empty:
        return []
    text = (
        "# Fig 6(d): processing time (ms per frame)\n\n"
        f"Ours: {machine()}, over every frame of the runs, grouped by the number of pose samples "
        "(capture = silhouette extraction at 320x240; estimation = the tracker's step). The paper's "
        "columns are its own machines, for its 57,136 samples.\n\n" + markdown(six_d.round(2)) + "\n"
    )
    with atomic_path(out / "table6d.md") as temporary:
        temporary.write_text(text)
    return [out / "table6d.md"]


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
