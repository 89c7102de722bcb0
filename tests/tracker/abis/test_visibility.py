import numpy as np

from tests.tracker.test_render import sphere_mesh
from tracker.abis.visibility import visible_mask, visible_samples
from tracker.geometry.cameras import look_at
from tracker.models.dsq import sample_grid
from tracker.render.offscreen import DepthLabels
from tracker.tol import VISIBILITY_DEPTH_M

CAMERA = look_at(
    "c", np.array([0.0, -3.0, 0.0]), np.zeros(3), np.array([0, 0, 1.0]), width=320, height=240, focal_px=400.0
)


def sphere_samples(center, radius, grid):
    directions = np.stack(
        [np.cos(grid.eta) * np.cos(grid.omega), np.cos(grid.eta) * np.sin(grid.omega), np.sin(grid.eta)], axis=1
    )
    return center + radius * directions, directions


def ray_hits_sphere_before(origin, targets, center, radius):
    """For rays origin -> target: does the sphere (center, radius) block them before the target? (independent)"""
    d = targets - origin
    length = np.linalg.norm(d, axis=1)
    d = d / length[:, None]
    oc = origin - center
    b = d @ oc
    disc = b**2 - (oc @ oc - radius**2)
    t_near = -b - np.sqrt(np.maximum(disc, 0))
    return (disc > 0) & (t_near > 0) & (t_near < length - 1e-9)


def test_samples_behind_another_part_or_on_the_far_side_are_invisible(renderer):
    grid = sample_grid(24, 48)
    front_center, back_center = np.array([0.05, -0.6, 0.02]), np.array([0.0, 0.3, 0.0])
    front_radius, back_radius = 0.12, 0.3
    back_points, back_normals = sphere_samples(back_center, back_radius, grid)
    front_points, front_normals = sphere_samples(front_center, front_radius, grid)
    meshes = [
        sphere_mesh(back_center, back_radius, label=1, resolution=(80, 96)),
        sphere_mesh(front_center, front_radius, label=2, resolution=(80, 96)),
    ]
    zbuffer = renderer.render_depth_labels([CAMERA], meshes)["c"]
    seen = visible_samples(CAMERA, zbuffer, [back_points, front_points])

    for part, (points, normals) in enumerate([(back_points, back_normals), (front_points, front_normals)]):
        to_camera = CAMERA.position - points
        facing = np.einsum("ij,ij->i", normals, to_camera) / np.linalg.norm(to_camera, axis=1)
        blocked = ray_hits_sphere_before(CAMERA.position, points, front_center, front_radius) if part == 0 else 0
        expected = (facing > 0) & ~np.asarray(blocked, bool)
        clear = np.abs(facing) > 0.15  # away from the silhouette, where one pixel decides
        if part == 0:  # and away from the edge of the front sphere's shadow on the back one
            grazing = ray_hits_sphere_before(CAMERA.position, points, front_center, front_radius * 1.1)
            grazing ^= ray_hits_sphere_before(CAMERA.position, points, front_center, front_radius * 0.9)
            clear &= ~grazing
        got = np.zeros(len(points), bool)
        got[seen.sample[seen.part == part]] = True
        assert (got[clear] == expected[clear]).mean() >= 0.99, part
        if part == 0:
            assert (expected & ~np.asarray(blocked, bool)).any() and np.asarray(blocked, bool)[clear].sum() > 10
    # Projections are reported for the visible samples, where the camera puts them.
    uv, _ = CAMERA.project(np.concatenate([back_points, front_points])[seen.sample + (seen.part * len(back_points))])
    np.testing.assert_allclose(seen.uv, uv)


