import numpy as np
import pytest

from tracker.geometry.cameras import Camera, ViewsPoints, look_at, opengl_camera, projection_jacobian
from tracker.geometry.rigs import mono, orthogonal3


def front_camera(**kw) -> Camera:
    return look_at(
        "front",
        np.array([0.0, -2.0, 0.0]),
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        width=320,
        height=240,
        focal_px=100.0,
        **kw,
    )


def test_projection_of_a_hand_derived_point():
    # Camera at y = -2 looking at the origin, z up. World (0.5, 0, 0.25) is 0.5 right, 0.25 up, 2 ahead:
    # camera (x, y, z) = (0.5, -0.25, 2); u = 100 * 0.5 / 2 + 159.5 = 184.5, v = 100 * -0.25 / 2 + 119.5 = 107.0.
    uv, depth = front_camera().project(np.array([[0.5, 0.0, 0.25]]))
    np.testing.assert_allclose(uv, [[184.5, 107.0]])
    np.testing.assert_allclose(depth, [2.0])


def test_world_to_camera_is_eq5():
    camera = front_camera()
    p = np.array([[0.3, 0.7, -0.2]])
    expected = np.linalg.inv(camera.rotation) @ (p[0] - camera.position)  # (R^v)^-1 (p - T^v)
    np.testing.assert_allclose(camera.world_to_camera(p)[0], expected)


def test_points_behind_the_camera_get_nan_pixels():
    uv, depth = front_camera().project(np.array([[0.0, -3.0, 0.0], [0.0, 1.0, 0.0]]))
    assert np.isnan(uv[0]).all() and depth[0] < 0
    assert np.isfinite(uv[1]).all()


def test_look_at_gives_a_proper_rotation_with_opencv_axes():
    camera = front_camera()
    np.testing.assert_allclose(camera.rotation.T @ camera.rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(camera.rotation) == pytest.approx(1.0)
    x, y, z = camera.rotation.T  # camera axes in the world
    np.testing.assert_allclose(z, [0, 1, 0], atol=1e-12)  # looks along +y
    np.testing.assert_allclose(x, [1, 0, 0], atol=1e-12)  # right is +x
    np.testing.assert_allclose(y, [0, 0, -1], atol=1e-12)  # down is -z


def test_look_at_rejects_degenerate_input():
    with pytest.raises(ValueError, match="coincide"):
        look_at("c", np.zeros(3), np.zeros(3), np.array([0, 0, 1.0]), width=32, height=32, focal_px=10)
    with pytest.raises(ValueError, match="parallel"):
        look_at("c", np.zeros(3), np.array([0, 0, 1.0]), np.array([0, 0, 1.0]), width=32, height=32, focal_px=10)


def test_orthogonal3_views_look_along_the_paper_axes():
    rig = orthogonal3(
        target=(1.0, 0.0, 0.0), front_distance=2, left_distance=1, top_distance=3, focal_px=300, width=320, height=240
    )
    directions = {camera.name: camera.rotation[:, 2] for camera in rig}
    np.testing.assert_allclose(directions["front"], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(directions["left"], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(directions["top"], [0, 0, -1], atol=1e-12)
    for camera in rig:  # every view sees the target at its principal point
        uv, _ = camera.project(np.array([[1.0, 0.0, 0.0]]))
        np.testing.assert_allclose(uv[0], [camera.cx, camera.cy], atol=1e-9)
    assert [c.name for c in mono(position=(0, -2, 0), target=(0, 0, 0), focal_px=300, width=64, height=48)] == ["main"]


def _pyrender_pixel(gl, width, height, point):
    """Where pyrender's own projection matrix puts a world point: (column, row) with pixel centres at integers."""
    from tracker.render.gl import load_pyrender

    pyrender = load_pyrender()
    projection = pyrender.IntrinsicsCamera(fx=gl.fx, fy=gl.fy, cx=gl.cx, cy=gl.cy).get_projection_matrix(width, height)
    eye = np.linalg.inv(gl.pose) @ np.append(point, 1.0)
    clip = projection @ eye
    ndc = clip[:3] / clip[3]
    window_x = (ndc[0] + 1) / 2 * width  # OpenGL: pixel i covers [i, i + 1), its centre at i + 0.5
    window_y = (ndc[1] + 1) / 2 * height  # counted from the bottom; pyrender flips rows when reading back
    return np.array([window_x - 0.5, height - window_y - 0.5]), clip[3]


def test_opengl_conversion_agrees_with_pyrender_projection_and_the_wrong_one_does_not():
    camera = look_at(
        "c",
        np.array([0.3, -2.0, 0.4]),
        np.array([0.1, 0.2, -0.1]),
        np.array([0, 0, 1.0]),
        width=320,
        height=240,
        focal_px=280.0,
    )
    point = np.array([0.25, 0.1, 0.05])
    expected, _ = camera.project(point[None])
    gl = opengl_camera(camera)
    pixel, w = _pyrender_pixel(gl, 320, 240, point)
    assert w > 0  # in front of the camera
    np.testing.assert_allclose(pixel, expected[0], atol=1e-9)

    # Wrong reading 1: the OpenCV pose handed to OpenGL as is puts the point behind the camera.
    cv_pose = np.eye(4)
    cv_pose[:3, :3], cv_pose[:3, 3] = camera.rotation, camera.position
    _, w_wrong = _pyrender_pixel(type(gl)(gl.fx, gl.fy, gl.cx, gl.cy, cv_pose), 320, 240, point)
    assert w_wrong < 0
    # Wrong reading 2: forgetting OpenGL's half-pixel centres shifts the image by half a pixel.
    unshifted, _ = _pyrender_pixel(type(gl)(gl.fx, gl.fy, camera.cx, camera.cy, gl.pose), 320, 240, point)
    np.testing.assert_allclose(unshifted - expected[0], [-0.5, -0.5], atol=1e-9)


def test_points_of_several_views_get_each_cameras_own_pixels_and_jacobian_bit_for_bit(rig):
    rng = np.random.default_rng(4)
    counts = [7, 0, 12]  # a camera with no points among them
    points = [rng.normal([0.5, 0.0, -0.2], 0.3, size=(count, 3)) for count in counts]
    points[2][3] = rig[2].position - 0.5 * rig[2].rotation[:, 2]  # behind the camera: no pixel
    views = ViewsPoints.of(rig, counts)
    in_cameras = views.to_camera(np.concatenate(points))
    uv, depth = views.pixels(in_cameras)
    jacobian = views.projection_jacobian(in_cameras)
    for camera, rows, own in zip(rig, views.rows, points, strict=True):
        expected_uv, expected_depth = camera.project(own)
        np.testing.assert_array_equal(uv[rows], expected_uv)  # NaN where the camera's own is NaN
        np.testing.assert_array_equal(depth[rows], expected_depth)
        np.testing.assert_array_equal(jacobian[rows], projection_jacobian(camera, own))
    assert np.isnan(uv[views.rows[2]][3]).all()
