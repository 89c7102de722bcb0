import json

import numpy as np
import pandas as pd

from eval.recordings import read_images
from tests.conftest import MOCAP_DIR, run_cli
from tests.experiments.test_run import frames_by_entity
from tracker.models.body_skeleton import POSE_SIZE
from tracker.motion.body_swing import BodySwing
from tracker.tbf.costs import weight_map


def test_a_body_run_records_silhouettes_weight_maps_and_their_quality(body_swing_run):
    metrics = json.loads((body_swing_run / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["choices"]["rig"] == "body_side"  # the model picked its camera
    assert metrics["silhouette_iou"]["main"]["min"] >= 0.97
    frames = frames_by_entity(body_swing_run / "run.rrd")
    for entity in (
        "/world/cameras/main/image/rgb",
        "/world/cameras/main/image/silhouette",
        "/capture/main/weights/wxor",
        "/capture/main/weights/nwxor",
        "/metrics/silhouette_iou/main",
        "/world/truth/body_right_upper_arm",
        "/metrics/params/joints/RightArm_deg/truth",
    ):
        assert frames[entity] == [0, 1, 2, 3], entity
    assert frames["/world/truth/body_left_foot"] == [0]  # only the right arm moves: a foot is written once


def test_a_body_runs_table_holds_the_truth_pose_per_frame(body_swing_run, body):
    table = pd.read_parquet(body_swing_run / "frames.parquet")
    assert len(table) == 4 * 15 and len(table["truth_pose"].iloc[0]) == POSE_SIZE
    poses = np.array([row for row in table.drop_duplicates("frame")["truth_pose"]])
    np.testing.assert_allclose(poses, [BodySwing().params(body, k) for k in range(4)], atol=1e-12)


def test_recorded_weight_maps_are_those_of_the_recorded_silhouettes(body_swing_run):
    path = body_swing_run / "run.rrd"
    silhouettes = read_images(path, "/world/cameras/main/image/silhouette")
    for cost in ("wxor", "nwxor"):
        maps = read_images(path, f"/capture/main/weights/{cost}")
        assert maps[2].dtype == np.float32 and maps[2].shape == (240, 320)
        np.testing.assert_allclose(maps[2], weight_map(cost, silhouettes[2] > 0), rtol=1e-6)


def test_a_mocap_clip_runs_as_a_scene(tmp_path):
    result = run_cli(
        tmp_path / "out",
        "model=body_mesh",
        "scene=bvh",
        f"scene.path={MOCAP_DIR / '69_20.bvh'}",
        "rig=body_front",
        "frames=3",
        "record.images=false",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["frames_done"] == 3
    assert metrics["silhouette_iou"]["main"]["mean"] >= 0.97
