import json

import numpy as np
import pandas as pd
from omegaconf import OmegaConf
from rerun.chunk import RrdReader

from eval.recordings import read_mesh_vertices
from experiments.components import build
from tests.experiments.test_run import PARTS, VIEWS, frames_by_entity
from tracker.abis.correspondences import COUNT_NAMES
from tracker.models.dsq import PARAM_NAMES


def test_frames_table_has_estimates_counts_and_costs(abis_run):
    table = pd.read_parquet(abis_run / "frames.parquet")
    assert len(table) == 10 * 3
    for name in PARAM_NAMES:
        assert {f"truth_{name}", f"est_{name}"} <= set(table.columns)
    for count in COUNT_NAMES:
        assert count in table.columns and {f"{count}_{view}" for view in VIEWS} <= set(table.columns)
        np.testing.assert_array_equal(table[count], sum(table[f"{count}_{view}"] for view in VIEWS))
    assert {
        "pairs",
        "cost",
        "iterations",
        "surface_error_mm",
        "surface_distance_mm",
        "estimate_ms",
        "estimate_fit_ms",
    } <= set(table.columns)
    forearm = table[table["part"] == "forearm"]
    assert (forearm["iterations"].iloc[1:] > 0).all() and (forearm["cost"].iloc[1:] > 0).all()


def test_metrics_report_the_issue_figures(abis_run):
    metrics = json.loads((abis_run / "metrics.json").read_text())
    timing = json.loads((abis_run / "timings.json").read_text())
    assert metrics["status"] == "ok" and metrics["tracker"] == "abis"
    assert set(metrics["rms"]) == set(PARTS) and "r2_deg" in metrics["rms"]["forearm"]
    table = pd.read_parquet(abis_run / "frames.parquet")
    forearm = table[table["part"] == "forearm"]
    independent = np.sqrt(np.mean((forearm["est_b1"] - forearm["truth_b1"]) ** 2))
    assert metrics["part2_b1_rms"] == independent
    assert metrics["part2_b1_range"] == np.ptp(forearm["truth_b1"])
    # Fig 8's targets over whole runs are 10% of b1's range and 3 deg; these 10 frames are where b1 rises fastest and
    # anchoring the first pairs to the texture costs a little (tests/tracker/abis/test_tracker.py).
    assert metrics["part2_r2_rms_deg"] < 3.0 and metrics["part2_b1_rms"] < 0.15 * 0.08
    assert metrics["failed_frames"] == 0 and timing["estimate_ms_median"] > 0


def test_recording_has_the_count_series_features_and_estimate(abis_run):
    frames = frames_by_entity(abis_run / "run.rrd")
    every_frame = list(range(10))
    for part in PARTS:
        for count in COUNT_NAMES:
            assert frames[f"/metrics/correspondences/{part}/{count}"] == every_frame
        assert frames[f"/metrics/params/{part}/r2/estimate"] == every_frame
        assert frames[f"/world/estimate/{part}"] == every_frame
    for view in VIEWS:
        assert frames[f"/world/cameras/{view}/image/features"] == every_frame
        assert frames[f"/world/cameras/{view}/image/estimate"] == every_frame
    assert RrdReader(abis_run / "run.rrd").recordings()


def test_recorded_meshes_are_the_models_surfaces_at_every_frame(abis_run):
    """Read back as the viewer shows them (vertices moved by their transform), the truth and estimate meshes are
    the model's surfaces for the parameters in frames.parquet; parts that only moved were written as transforms."""
    model = build(OmegaConf.load(abis_run / ".hydra" / "config.yaml")).model
    table = pd.read_parquet(abis_run / "frames.parquet")
    for kind, prefix in (("truth", "truth_"), ("estimate", "est_")):
        recorded = {part: read_mesh_vertices(abis_run / "run.rrd", f"/world/{kind}/{part}") for part in PARTS}
        for frame, rows in table.groupby("frame"):
            params = rows.set_index("part").loc[list(PARTS), [prefix + name for name in PARAM_NAMES]].to_numpy()
            for mesh in model.surface_meshes(params):
                np.testing.assert_allclose(recorded[mesh.key][frame], mesh.vertices, atol=1e-5)
    chunks = [
        chunk.to_record_batch()
        for chunk in RrdReader(abis_run / "run.rrd").stream().to_chunks()
        if chunk.entity_path == "/world/truth/upper_arm" and not chunk.is_static
    ]
    vertex_rows = sum(
        batch.column("Mesh3D:vertex_positions").null_count < batch.num_rows
        for batch in chunks
        if "Mesh3D:vertex_positions" in batch.schema.names
    )
    assert vertex_rows >= 1 and any("Transform3D:translation" in batch.schema.names for batch in chunks)
