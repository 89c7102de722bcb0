import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.geometry.rotations import (
    euler_to_matrix,
    fit_rigid,
    invert_rigid,
    matrix_to_euler,
    mean_rotation_vectors,
    rigid_transform,
    rotation_x,
    rotation_y,
    rotation_z,
    transform_points,
)


def test_euler_matches_scipy_extrinsic_xyz():
    rng = np.random.default_rng(0)
    for r in rng.uniform(-np.pi, np.pi, size=(20, 3)):
        np.testing.assert_allclose(euler_to_matrix(r), Rotation.from_euler("xyz", r).as_matrix(), atol=1e-12)


def test_a_rotation_asked_again_is_a_fresh_matrix_of_the_same_bits():
    r = np.array([0.3, -0.7, 1.1])
    first = euler_to_matrix(r)
    first[0, 0] = 99.0  # the caller's own array: the next call does not see it
    again = euler_to_matrix(r.tolist())
    assert again[0, 0] != 99.0
    np.testing.assert_array_equal(again, rotation_z(1.1) @ rotation_y(-0.7) @ rotation_x(0.3))


def test_wrong_reading_of_the_convention_differs():
    r = np.array([0.3, -0.7, 1.1])
    intrinsic = Rotation.from_euler("XYZ", r).as_matrix()  # Rx @ Ry @ Rz: the other common reading
    assert np.abs(euler_to_matrix(r) - intrinsic).max() > 0.1


def test_rotation_about_y_turns_z_onto_x():
    # The arm relies on this: r2 = +90 deg maps a part's axis (local z) onto the parent's +x.
    np.testing.assert_allclose(euler_to_matrix([0.0, np.pi / 2, 0.0]) @ [0, 0, 1], [1, 0, 0], atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_matrix_to_euler_round_trip(seed):
    rng = np.random.default_rng(seed)
    r = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-1.5, 1.5), rng.uniform(-np.pi, np.pi)])
    np.testing.assert_allclose(matrix_to_euler(euler_to_matrix(r)), r, atol=1e-10)


def test_matrix_to_euler_at_gimbal_lock_reproduces_the_matrix():
    rotation = euler_to_matrix([0.4, np.pi / 2, -0.2])
    np.testing.assert_allclose(euler_to_matrix(matrix_to_euler(rotation)), rotation, atol=1e-9)


def test_rigid_inverse_and_point_transform():
    transform = rigid_transform(euler_to_matrix([0.1, 0.2, 0.3]), np.array([1.0, -2.0, 0.5]))
    points = np.random.default_rng(1).normal(size=(10, 3))
    np.testing.assert_allclose(transform_points(invert_rigid(transform), transform_points(transform, points)), points)
    np.testing.assert_allclose(invert_rigid(transform) @ transform, np.eye(4), atol=1e-12)


def test_rotation_derivatives_match_central_differences():
    from tracker.geometry.rotations import euler_to_matrix_derivatives

    r = np.array([0.4, -1.1, 2.3])
    analytic = euler_to_matrix_derivatives(r)
    for i in range(3):
        step = np.zeros(3)
        step[i] = 1e-6
        numeric = (euler_to_matrix(r + step) - euler_to_matrix(r - step)) / 2e-6
        np.testing.assert_allclose(analytic[i], numeric, atol=1e-9)


def test_rotation_vector_matches_scipy_and_local_derivatives_match_differences():
    from tracker.geometry.rotations import local_rotation_derivatives, rotation_vector_to_matrix

    for vector in (np.array([0.3, -0.2, 0.9]), np.array([1e-14, 0.0, 0.0]), np.zeros(3)):
        np.testing.assert_allclose(
            rotation_vector_to_matrix(vector), Rotation.from_rotvec(vector).as_matrix(), atol=1e-12
        )
    rotation = euler_to_matrix([0.2, np.pi / 2, -0.4])  # at the Euler angles' singularity: no matter here
    analytic = local_rotation_derivatives(rotation)
    for i in range(3):
        step = np.zeros(3)
        step[i] = 1e-6
        numeric = (rotation @ rotation_vector_to_matrix(step) - rotation @ rotation_vector_to_matrix(-step)) / 2e-6
        np.testing.assert_allclose(analytic[i], numeric, atol=1e-9)


@pytest.mark.parametrize(
    "vector", [[0.3, -0.2, 0.9], [1e-9, 2e-9, 0.0], [0.0, 0.0, 0.0], [0.0, np.pi - 1e-9, 0.0], [2.0, -1.0, 0.5]]
)
def test_rotation_vector_round_trip(vector):
    from tracker.geometry.rotations import matrix_to_rotation_vector, rotation_vector_to_matrix

    rotation = rotation_vector_to_matrix(np.array(vector))
    np.testing.assert_allclose(rotation_vector_to_matrix(matrix_to_rotation_vector(rotation)), rotation, atol=1e-7)
    np.testing.assert_allclose(
        matrix_to_rotation_vector(rotation), Rotation.from_matrix(rotation).as_rotvec(), atol=1e-6
    )


