"""A standing person's posture, the capture session of samples and the subject's varied swing: conventions checked
on the posed skeleton, ranges kept, and the samples never holding the test motion."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.evaluation.body import split_swings
from tracker.models.body_shapes import STANDARD_BODIES, MacroShape
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.models.makehuman import build_body
from tracker.motion.arm_capture import ArmRanges, right_arm_track
from tracker.motion.body_swing import _SWING_SPREAD, SWINGS_PER_BLOCK, BodySwing
from tracker.motion.posture import (
    NATURAL_SPREAD,
    ONE_SIDED,
    RANGE_SIGMAS,
    Drifts,
    Posture,
    arms_pose,
    standing_pose,
    standing_poses,
)
from tracker.tbf.pose_sets import remove_near_duplicates
from tracker.tbf.sample_spec import CaptureSpec


@pytest.fixture(scope="module")
def body():
    return build_body()


def joint(body, pose, name):
    return body.joint_positions(pose)[JOINT_INDEX[name]]


def test_a_still_posture_is_the_arms_pose(body):
    posture = Posture(right=(30.0, 10.0, 20.0), left=(-5.0, 8.0, 0.0), yaw_deg=-80.0)
    np.testing.assert_allclose(
        standing_pose(body, posture), arms_pose(body, posture.right, posture.left, -80.0), atol=1e-12
    )


def test_postures_put_on_the_floor_together_are_each_put_there_alone_to_the_bit(body):
    rng = np.random.default_rng(5)
    postures = [
        Posture(
            right=tuple(rng.uniform(-30.0, 90.0, 3)),
            yaw_deg=float(rng.uniform(-120.0, -60.0)),
            left_knee_deg=float(rng.uniform(0.0, 20.0)),
            weight_shift_deg=float(rng.uniform(-4.0, 4.0)),
            root_offset_m=tuple(rng.uniform(-0.1, 0.1, 2)),
        )
        for _ in range(12)
    ]
    np.testing.assert_array_equal(standing_poses(body, postures), [standing_pose(body, p) for p in postures])
    assert standing_poses(body, []).shape == (0, len(body.rest_pose()))


@pytest.mark.parametrize(("field", "axis", "sign"), [("lean_deg", 1, -1), ("side_deg", 0, 1), ("nod_deg", 1, -1)])
def test_trunk_and_head_move_the_way_their_names_say(body, field, axis, sign):
    # The body faces -y with +x its left (yaw -90 is the rest pose's own facing).
    still = standing_pose(body, Posture())
    moved = standing_pose(body, Posture(**{field: 10.0}))
    head = "Head" if field == "nod_deg" else "Neck"
    tip = (
        (joint(body, moved, head) - joint(body, still, head))
        if field != "nod_deg"
        else (_head_top(body, moved) - _head_top(body, still))
    )
    assert sign * tip[axis] > 0.005


def _head_top(body, pose):
    heads = body.joint_positions(pose)
    return heads[JOINT_INDEX["Head"]] + 2 * (heads[JOINT_INDEX["Head"]] - heads[JOINT_INDEX["Neck1"]])


def test_bent_knees_and_a_weight_shift_keep_the_lower_foot_on_the_floor(body):
    rest = min(joint(body, body.rest_pose(), f)[2] for f in ("LeftFoot", "RightFoot"))
    pose = standing_pose(body, Posture(left_knee_deg=20.0, right_knee_deg=5.0, weight_shift_deg=4.0))
    assert min(joint(body, pose, f)[2] for f in ("LeftFoot", "RightFoot")) == pytest.approx(rest, abs=1e-9)
    assert pose[2] < body.rest_pose()[2] - 0.003  # the hips went down
    knee_forward = joint(body, pose, "LeftLeg")[1] - joint(body, pose, "LeftUpLeg")[1]
    assert knee_forward < -0.02  # the knee comes forward (-y)


def test_drifts_stay_within_their_documented_ranges():
    drifts = Drifts.draw(np.random.default_rng(3), NATURAL_SPREAD, (3.0, 15.0))
    values = drifts.natural(np.arange(20000) / 30.0, amplitude=0.8)
    for name, spread in NATURAL_SPREAD.items():
        bound = 0.8 * spread * RANGE_SIGMAS
        low = 0.0 if name in ONE_SIDED else -bound
        assert low - 1e-9 <= values[name].min() and values[name].max() <= bound + 1e-9, name
        assert np.ptp(values[name]) > 0.5 * bound, name  # and do vary


def test_the_capture_session_keeps_the_arm_in_its_ranges_and_moves_it_smoothly():
    ranges = ArmRanges((-60.0, 120.0), (0.0, 40.0), (0.0, 90.0))
    track = right_arm_track(ranges, 3000, 30.0, np.random.default_rng(0))
    spans = np.array([ranges.swing_deg, ranges.abduction_deg, ranges.elbow_deg])
    assert (track >= spans[:, 0] - 1e-9).all() and (track <= spans[:, 1] + 1e-9).all()
    assert np.abs(np.diff(track, axis=0)).max() < 25.0  # degrees per frame at 30 fps: a continuous session
    assert np.ptp(track[:, 0]) > 150 and np.ptp(track[:, 2]) > 70  # the arm goes everywhere


def test_the_clean_swing_is_unchanged_and_the_varied_one_keeps_24_swings_in_960_frames(body):
    clean = BodySwing()
    assert clean.swing_angle_deg(10) == 50.0 and clean.swing_angle_deg(30) == -30.0  # the triangle wave
    varied = BodySwing(variation=1.0, seed=4)
    plan = varied._variation
    assert plan.starts[SWINGS_PER_BLOCK] == pytest.approx(SWINGS_PER_BLOCK * varied.period_frames)
    assert np.all(np.abs(plan.forward / varied.forward_deg - 1) <= RANGE_SIGMAS * _SWING_SPREAD + 1e-9)
    angles = np.array([varied.swing_angle_deg(k) for k in range(965)])
    assert np.abs(np.diff(angles)).max() < 10.0  # continuous
    truth = np.array([body.right_arm_swing_deg(varied.params(body, k)) for k in range(975)])
    assert len(split_swings(truth)) == SWINGS_PER_BLOCK


def test_samples_from_a_capture_never_held_the_test_motion():
    """The experiment's own samples and subject: the typical test frame's nearest sample is beyond 5 degrees in
    some joint, and only chance coincidences (a few frames in a hundred) come within 5 degrees in every joint."""
    standard = build_body(shape=STANDARD_BODIES["male_h0.54_stout"])
    samples = CaptureSpec(seconds=330, seed=1000).poses(standard)
    samples = _joint_quaternions(samples[remove_near_duplicates(samples, 5.0)])
    subject = build_body(shape=MacroShape(gender=1.0, muscle=0.6, weight=0.6, height=0.52))
    for seed in (0, 1, 2):
        swing = BodySwing(variation=1.0, seed=seed)
        frames = _joint_quaternions(np.array([swing.params(subject, k) for k in range(0, 975, 5)]))
        cosines = np.abs(np.einsum("fjc,sjc->fsj", frames, samples)).min(axis=2)  # the worst joint of each pair
        nearest = np.degrees(2 * np.arccos(np.clip(cosines.max(axis=1), 0.0, 1.0)))
        assert np.median(nearest) > 7.0
        assert np.mean(nearest < 5.0) < 0.05


def _joint_quaternions(poses: np.ndarray) -> np.ndarray:
    rotations = Rotation.from_rotvec(poses[:, 3:].reshape(-1, 3))
    return rotations.as_quat().reshape(len(poses), -1, 4)
