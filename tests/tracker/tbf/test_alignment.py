"""Moving the observed silhouette onto the samples' feet, and the estimate's root back by as much; placing the
person on the floor."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.geometry.cameras import look_at, wholly_in_view
from tracker.geometry.rigs import View, cameras
from tracker.models.body_skeleton import JOINT_INDEX, turned_about_vertical
from tracker.motion.posture import arms_pose
from tracker.tbf.alignment import (
    GroundPlacement,
    ViewsPlacement,
    centroid_rays,
    feet_anchor,
    ground_point,
    nearest_to_rays,
    sample_anchors,
    shifted,
    silhouette_centroid,
    spot_pixels,
    world_offset,
)
from tracker.tbf.pose_sets import grounded, mirrored
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.samples import SampleViews


def test_the_centroid_is_the_mean_of_the_silhouettes_pixels_to_the_bit():
    rng = np.random.default_rng(3)
    for _ in range(20):
        mask = rng.random((60, 90)) < rng.uniform(0.01, 0.6)
        rows, columns = np.nonzero(mask)
        assert silhouette_centroid(mask) == (columns.mean(), rows.mean())
    assert silhouette_centroid(np.zeros((6, 8), bool)) is None


def test_the_feet_are_the_middle_of_the_silhouettes_bottom_rows():
    mask = np.zeros((100, 80), bool)
    mask[10:90, 30:40] = True  # a body
    mask[85:90, 40:56] = True  # a foot forward
    mask[60:70, 40:70] = True  # an arm: not the feet
    u, v = feet_anchor(mask)
    assert v == 89.0
    assert u == np.median(np.arange(30, 56))  # the bottom 6 % (5 rows) span columns 30-55
    assert feet_anchor(np.zeros((4, 4), bool)) is None


@pytest.mark.parametrize(("du", "dv"), [(3, -2), (-5, 4), (0, 0), (120, 0)])
def test_a_shift_moves_every_pixel_and_loses_what_leaves(du, dv):
    rng = np.random.default_rng(0)
    mask = rng.random((30, 40)) < 0.3
    moved = shifted(mask, du, dv)
    expected = np.zeros_like(mask)
    for v, u in zip(*np.nonzero(mask), strict=True):
        if 0 <= v + dv < 30 and 0 <= u + du < 40:
            expected[v + dv, u + du] = True
    assert np.array_equal(moved, expected)


def test_the_world_offset_moves_the_projection_by_the_pixels_asked():
    camera = look_at(
        "main",
        np.array([4.0, 0.0, 0.9]),
        np.array([0.0, 0.0, 0.9]),
        np.array([0.0, 0.0, 1.0]),
        width=320,
        height=240,
        focal_px=480.0,
    )
    point = np.array([0.1, -0.2, 0.95])
    offset = world_offset(camera, point, 7.0, -3.0)
    before, _ = camera.project(point[None])
    after, _ = camera.project((point + offset)[None])
    np.testing.assert_allclose(after[0] - before[0], [7.0, -3.0], atol=1e-9)
    depths = camera.world_to_camera(np.array([point, point + offset]))[:, 2]
    assert depths[1] == pytest.approx(depths[0])  # parallel to the image plane


def test_a_ground_point_projects_back_onto_its_pixel_and_lies_on_the_floor():
    camera = _front_camera()
    for u, v in [(160.0, 200.0), (20.5, 239.0), (300.0, 130.0)]:
        point = ground_point(camera, u, v)
        assert point[2] == pytest.approx(0.0, abs=1e-12)
        np.testing.assert_allclose(camera.project(point[None])[0][0], [u, v], atol=1e-9)
    assert ground_point(camera, 160.0, 100.0) is None  # above the horizon (v < cy)


def test_ground_placement_finds_where_a_walking_person_stands(body, tmp_path):
    camera = _front_camera()
    postures = np.array(
        [
            arms_pose(body, (swing, 10.0, elbow), (0.0, 8.0, 0.0), yaw_deg=-90.0)
            for swing in (-30.0, 0.0, 40.0, 90.0)
            for elbow in (0.0, 60.0)
        ]
    )
    samples = load_or_build(body, camera, postures, tmp_path / "samples", progress=False)
    for index, step in ((2, (0.4, -0.7)), (7, (-0.6, 1.0)), (4, (0.0, 0.0))):
        # He walked nearer the camera and sideways, or away, and turned to it as much as he went off its axis: the
        # camera sees him as it sees the sample.
        person = postures[index].copy()
        bearing = np.arctan2(step[1] + 4.5, step[0]) - np.pi / 2
        person[3:6] = (Rotation.from_euler("z", bearing) * Rotation.from_rotvec(person[3:6])).as_rotvec()
        person[:2] += step
        seen = _silhouette(body, camera, person, tmp_path / f"seen{index}")
        placement = GroundPlacement(camera, samples, reference=index)  # the last estimate: the same posture
        placed = placement.place(seen)
        estimate = placement.pose(index, placed)
        # On the floor within what one and a half pixel rows of the feet span there (a row: depth^2 / (camera
        # height * focal), 3.6 cm at 3.8 m, 8 cm at 5.5 m); the height is the sample's.
        depth = 4.5 + step[1]
        np.testing.assert_allclose(estimate[:3], person[:3], atol=1.5 * depth**2 / (0.9 * 420.0))
        np.testing.assert_allclose(estimate[3:6], person[3:6], atol=2e-3)  # turned as he is (the feet's bearing)
        np.testing.assert_array_equal(estimate[6:], postures[index][6:])
        cut = shifted(seen, 0, int(240 - feet_anchor(seen)[1]))  # the feet below the image's bottom edge
        assert placement.place(cut) is None
        sample = np.zeros_like(seen)
        u0, v0, u1, v1 = samples.silhouettes((320, 240)).window
        sample[v0:v1, u0:u1] = samples.silhouettes((320, 240)).mask(index)
        iou = np.count_nonzero(placed.silhouette & sample) / np.count_nonzero(placed.silhouette | sample)
        assert iou > 0.85, iou  # scaled and moved onto the sample's spot, the silhouettes agree


def test_a_samples_anchor_is_its_silhouettes_centroid_column_over_its_lowest_row(body, tmp_path):
    camera = _front_camera()
    postures = np.array(
        [
            arms_pose(body, (swing, 10.0, 30.0), (-swing, 20.0, 0.0), yaw_deg=yaw)
            for swing in (-40.0, 30.0, 150.0)
            for yaw in (-90.0, 0.0)
        ]
    )
    samples = load_or_build(body, camera, postures, tmp_path / "samples", progress=False)
    stack = samples.silhouettes((320, 240))
    u0, v0 = stack.window[:2]
    for index, (u, v) in enumerate(sample_anchors(samples)):
        rows, columns = np.nonzero(stack.mask(index))
        assert u == pytest.approx(columns.mean() + u0, abs=1e-9) and v == rows.max() + v0


def test_one_view_scores_each_sample_from_its_own_anchor_whichever_it_was_placed_on(body, tmp_path):
    """A stride towards the camera and its depth flip (`tracker.tbf.flips`: facing away, the other leg forward)
    cast one outline but for perspective: the nearer foot, lowest in the image, stands 19 pixels from where the
    flip's nearer foot stands. Placed on a sample's feet, the observed stride looks like that sample, so the run's
    side confirms itself; scored each from its own anchor (the silhouette's centroid column over its lowest row),
    the stride wins on either sample's."""
    camera = _front_camera()
    stride = arms_pose(body, (10.0, 8.0, 20.0), (-10.0, 8.0, 20.0), yaw_deg=-90.0)
    stride[3 + 3 * JOINT_INDEX["LeftUpLeg"]], stride[3 + 3 * JOINT_INDEX["RightUpLeg"]] = 0.4, -0.4
    postures = grounded(body, np.array([stride, turned_about_vertical(mirrored(stride[None]), np.pi)[0]]))
    samples = load_or_build(body, camera, postures, tmp_path / "samples", progress=False)
    anchors = sample_anchors(samples)
    stack = samples.silhouettes((320, 240))
    for step in (-0.6, 0.7):  # he walked nearer the camera, or away
        person = postures[0].copy()
        person[1] += step
        seen = _silhouette(body, camera, person, tmp_path / f"seen{step}")
        for reference in (0, 1):
            own = GroundPlacement(camera, samples, reference, anchors).place(seen).silhouette
            at_feet = GroundPlacement(camera, samples, reference).place(seen).silhouette
            differing_own, differing_at_feet = [], []
            for index in (0, 1):
                sample = np.zeros_like(seen)
                u0, v0, u1, v1 = stack.window
                sample[v0:v1, u0:u1] = stack.mask(index)
                differing_at_feet.append(np.count_nonzero(at_feet ^ sample))
                du, dv = np.rint(anchors[reference] - anchors[index]).astype(int)
                differing_own.append(np.count_nonzero(own ^ shifted(sample, du, dv)))
            assert differing_own[0] < differing_own[1], (step, reference, differing_own)
            # placed on the sample's feet, that sample looks nearer: the flip, when it is the reference
            assert (differing_at_feet[0] < differing_at_feet[1]) == (reference == 0), (step, reference)


def _front_camera():
    return look_at(
        "main",
        np.array([0.0, -4.5, 0.9]),
        np.array([0.0, 0.0, 0.9]),
        np.array([0.0, 0.0, 1.0]),
        width=320,
        height=240,
        focal_px=420.0,
    )


def _silhouette(body, camera, pose, folder):
    """The body's silhouette at ``pose`` in the whole image, rendered as the samples are."""
    rendered = load_or_build(body, camera, pose[None], folder, progress=False)
    stack = rendered.silhouettes((camera.width, camera.height))
    full = np.zeros((camera.height, camera.width), bool)
    u0, v0, u1, v1 = stack.window
    full[v0:v1, u0:u1] = stack.mask(0)
    return full


def test_rays_crossing_at_a_point_give_that_point():
    point = np.array([0.3, -0.2, 1.1])
    origins = np.array([[0.0, -4.5, 0.9], [4.5, 0.0, 0.9], [3.2, -3.2, 2.0]])
    np.testing.assert_allclose(nearest_to_rays(origins, point - origins), point, atol=1e-12)
    # two skew rays: the midpoint of their common perpendicular
    np.testing.assert_allclose(
        nearest_to_rays(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])),
        [0.0, 0.0, 0.5],
    )


