"""Depth flips: the sample whose pose is a sample's mirror image through the plane facing the camera."""

import numpy as np
import pytest

from tracker.geometry.cameras import look_at
from tracker.models.body_skeleton import turned_about_vertical
from tracker.motion.posture import arms_pose
from tracker.tbf.flips import depth_flips, line_of_sight, mirrored_through
from tracker.tbf.pose_sets import mirrored


def _camera(position):
    return look_at(
        "main",
        np.array(position),
        np.array([0.0, 0.0, 0.9]),
        np.array([0.0, 0.0, 1.0]),
        width=320,
        height=240,
        focal_px=420.0,
    )


@pytest.mark.parametrize("position", [(0.0, -4.5, 0.9), (3.182, -3.182, 0.9), (-2.0, 4.0, 1.5)])
def test_each_pose_and_its_mirror_image_through_the_plane_facing_the_camera_are_each_others_flips(body, position):
    """The flips, found from joint positions mirrored through the plane across the line of sight, are the poses
    made the other way: each pose mirrored left for right through x = 0 (`pose_sets.mirrored`, its rotations) and
    turned by twice the line of sight's bearing (a mirror through a plane of normal at bearing b is the mirror
    through x = 0 turned by 2b), posed by the body's skeleton."""
    camera = _camera(position)
    poses = np.array(
        [
            arms_pose(body, (swing, 10.0, elbow), (-20.0, 25.0, 30.0), yaw_deg=yaw)
            for swing, elbow, yaw in (
                (60.0, 0.0, -90.0),
                (-30.0, 70.0, -60.0),
                (120.0, 20.0, 10.0),
                (10.0, 90.0, 170.0),
            )
        ]
    )
    bearing = np.arctan2(*line_of_sight(camera, np.zeros(3))[1::-1])
    made = turned_about_vertical(mirrored(poses), 2.0 * bearing)
    joints = body.joint_positions(np.concatenate([poses, made]))
    flips = depth_flips(joints, line_of_sight(camera, np.zeros(3)))
    count = len(poses)
    np.testing.assert_array_equal(flips, np.r_[np.arange(count, 2 * count), np.arange(count)])
    # The joints mirrored are the other poses' to within the rest skeleton's own asymmetry: its toes are 2 cm, its
    # fingers 6 mm, from where their twins' mirror images are (at rest, every other joint to the micrometre).
    aligned = joints - joints[:, :1]
    difference = np.linalg.norm(
        mirrored_through(joints[:count], line_of_sight(camera, np.zeros(3))) - aligned[count:], axis=2
    )
    assert difference.max() < 0.021 and np.median(difference) < 1e-6


def test_a_mirror_image_mirrored_again_is_the_pose_and_the_line_of_sight_is_level():
    rng = np.random.default_rng(3)
    joints = rng.normal(size=(5, 31, 3))
    normal = line_of_sight(_camera((1.0, -3.0, 2.5)), np.array([0.2, 0.1, 0.0]))
    assert normal[2] == 0.0 and np.linalg.norm(normal) == pytest.approx(1.0)
    twice = mirrored_through(mirrored_through(joints, normal), normal)
    np.testing.assert_allclose(twice, joints - joints[:, :1], atol=1e-12)
    with pytest.raises(ValueError, match="line of sight"):
        line_of_sight(_camera((0.0, -4.5, 0.9)), np.array([0.0, -4.5, 0.0]))


def test_a_flip_share_from_several_views_stops_before_any_sample_is_made(body):
    from tracker.registry import COSTS
    from tracker.tbf.filter import FilterSettings
    from tracker.tbf.motion import OccludedWiderWalk
    from tracker.tbf.settings import TbfSettings
    from tracker.tbf.tracker import TbfTracker

    tracker = TbfTracker(
        TbfSettings(filter=FilterSettings(flip_share=0.05)), COSTS.defaults("nwxor"), OccludedWiderWalk()
    )
    rig = [_camera((0.0, -4.5, 0.9)), _camera((4.5, 0.0, 0.9))]
    with pytest.raises(ValueError, match=r"^tracker\.filter\.flip_share=0\.05: 2 views tell a pose from its depth"):
        tracker.start(body, rig, np.zeros(96), np.random.default_rng(0))
    assert tracker.samples is None
