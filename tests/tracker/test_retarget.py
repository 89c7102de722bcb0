"""Retargeting other BVH skeletons onto the body's CMU rig (`tracker.motion.retarget`), on real DAZ-friendly clips."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.data import data_dir
from tracker.models.body_skeleton import BVH_TO_BODY, JOINT_INDEX
from tracker.motion.bvh import BvhError
from tracker.motion.mocap import ClipSelection, MocapScene, clip_poses, read_body_clip, read_clip
from tracker.motion.retarget import CMU, DAZ, skeleton_of, smallest_rotation

DAZ_DIR = data_dir() / "mocap_daz"


def _bone_angles_deg(body, clip, poses, times_s):
    """Per matched bone, the largest angle between the body's bone and the file's over the given frames."""
    frames = DAZ.motion_from + np.round(times_s / clip.frame_time).astype(int)
    theirs, ours = clip.joint_positions(frames), body.joint_positions(poses)
    worst = {}
    for joint, (end, (start_file, end_file)) in DAZ.rest_bones.items():
        a = ours[:, JOINT_INDEX[end]] - ours[:, JOINT_INDEX[joint]]
        b = (theirs[:, clip.index(end_file)] - theirs[:, clip.index(start_file)]) @ BVH_TO_BODY.T
        cosine = np.sum(a * b, axis=1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
        worst[joint] = float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))).max())
    return worst


@pytest.mark.parametrize("name", ["martial_04.bvh", "salsa_03.bvh"])
def test_a_daz_clips_limb_directions_survive_retargeting(body, name):
    clip = read_clip(DAZ_DIR / name)
    assert skeleton_of(clip.names) is DAZ
    poses = clip_poses(clip, body, ClipSelection(start_s=1.0, frames=10, fps=1.0))
    angles = _bone_angles_deg(body, clip, poses, 1.0 + np.arange(10))
    assert max(angles.values()) < 1.0, angles  # upper arms, forearms, collars, thighs, shins of both sides
    # The motion is real: the limbs moved well away from the T-pose over these frames.
    elbow, shoulder = JOINT_INDEX["RightForeArm"], JOINT_INDEX["RightArm"]
    posed, t_pose = body.joint_positions(poses), body.joint_positions(body.rest_pose())
    arm, rest = posed[:, elbow] - posed[:, shoulder], t_pose[elbow] - t_pose[shoulder]
    turned = np.degrees(np.arccos(arm @ rest / np.linalg.norm(arm, axis=1) / np.linalg.norm(rest)))
    assert turned.max() > 30.0


def test_a_daz_clips_first_frame_is_the_motions_not_the_conversions_ease_in(body):
    """The DAZ-friendly files ease from their T-pose into the motion over frames 1-8: read from frame 1, a clip's first
    step (root-aligned joints, 15 fps) was 85-180 mm, into a motion whose next steps were 0.2-15 mm."""
    for path in sorted(DAZ_DIR.glob("*.bvh")):
        poses = clip_poses(read_clip(path), body, ClipSelection(frames=4, fps=15.0))
        joints = body.joint_positions(poses)
        joints -= joints[:, :1]
        steps_mm = 1e3 * np.linalg.norm(np.diff(joints, axis=0), axis=2).mean(axis=1)
        assert steps_mm[0] <= 1.5 * steps_mm[1:].max() + 5.0, (path.name, steps_mm)  # the motion's own pace


def test_no_staged_clip_turns_the_hip_bones(body):
    """What the hybrid's fit holds by default (`tracker.hybrid.silhouette_fit`): CMU's skeleton gives LHipJoint and
    RHipJoint no channels of motion, and the retargeting of the DAZ clips leaves them at rest."""
    hips = np.r_[[3 + 3 * JOINT_INDEX[name] + np.arange(3) for name in ("LHipJoint", "RHipJoint")]].ravel()
    for path in [*sorted(DAZ_DIR.glob("*.bvh")), *sorted((data_dir() / "mocap").glob("*.bvh"))]:
        poses = clip_poses(read_clip(path), body, ClipSelection(fps=5.0))
        assert np.abs(poses[:, hips]).max() < 1e-9, path.name


def test_a_true_frame_rate_stretches_the_clip_in_time(body):
    header = read_clip(DAZ_DIR / "salsa_01.bvh")
    true = read_clip(DAZ_DIR / "salsa_01.bvh", true_fps=60.0)
    assert header.frame_time == pytest.approx(1 / 120, rel=1e-3) and true.frame_time == pytest.approx(1 / 60)
    at_120 = MocapScene(str(DAZ_DIR / "salsa_01.bvh"), fps=10.0).poses(body)
    at_60 = MocapScene(str(DAZ_DIR / "salsa_01.bvh"), fps=10.0, true_fps=60.0).poses(body)
    assert len(at_60) == pytest.approx(2 * len(at_120), abs=2)
    np.testing.assert_allclose(at_60[10, 3:], at_120[5, 3:], atol=1e-6)  # 1 s at 60 fps is 0.5 s at 120


def test_the_cmu_table_maps_every_joint_to_itself():
    assert all(CMU.sources[name] == name for name in JOINT_INDEX) and not CMU.rest_bones


def test_an_unknown_skeleton_gives_one_line_naming_the_known_ones(tmp_path):
    path = tmp_path / "robot.bvh"
    path.write_text(
        "HIERARCHY\nROOT base\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
        "Xrotation Yrotation\n JOINT arm\n {\n  OFFSET 1 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "  End Site\n  {\n   OFFSET 1 0 0\n  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n"
        "0 0 0 0 0 0 0 0 0\n0 0 0 0 0 0 0 0 0\n"
    )
    with pytest.raises(
        ValueError,
        match=r"^scene.path=.*robot.bvh: no retargeting table fits its skeleton "
        r"\(2 joints rooted at 'base'\): the nearest, daz, needs joints abdomen, "
        r".*; known skeletons: cmu, daz",
    ) as caught:
        read_body_clip(str(path), "scene.path")
    assert "\n" not in str(caught.value)
    with pytest.raises(BvhError, match="no retargeting table"):
        clip_poses(read_clip(path), None)


def test_the_smallest_rotation_against_scipys_alignment():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=3), rng.normal(size=3)
        rotation = smallest_rotation(a, b)
        np.testing.assert_allclose(rotation @ a / np.linalg.norm(a), b / np.linalg.norm(b), atol=1e-12)
        theirs, _ = Rotation.align_vectors([b], [a])  # the smallest rotation for a single pair
        np.testing.assert_allclose(rotation, theirs.as_matrix(), atol=1e-9)