def test_several_views_place_a_walking_person_without_a_reference(body, tmp_path):
    """Three calibrated views: the offset across the floor comes from where the silhouettes' centroid rays cross,
    against where the reference sample's (the last estimate's: here the same posture) cross."""
    rig = cameras(
        views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9)), View("oblique", (3.182, -3.182, 0.9)))
    )
    postures = np.array(
        [
            arms_pose(body, (swing, 10.0, elbow), (0.0, 8.0, 0.0), yaw_deg=-90.0)
            for swing in (-30.0, 0.0, 40.0, 90.0)
            for elbow in (0.0, 60.0)
        ]
    )
    samples = SampleViews(
        tuple(load_or_build(body, camera, postures, tmp_path / "samples", progress=False) for camera in rig)
    )
    for index, step in ((2, (0.4, -0.7)), (7, (-0.6, 1.0)), (4, (0.0, 0.0))):
        placement = ViewsPlacement(rig, samples, reference=index)
        person = postures[index].copy()
        person[:2] += step
        seen = [_silhouette(body, camera, person, tmp_path / f"seen{index}{camera.name}") for camera in rig]
        placed, offset = placement.place(seen)
        np.testing.assert_allclose(offset[:2], step, atol=0.03)  # within 3 cm across the floor
        assert offset[2] == 0.0
        estimate = placement.pose(index, offset)
        np.testing.assert_allclose(estimate[:2], person[:2], atol=0.03)
        np.testing.assert_array_equal(estimate[2:], postures[index][2:])
        for silhouette, stack in zip(placed, samples.silhouettes((320, 240)), strict=True):
            sample = np.zeros_like(silhouette)
            u0, v0, u1, v1 = stack.window
            sample[v0:v1, u0:u1] = stack.mask(index)
            iou = np.count_nonzero(silhouette & sample) / np.count_nonzero(silhouette | sample)
            assert iou > 0.8, iou  # measured 0.81-1.0: off the samples' spot a view sees him from another side
    # Each sample's spot, from all of them at once, is where the rays through its own silhouettes' centroids cross,
    # brought to one height: the crossings' median.
    crossings = np.array([_crossing(rig, samples, index) for index in range(len(postures))])
    np.testing.assert_allclose(placement.spots[:, :2], crossings[:, :2], atol=1e-12)
    np.testing.assert_array_equal(placement.spots[:, 2], np.median(crossings[:, 2]))
    # Placed on another posture's spot, the estimate is still moved until its own spot is his.
    person = postures[6].copy()
    person[:2] += (0.3, 0.5)
    seen = [_silhouette(body, camera, person, tmp_path / f"other{camera.name}") for camera in rig]
    placement = ViewsPlacement(rig, samples, reference=1)
    assert np.linalg.norm(placement.spot(1)[:2] - placement.spot(6)[:2]) > 0.03  # the postures' spots differ
    _, offset = placement.place(seen)
    np.testing.assert_allclose(placement.pose(6, offset)[:2], person[:2], atol=0.03)
    assert placement.reference == 6