def test_the_geodesic_angle_is_the_angle_between_two_orientations():
    from tracker.geometry.rotations import rotation_angle_deg, rotation_vector_to_matrix

    a = rotation_vector_to_matrix(np.array([0.3, -0.2, 0.5]))
    turn = rotation_vector_to_matrix(np.radians(25.0) * np.array([0.0, 0.6, 0.8]))
    assert rotation_angle_deg(a, a @ turn) == pytest.approx(25.0)
    # Gimbal lock of eq 4's angles: at r2 = 90 degrees, (r1, r3) = (t, t) is one orientation for any t.
    assert rotation_angle_deg(euler_to_matrix([0.7, np.pi / 2, 0.7]), euler_to_matrix([-0.4, np.pi / 2, -0.4])) < 1e-6


def test_fit_rigid_recovers_a_motion_and_measures_what_is_not_rigid():
    rng = np.random.default_rng(3)
    source = rng.normal(size=(200, 3))
    truth = rigid_transform(Rotation.random(random_state=4).as_matrix(), [0.4, -1.0, 2.5])
    transform, residual = fit_rigid(source, transform_points(truth, source))
    np.testing.assert_allclose(transform, truth, atol=1e-12)
    assert residual < 1e-12
    mirrored = source * [1.0, 1.0, -1.0]  # a reflection is no rigid motion: the fit stays a rotation
    transform, residual = fit_rigid(source, mirrored)
    assert np.linalg.det(transform[:3, :3]) > 0 and residual > 0.5
    bent = transform_points(truth, source) + [0.0, 0.0, 1e-3] * (source[:, :1] > 0)
    assert 1e-4 < fit_rigid(source, bent)[1] < 2e-3


def test_matrix_to_euler_near_follows_a_hinge_past_the_gimbal_lock():
    # A hinge about y turning from 0 to 120 degrees: the canonical angles fold back at r2 = 90 deg (r1 and r3 jump
    # by pi); taken near the last frame's angles they keep following the hinge.
    angles = np.array([0.0, 0.0, 0.0])
    for theta in np.linspace(0.0, np.radians(120), 61):
        rotation = euler_to_matrix([0.0, theta, 0.0])
        angles = matrix_to_euler(rotation, near=angles)
        np.testing.assert_allclose(angles, [0.0, theta, 0.0], atol=1e-6)
    assert matrix_to_euler(euler_to_matrix([0.0, np.radians(120), 0.0]))[1] == pytest.approx(np.radians(60))


@pytest.mark.parametrize("seed", range(5))
def test_matrix_to_euler_near_gives_the_same_rotation_within_pi_of_near(seed):
    rng = np.random.default_rng(seed)
    rotation = Rotation.random(random_state=seed).as_matrix()
    near = rng.uniform(-4, 4, 3)
    angles = matrix_to_euler(rotation, near=near)
    np.testing.assert_allclose(euler_to_matrix(angles), rotation, atol=1e-9)
    assert np.all(np.abs(angles - near) <= np.pi + 1e-9)


@pytest.mark.parametrize("vector", [[0.0, 0.0, 0.0], [1e-5, -2e-5, 0.0], [0.3, -1.2, 0.5], [2.9, 0.1, -0.4]])
def test_the_right_jacobian_maps_a_small_step_of_the_vector_to_a_turn_in_the_rotated_frame(vector):
    from tracker.geometry.rotations import matrix_to_rotation_vector, right_jacobian, rotation_vector_to_matrix

    vector, step = np.asarray(vector), 1e-6
    rotation = rotation_vector_to_matrix(vector)
    for axis in np.eye(3):
        turned = rotation.T @ rotation_vector_to_matrix(vector + step * axis)  # Exp(J_r step e_k) to first order
        np.testing.assert_allclose(matrix_to_rotation_vector(turned) / step, right_jacobian(vector) @ axis, atol=1e-6)


def test_the_batched_mean_of_rotation_vectors_is_scipys_weighted_mean_of_each():
    rng = np.random.default_rng(3)
    vectors, weights = rng.normal(0.0, 0.8, (6, 4, 3)), rng.random(6)
    mean = mean_rotation_vectors(vectors, weights)
    for joint in range(4):
        expected = Rotation.from_rotvec(vectors[:, joint]).mean(weights)
        assert Rotation.from_rotvec(mean[joint]).approx_equal(expected, atol=1e-12)
    # one pose, or every pose the same: that pose
    for poses in (vectors[:1], np.repeat(vectors[:1], 3, 0)):
        mean = Rotation.from_rotvec(mean_rotation_vectors(poses, weights[: len(poses)]))
        assert all(mean.approx_equal(Rotation.from_rotvec(vectors[0]), atol=1e-12))
