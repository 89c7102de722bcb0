import json
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from rerun.chunk import RrdReader

from tests.conftest import TBF_RUN, run_cli
from tracker.models.dsq import PARAM_NAMES

VIEWS = ("front", "left", "top")
PARTS = ("upper_arm", "forearm", "hand")


def frames_by_entity(path):
    """Entity path -> sorted frame indices at which it was logged (non-static chunks)."""
    frames: dict[str, list[int]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.is_static or "frame" not in chunk.timeline_names:
            continue
        column = chunk.to_record_batch().column("frame").to_pylist()
        frames.setdefault(chunk.entity_path, []).extend(column)
    return {entity: sorted(values) for entity, values in frames.items()}


def test_run_writes_the_three_outputs_and_nothing_half_written(five_frame_run):
    names = {p.name for p in five_frame_run.iterdir()}
    assert {"run.rrd", "frames.parquet", "timings.json", "metrics.json", ".hydra"} <= names
    assert not [name for name in names if name.endswith(".tmp")]


def test_metrics_summarise_the_run(five_frame_run):
    metrics = json.loads((five_frame_run / "metrics.json").read_text())
    timing = json.loads((five_frame_run / "timings.json").read_text())
    assert metrics["status"] == "ok"
    assert metrics["choices"] == {
        "model": "dsq_arm",
        "rig": "orthogonal3",
        "scene": "arm_swing",
        "tracker": "render_only",
    }
    assert (metrics["seed"], metrics["frames"], metrics["frames_done"]) == (0, 5, 5)
    assert metrics["views"] == ["front", "left", "top"]
    assert set(timing) == {
        "pose_ms_median",
        "render_ms_median",
        "evaluate_ms_median",
        "record_ms_median",
        "render_ms_per_view_median",
    }
    assert all(value > 0 for value in timing.values())
    assert metrics["min_visible_fraction"]["forearm"]["left"] == 0.0  # hidden end-on at frame 0


def test_frames_table_has_truth_per_frame_and_part(five_frame_run, arm, motion):
    table = pd.read_parquet(five_frame_run / "frames.parquet")
    assert len(table) == 5 * 3 and list(table["part"][:3]) == list(PARTS)
    truth = table[[f"truth_{name}" for name in PARAM_NAMES]].to_numpy().reshape(5, 3, 17)
    for frame in range(5):
        np.testing.assert_allclose(truth[frame], motion.params(arm, frame))
    assert {f"visible_px_{view}" for view in VIEWS} <= set(table.columns)
    assert (table[["pose_ms", "render_ms", "record_ms"]] > 0).all().all()


def test_recording_has_images_labels_params_and_timings_for_every_frame(five_frame_run):
    path = five_frame_run / "run.rrd"
    reader = RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1  # with its default blueprint
    frames = frames_by_entity(path)
    every_frame = [0, 1, 2, 3, 4]
    for view in VIEWS:
        assert frames[f"/world/cameras/{view}/image/rgb"] == every_frame
        assert frames[f"/world/cameras/{view}/image/labels"] == every_frame
    for stage in ("pose", "render", "record"):
        assert frames[f"/metrics/timing/{stage}_ms"] == every_frame
    for part in PARTS:
        assert frames[f"/world/truth/{part}"] == every_frame
        assert frames[f"/metrics/params/{part}/b1/truth"] == every_frame
    chunks = [chunk for chunk in reader.stream().to_chunks() if chunk.entity_path.startswith("/metrics/")]
    series = [chunk for chunk in chunks if not chunk.is_static]
    assert all(chunk.timeline_names == ["frame"] for chunk in series)  # a series is sent as columns, one chunk each
    assert len(series) == len({chunk.entity_path for chunk in series})
    colours = {chunk.entity_path for chunk in chunks if chunk.is_static}  # a plotted one's colour, once
    assert "/metrics/timing/render_ms" in colours and colours <= {chunk.entity_path for chunk in series}


def blueprint_origins(path) -> set[str]:
    """The space origins of the views in a recording's default blueprint."""
    reader = RrdReader(path)
    origins = set()
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        batch = chunk.to_record_batch()
        if "ViewBlueprint:space_origin" in batch.schema.names:
            origins.update(value[0] for value in batch.column("ViewBlueprint:space_origin").to_pylist() if value)
    return origins


def test_default_blueprint_shows_the_views_the_scene_and_the_series(five_frame_run, abis_run):
    origins = blueprint_origins(five_frame_run / "run.rrd")
    assert {f"world/cameras/{view}/image" for view in VIEWS} <= origins  # RGB with the label overlay
    assert {"world", "metrics/visible_px", "metrics/timing"} <= origins  # the arm's 9 parts' pixels in one plot
    assert "metrics/params/forearm" in origins  # the model's own: Fig 8's b1 and r2
    assert not any(origin.startswith(("metrics/correspondences", "metrics/error")) for origin in origins)  # no estimate
    tracked = blueprint_origins(abis_run / "run.rrd")
    assert "metrics/error" in tracked  # the estimate's errors, where a tracker estimates
    pairs = [origin for origin in tracked if "correspondences" in origin]
    assert sorted(pairs) == [f"metrics/correspondences/{part}" for part in sorted(PARTS)]  # a plot per part


def test_recorded_truth_series_equals_the_frames_table(five_frame_run):
    table = pd.read_parquet(five_frame_run / "frames.parquet")
    expected = table.loc[table["part"] == "forearm", "truth_r2"].to_numpy()
    values = {}
    for chunk in RrdReader(five_frame_run / "run.rrd").stream().to_chunks():
        if chunk.entity_path == "/metrics/params/forearm/r2/truth" and not chunk.is_static:  # static: its colour
            batch = chunk.to_record_batch()
            frames, scalars = batch.column("frame").to_pylist(), batch.column("Scalars:scalars").to_pylist()
            values.update(zip(frames, scalars, strict=True))
    np.testing.assert_allclose([values[f][0] for f in range(5)], expected)


def test_each_run_has_its_own_recording_id(five_frame_run, tmp_path):
    result = run_cli(tmp_path / "again", "frames=1", "record.images=false", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    ids = {RrdReader(d / "run.rrd").recordings()[0].recording_id for d in (five_frame_run, tmp_path / "again")}
    assert len(ids) == 2


def test_the_same_seed_gives_the_same_metrics_bytes_and_another_seed_differs(tmp_path):
    runs = {"a": "seed=3", "b": "seed=3", "c": "seed=4"}
    for name, seed in runs.items():
        result = run_cli(tmp_path / name, "tracker=abis", "frames=3", "record.images=false", seed, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    metrics = {name: (tmp_path / name / "metrics.json").read_bytes() for name in runs}
    assert metrics["a"] == metrics["b"]
    results = {
        name: {k: v for k, v in json.loads(text).items() if k not in ("seed", "config")}
        for name, text in metrics.items()
    }
    assert results["a"]["rms"] != results["c"]["rms"]  # the seed reached the tracker's start, not just the config
    timings = {name: json.loads((tmp_path / name / "timings.json").read_text()) for name in runs}
    assert timings["a"]["estimate_ms_median"] > 0  # timings live apart, so they may differ


def test_a_failing_run_records_why_and_keeps_its_outputs_readable(tmp_path):
    # The tracker's samples fall outside a camera looking away: the run fails after Hydra started it.
    result = run_cli(
        tmp_path / "out", *TBF_RUN, "rig.target=[0,9,0.9]", f"tracker.cache_dir={tmp_path}/c", cwd=tmp_path
    )
    assert result.returncode == 1
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["status"] == "failed: ValueError: the pose samples are not in the camera's view"
    assert metrics["frames_done"] == 0
    assert pd.read_parquet(tmp_path / "out" / "frames.parquet").empty
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("signal_number", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_run_says_so_and_leaves_readable_outputs(tmp_path, signal_number):
    run_dir = tmp_path / "out"
    command = [sys.executable, "-m", "experiments.run", f"hydra.run.dir={run_dir}", "frames=1000"]
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    # The recording's temporary file exists once the stop handler is installed and the components are built; a
    # stop asked from then on still finishes the frame under way. Its bytes arrive in large batches
    # (recording_file.BATCHES), so its size says little of the frames done: three seconds hold frames enough, also on
    # a loaded machine (with one second, no frame had finished there; later frames take ~70 ms).
    deadline = time.monotonic() + 120
    while not list(run_dir.glob(".run.rrd.*.tmp")) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(3.0)
    process.send_signal(signal_number)  # Ctrl-C, or a scheduler's stop
    assert process.wait(timeout=120) != 0
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["status"] == f"failed: interrupted by {signal_number.name}" and 0 < metrics["frames_done"] < 1000
    assert len(pd.read_parquet(run_dir / "frames.parquet")) == 3 * metrics["frames_done"]
    assert RrdReader(run_dir / "run.rrd").recordings()
    assert not list(run_dir.glob("*.tmp")) and not list(run_dir.glob(".*.tmp"))