def test_a_sample_is_scored_where_it_stands_however_high_its_centroid(body, tmp_path):
    """Arms raised over the head lift the silhouettes' centroids, and with them where their rays cross; the person
    stands on the floor all the same. Placed on the spot of a posture with its arms down, his silhouettes meet the
    raised posture's where the filter moves them (the reference's spot pixel less its own, `TreeFilter.shifts`): moved
    across the image, not down it by the difference in the centroids' heights (8 pixels in the front view at
    320x240, where the silhouettes then overlapped by 0.72 of their union; 0.88-0.95 in the three views moved
    across)."""
    rig = cameras(
        views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9)), View("oblique", (3.182, -3.182, 0.9)))
    )
    down, raised = (arms_pose(body, (swing, 10.0, 0.0), (swing, 10.0, 0.0), yaw_deg=-90.0) for swing in (0.0, 170.0))
    samples = SampleViews(
        tuple(
            load_or_build(body, camera, np.array([down, raised]), tmp_path / "samples", progress=False)
            for camera in rig
        )
    )
    assert _crossing(rig, samples, 1)[2] - _crossing(rig, samples, 0)[2] > 0.08  # the raised arms' cross higher
    placement = ViewsPlacement(rig, samples, reference=0)
    person = raised.copy()
    person[:2] += (0.3, -0.4)
    seen = [_silhouette(body, camera, person, tmp_path / f"seen{camera.name}") for camera in rig]
    placed, _ = placement.place(seen)
    pixels = spot_pixels(rig, placement.spots, (320, 240))  # (samples, views, 2)
    shifts = np.rint(pixels[0] - pixels[1])  # the reference's less the raised posture's, per view
    for silhouette, stack, (du, dv) in zip(placed, samples.silhouettes((320, 240)), shifts.astype(int), strict=True):
        sample = np.zeros_like(silhouette)
        u0, v0, u1, v1 = stack.window
        sample[v0:v1, u0:u1] = stack.mask(1)
        moved = shifted(sample, du, dv)
        iou = np.count_nonzero(silhouette & moved) / np.count_nonzero(silhouette | moved)
        assert abs(dv) <= 1 and iou > 0.85, (du, dv, iou)


