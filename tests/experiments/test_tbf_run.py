import json

import pandas as pd

from tests.experiments.test_run import blueprint_origins, frames_by_entity


def test_a_tbf_run_records_the_tree_search_per_level_and_its_timings(tbf_run):
    metrics = json.loads((tbf_run / "metrics.json").read_text())
    timing = json.loads((tbf_run / "timings.json").read_text())
    assert metrics["status"] == "ok" and metrics["tracker"] == "tbf"
    assert len(metrics["nodes_evaluated_mean"]) == 3 and all(n >= 1 for n in metrics["nodes_evaluated_mean"])
    assert len(metrics["tree_nodes"]) == 3 and metrics["tree_nodes"][-1] <= metrics["samples"]
    assert metrics["mpjpe_mm"] < 60 and metrics["swing_error_deg_mean"] < 15
    assert 0 <= metrics["mpjpe_root_aligned_mm"] < 60
    for stage in ("capture", "estimate", "estimate_prior", "estimate_level1", "estimate_level2", "estimate_level3"):
        assert timing[f"{stage}_ms_median"] > 0, stage
    table = pd.read_parquet(tbf_run / "frames.parquet").drop_duplicates("frame")
    assert list(table["frame"]) == list(range(6))
    assert (table["kept_level1"] <= table["nodes_level1"]).all() and (table["nodes_level3"] >= 1).all()
    assert len(table["est_pose"].iloc[0]) == 96 and table["entropy"].ge(0).all()
    frames = frames_by_entity(tbf_run / "run.rrd")
    for entity in (
        "/metrics/tree/level1/evaluated",
        "/metrics/tree/level3/kept",
        "/metrics/tree/entropy",
        "/metrics/params/swing/right_arm_deg/estimate",
        "/metrics/params/swing/right_arm_deg/truth",
    ):
        assert frames[entity] == list(range(6)), entity


def test_the_tbf_blueprint_shows_the_silhouette_and_the_tree_search(tbf_run):
    origins = blueprint_origins(tbf_run / "run.rrd")
    view = "main"
    assert f"world/cameras/{view}/image" in origins  # the image, and the silhouette beside and over it
    assert {"world", "metrics/params/swing", "metrics/tree", "metrics/silhouette_iou"} <= origins
    assert "metrics/correspondences" not in origins  # AbIS's pairs have no place here


def test_eval_figures_writes_every_figure_of_a_body_run(tbf_run, tmp_path):
    """A tree-filtering run of the body: its views, Fig 5's strip and its error against the dictionary's floor, by
    the command a user runs; 6 frames hold no complete swing, so no Fig 4(c) evidence."""
    import shutil
    import subprocess
    import sys

    run = shutil.copytree(tbf_run, tmp_path / "run")
    subprocess.run([sys.executable, "-m", "eval.figures", str(run)], check=True, capture_output=True)
    assert {"views.png", "fig5_strip.png", "error_against_floor.png"} <= {path.name for path in run.iterdir()}
    assert "fig4c_swings.png" not in {path.name for path in run.iterdir()}
