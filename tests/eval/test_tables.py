import pandas as pd

from eval.paper_2_tables import PAPER_4C, table_4c, table_4c_bounds, table_6d
from eval.runs import collect
from eval.tables import write_reports


def test_tables_collect_tbf_runs_next_to_the_papers_numbers(tbf_run, tmp_path):
    runs = collect([tbf_run.parent])
    assert len(runs) == 1 and runs.loc[0, "tracker"] == "tbf" and runs.loc[0, "status"] == "ok"
    four_c = table_4c(runs)
    assert list(four_c.columns) == [
        "experiment",
        "cost",
        "motion",
        "runs",
        "fail",
        "error",
        "success",
        "floor_success",
        "mpjpe_mm",
        "mpjpe_aligned_mm",
        "mpjpe_floor_mm",
        "max_err_median_deg",
        "max_err_p90_deg",
        "paper_fail",
        "paper_error",
        "paper_success",
    ]
    row = four_c.iloc[0]
    assert (row["cost"], row["motion"]) == ("nwxor", "dm2")
    assert (row["paper_fail"], row["paper_error"], row["paper_success"]) == PAPER_4C[("nwxor", "dm2")]
    six_d = table_6d(runs)
    frames = pd.read_parquet(tbf_run / "frames.parquet").drop_duplicates("frame")
    assert six_d.loc[six_d["stage"] == "capture", "max"].item() == frames["capture_ms"].max()
    assert six_d.loc[six_d["stage"] == "estimation", "avg"].item() == frames["estimate_ms"].mean()
    assert set(six_d["samples"]) == {runs.loc[0, "samples"]} and set(six_d["frames"]) == {len(frames)}
    written = write_reports(runs, tmp_path)
    assert {path.name for path in written} == {"table4c.md", "table4c.csv", "table6d.md"}
    assert pd.read_csv(tmp_path / "table4c.csv").shape == (1, 16)
    assert "| nwxor | dm2 |" in (tmp_path / "table4c.md").read_text()


def test_fig4c_counts_at_any_bound_follow_from_each_swings_largest_error():
    details = {"followed": [True, True, True, False], "max_error_deg": [5.0, 19.0, 25.0, 3.0]}
    runs = pd.DataFrame(
        [
            {
                "experiment": "x",
                "cost": "nwxor",
                "motion": "dm2",
                "status": "ok",
                "fail": 1,
                "error": 1,
                "success": 2,
                "mpjpe_mm": 10.0,
                "swing_followed": details["followed"],
                "swing_max_error_deg": details["max_error_deg"],
            },
            {
                "experiment": "x",
                "cost": "nwxor",
                "motion": "dm2",
                "status": "ok",
                "fail": 1,
                "error": 0,
                "success": 3,
                "mpjpe_mm": 20.0,
                "swing_followed": [True, True, True, False],
                "swing_max_error_deg": [1.0, 2.0, 3.0, 4.0],
            },
        ]
    )
    bounds = table_4c_bounds(runs, bounds=(10.0, 20.0, 30.0)).iloc[0]
    # run 1: 1 / 2 / 3 swings within 10 / 20 / 30 degrees among those followed; run 2: 3 at every bound
    assert (bounds["success <= 10 deg"], bounds["success <= 20 deg"], bounds["success <= 30 deg"]) == (2.0, 2.5, 3.0)
    assert bounds["followed"] == 3.0
    row = table_4c(runs).iloc[0]
    assert (row["runs"], row["success"], row["fail"], row["mpjpe_mm"]) == (2, "2.5 ± 0.7", "1.0 ± 0.0", 15.0)
    assert row["max_err_median_deg"] == 3.5  # of 1, 2, 3, 3, 4, 5, 19, 25