def test_arm_samples_visible_per_view(arm, motion, rig, renderer):
    params = motion.params(arm, 0)  # forearm straight: hidden behind the upper arm in the left view
    zbuffers = renderer.render_depth_labels(rig, arm.surface_meshes(params))
    samples = arm.sample_points(params)
    counts = {}
    for camera in rig:
        zbuffer = zbuffers[camera.name]
        seen = visible_samples(camera, zbuffer, samples)
        counts[camera.name] = np.bincount(seen.part, minlength=3)
        for part in range(3):  # a sample is seen only where its part shows, at its own projection
            on_part = zbuffer.labels[np.rint(seen.uv[:, 1]).astype(int), np.rint(seen.uv[:, 0]).astype(int)]
            assert (on_part[seen.part == part] == part + 1).all()
            if np.count_nonzero(zbuffer.labels == part + 1) == 0:
                assert counts[camera.name][part] == 0
    assert counts["left"][1] == 0  # the forearm is hidden behind the upper arm
    assert counts["front"][1] > 50 and counts["top"][1] > 50
    n = len(arm.sample_grid.ids)
    assert all(count.max() < 0.7 * n for count in counts.values())  # never more than the near side


def test_visible_mask_is_the_rule_applied_point_by_point(arm, motion, rig, renderer):
    """`visible_mask` against its rule written out for each point: the pixel rounded (half to even) inside the
    image, showing the point's own part, the z-buffer's depth there at most `VISIBILITY_DEPTH_M` in front of it.
    The arm's samples and points off them, off the image and behind the camera."""
    params = motion.params(arm, 3)
    zbuffers = renderer.render_depth_labels(rig, arm.zbuffer_meshes(params))
    samples = arm.sample_points(params)
    points = np.concatenate(samples)
    parts = np.repeat(np.arange(len(samples)), [len(s) for s in samples])
    rng = np.random.default_rng(3)
    points = np.concatenate(
        [points, points[::7] + rng.normal(0, 0.05, (len(points[::7]), 3)), rng.normal(0, 3, (60, 3))]
    )
    parts = np.concatenate([parts, parts[::7], rng.integers(0, 3, 60)])
    for camera in rig:
        zbuffer = zbuffers[camera.name]
        probe = points.copy()
        probe[-5:] = camera.position + camera.rotation[:, 2] * -1.0  # behind the camera
        seen, uv = visible_mask(camera, zbuffer, parts, probe)
        pixels, depth = camera.project(probe)
        np.testing.assert_array_equal(uv, pixels)
        expected = np.zeros(len(probe), bool)
        for k, ((u, v), z) in enumerate(zip(pixels, depth, strict=True)):
            column, row = np.rint(u), np.rint(v)
            if not (0 <= column <= camera.width - 1 and 0 <= row <= camera.height - 1):
                continue
            row, column = int(row), int(column)
            own = zbuffer.labels[row, column] == parts[k] + 1
            expected[k] = own and z <= zbuffer.depth[row, column] + VISIBILITY_DEPTH_M
        np.testing.assert_array_equal(seen, expected)
        assert 0 < seen.sum() < len(probe)


def test_visible_mask_keeps_the_images_edge_pixels_and_drops_those_beyond():
    """Points whose pixel rounds onto the image's first or last row or column are seen (a z-buffer of part 0
    everywhere, 10 m deep); those rounding beyond are not."""
    zbuffer = DepthLabels(
        np.ones((240, 320), np.uint8),
        np.zeros((240, 320), np.float32),
        lambda raw: np.full(raw.shape, 10.0, np.float32),
    )
    pixels = np.array([[0, 0], [319, 239], [-0.4, 10], [-0.6, 10], [319.4, 5], [319.6, 5], [10, -0.6], [10, 239.4]])
    depth = 2.0
    rays = np.column_stack([(pixels[:, 0] - CAMERA.cx) / CAMERA.fx, (pixels[:, 1] - CAMERA.cy) / CAMERA.fy, np.ones(8)])
    points = CAMERA.position + (depth * rays) @ CAMERA.rotation.T
    seen, _ = visible_mask(CAMERA, zbuffer, np.zeros(8, int), points)
    np.testing.assert_array_equal(seen, [True, True, True, False, True, False, False, True])