def test_views_that_see_the_person_cut_by_their_border_do_not_place_him(body, tmp_path):
    """A person stepped aside out of the front view's image in part: his spot is where the two views that see him
    whole cross; every view's rays (the front's centroid pulled into its image) put him further off. Out of the
    front view altogether, the other two place him and the front view gives the filter nothing; out of all but one,
    the point of its ray nearest his last spot."""
    rig = cameras(
        views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9)), View("oblique", (3.182, -3.182, 0.9)))
    )
    postures = np.array([arms_pose(body, (swing, 10.0, 0.0), (0.0, 8.0, 0.0), yaw_deg=-90.0) for swing in (0, 60)])
    samples = SampleViews(
        tuple(load_or_build(body, camera, postures, tmp_path / "samples", progress=False) for camera in rig)
    )
    for step, lost, whole_views in (((-1.75, 0.3), (), 2), ((-2.4, 0.5), ("front",), 2)):
        person = postures[1].copy()
        person[:2] += step
        seen = [
            np.zeros((240, 320), bool)
            if camera.name in lost
            else _silhouette(body, camera, person, tmp_path / f"seen{step}{camera.name}")
            for camera in rig
        ]
        assert sum(wholly_in_view(view) for view in seen) == whole_views
        placement = ViewsPlacement(rig, samples, reference=1)
        placement.last_spot = placement.spot(1) + [*step, 0.0] + [0.05, -0.05, 0.0]  # a frame ago, 7 cm away
        placed, offset = placement.place(seen)
        np.testing.assert_allclose(offset[:2], step, atol=0.04)
        assert [view is None for view in placed] == [camera.name in lost for camera in rig]  # the filter leaves it out
        if lost:
            # With the oblique view lost too, the side view alone: on its ray, as near his last spot as it goes.
            _, offset = placement.place([seen[0], seen[1], np.zeros_like(seen[2])])
            spot = placement.spot(1) + offset
            (origin,), (direction,) = (
                part[1:2] for part in centroid_rays(rig, np.array([[0, 0], _centroid(seen[1]), [0, 0]]))
            )
            off_ray = spot - origin - direction * ((spot - origin) @ direction) / (direction @ direction)
            assert np.linalg.norm(off_ray[:2]) < 0.01 and np.linalg.norm(offset[:2] - step) < 0.08, (off_ray, offset)
            continue
        centroids = [_centroid(view) for view in seen]
        every = nearest_to_rays(*centroid_rays(rig, np.array(centroids))) - placement.spot(1)
        assert np.linalg.norm(every[:2] - step) > 2 * np.linalg.norm(offset[:2] - step), (every, offset)


def _crossing(rig, samples, index):
    """Where the rays through sample ``index``'s silhouettes' centroids cross, from its masks (at its own height)."""
    centroids = []
    for stack in samples.silhouettes((320, 240)):
        v, u = np.nonzero(stack.mask(index))
        centroids.append([u.mean() + stack.window[0], v.mean() + stack.window[1]])
    return nearest_to_rays(*centroid_rays(rig, np.array(centroids)))


def _centroid(silhouette):
    """``(u, v)`` the silhouette's centroid, pixels."""
    return np.argwhere(silhouette)[:, ::-1].mean(axis=0)
