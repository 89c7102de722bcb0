import pandas as pd

from eval.tables import PAPER_4C, collect, table_4c, table_6d, write_reports


def test_tables_collect_tbf_runs_next_to_the_papers_numbers(tbf_run, tmp_path):
    runs = collect([tbf_run.parent])
    assert len(runs) == 1 and runs.loc[0, "tracker"] == "tbf" and runs.loc[0, "status"] == "ok"
    four_c = table_4c(runs)
    assert list(four_c.columns) == ["cost", "motion", "fail", "error", "success", "mpjpe_mm", "paper_fail",
                                    "paper_error", "paper_success"]  # fmt: skip
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
    assert pd.read_csv(tmp_path / "table4c.csv").shape == (1, 9)
    assert "| nwxor | dm2 |" in (tmp_path / "table4c.md").read_text()
