import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.conftest import MOCAP_DIR
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.motion.mocap import MocapScene
from tracker.tbf.pose_sets import arm_grid, clip_samples


def test_the_arm_grid_sweeps_the_right_arm_and_keeps_the_rest(body):
    poses = arm_grid(body, swing_deg=[-30.0, 0.0, 45.0], abduction_deg=[10.0, 30.0], elbow_deg=[0.0, 90.0],
                     left_swing_deg=[0.0, 20.0])  # fmt: skip
    assert poses.shape == (2 * 3 * 2 * 2, 96)
    heads = [body.joint_positions(pose) for pose in poses]
    shoulder, elbow, wrist = (JOINT_INDEX[name] for name in ("RightArm", "RightForeArm", "RightHand"))
    upper = np.array([h[elbow] - h[shoulder] for h in heads])
    # Swing: the upper arm's angle from the downward vertical in the sagittal (y, z) plane, + forward (-y).
    swing = np.degrees(np.arctan2(-upper[:, 1], -upper[:, 2]))
    np.testing.assert_allclose(swing[:12].reshape(3, 4)[:, 0], [-30.0, 0.0, 45.0], atol=0.5)
    forearm = np.array([h[wrist] - h[elbow] for h in heads])
    cosine = np.sum(upper * forearm, axis=1) / np.linalg.norm(upper, axis=1) / np.linalg.norm(forearm, axis=1)
    bent = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    assert bent[0] < 12.0 and abs(bent[1] - 90.0) < 12.0  # elbow 0 and 90 (the rig's own elbow angle adds a little)
    np.testing.assert_array_equal(poses[:, :3], np.broadcast_to(body.rest_heads[0], (24, 3)))


def test_clip_samples_take_every_frame_of_each_clip(body):
    paths = [MOCAP_DIR / "143_33.bvh", MOCAP_DIR / "69_20.bvh"]
    poses = clip_samples(body, paths, fps=10.0)
    lengths = [len(MocapScene(str(path), fps=10.0).poses(body)) for path in paths]
    assert len(poses) == sum(lengths) and lengths[0] == 30  # 360 x .0083333 s = 2.99999 s: 29 steps of 0.1 s
    facing = Rotation.from_rotvec(poses[lengths[0], 3:6]).apply([0.0, -1.0, 0.0])  # the second clip's start
    assert np.degrees(np.arctan2(facing[1], facing[0])) == pytest.approx(-90.0)
