import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.conftest import MOCAP_DIR
from tracker.models.body_skeleton import JOINT_INDEX, MIRROR_JOINTS, joint_angle_differences
from tracker.motion.mocap import MocapScene
from tracker.tbf.pose_sets import (
    arm_grid,
    clip_sequences,
    learned_transitions,
    mirrored,
    near_duplicate_representatives,
    remove_near_duplicates,
    repeated_sequences,
    successors,
)


def test_the_arm_grid_sweeps_the_right_arm_and_keeps_the_rest(body):
    poses = arm_grid(
        body,
        swing_deg=[-30.0, 0.0, 45.0],
        abduction_deg=[10.0, 30.0],
        elbow_deg=[0.0, 90.0],
        left_swing_deg=[0.0, 20.0],
    )
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


def test_clip_sequences_take_every_frame_of_each_clip(body):
    paths = [MOCAP_DIR / "143_33.bvh", MOCAP_DIR / "69_20.bvh"]
    poses, sequence = clip_sequences(body, paths, fps=10.0)
    lengths = [len(MocapScene(str(path), fps=10.0).poses(body)) for path in paths]
    assert len(poses) == sum(lengths) and lengths[0] == 30  # 360 x .0083333 s = 2.99999 s: 29 steps of 0.1 s
    np.testing.assert_array_equal(sequence, np.repeat([0, 1], lengths))
    facing = Rotation.from_rotvec(poses[lengths[0], 3:6]).apply([0.0, -1.0, 0.0])  # the second clip's start
    assert np.degrees(np.arctan2(facing[1], facing[0])) == pytest.approx(-90.0)


def test_a_mirrored_pose_is_the_pose_reflected_with_left_and_right_swapped(body):
    poses = MocapScene(str(MOCAP_DIR / "143_23.bvh"), fps=2.0).poses(body)[:6]
    poses[:, 0] += 0.3  # off the mirror plane
    reflect = np.array([-1.0, 1.0, 1.0])
    mine = body.joint_positions(mirrored(poses))
    theirs = body.joint_positions(poses)[:, list(MIRROR_JOINTS)] * reflect
    # The rig's two sides differ by a few millimetres at rest (the T-pose shoulders by 2 degrees).
    rest = body.joint_positions(body.rest_pose())
    asymmetry = np.abs(rest[list(MIRROR_JOINTS)] * reflect - rest).max()
    assert np.abs(mine - theirs).max() < asymmetry + 0.005  # measured: 19.5 mm against 19.2 mm at rest
    np.testing.assert_allclose(mirrored(mirrored(poses)), poses, atol=1e-12)


def test_each_dropped_pose_is_represented_by_a_kept_pose_within_the_threshold(body):
    poses = MocapScene(str(MOCAP_DIR / "143_23.bvh"), fps=30.0).poses(body)[:150]
    kept, representative = near_duplicate_representatives(poses, 5.0)
    np.testing.assert_array_equal(kept, remove_near_duplicates(poses, 5.0))
    assert 10 < len(kept) < 150
    np.testing.assert_array_equal(representative[kept], np.arange(len(kept)))
    differences = joint_angle_differences(poses, poses[kept[representative]])
    assert differences.max() <= 5.0 + 1e-6
    # Naive: the representative is the first kept pose (in order) within 5 degrees in every joint.
    for index in range(len(poses)):
        close = np.flatnonzero((joint_angle_differences(poses[index], poses[kept]) <= 5.0 + 1e-9).all(axis=1))
        assert representative[index] == close[0]


def test_clip_transitions_follow_consecutive_frames_within_each_sequence():
    sequence = np.array([0, 0, 0, 1, 1, 2])
    following = successors(sequence)
    np.testing.assert_array_equal(following, [1, 2, -1, 4, -1, -1])
    np.testing.assert_array_equal(
        successors(repeated_sequences(sequence, 2)), [1, 2, -1, 4, -1, -1, 7, 8, -1, 10, -1, -1]
    )
    representative = np.array([0, 0, 1, 2, 1, 3])  # poses 0 and 1 are one sample, 2 and 4 another
    np.testing.assert_array_equal(learned_transitions(following, representative), [[0, 0, 1], [0, 1, 1], [2, 1, 1]])
