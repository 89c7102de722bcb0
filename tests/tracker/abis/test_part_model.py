import numpy as np
import pytest

from tracker.abis.part_model import free_parameter_indices, part_world_points, posed_coordinates
from tracker.geometry.cameras import projection_jacobian
from tracker.models.dsq import PARAM_INDEX, pole_point


def arm_pixels(arm, params, part, camera):
    """Independent path: connect the joints, forward kinematics, project (what the renderer sees)."""
    return camera.project(arm.sample_points(arm.connect(params))[part])[0]


@pytest.mark.parametrize("part", [0, 1, 2])
def test_projected_jacobian_matches_finite_differences_through_the_arm(arm, motion, rig, part):
    params = motion.params(arm, 17)
    params[:, PARAM_INDEX["t1"]] = [0.1, -0.3, 0.2]  # exercise every shape term
    params[:, PARAM_INDEX["b2"]] = [0.05, -0.1, 0.0]
    params = arm.connect(params)
    grid = arm.sample_grid
    world = arm.world_transforms(params)
    is_root = part == 0
    parent = None if is_root else world[part - 1]
    joint = None if is_root else pole_point(params[part - 1], top=True)
    points, jacobian_of = part_world_points(
        params[part], posed_coordinates(grid.eta, grid.omega, is_root), parent, joint
    )
    np.testing.assert_allclose(points, arm.sample_points(params)[part], atol=1e-12)  # same points as the arm
    camera = rig[0]
    uv, _ = camera.project(points)
    uv_jacobian = np.einsum("nij,njk->nik", projection_jacobian(camera, points), jacobian_of())
    free = free_parameter_indices(is_root)
    assert uv_jacobian.shape == (len(points), 2, len(free))
    for column, index in enumerate(free):
        step = 1e-6
        plus, minus = params.copy(), params.copy()
        plus[part, index] += step
        minus[part, index] -= step
        numeric = (arm_pixels(arm, plus, part, camera) - arm_pixels(arm, minus, part, camera)) / (2 * step)
        np.testing.assert_allclose(uv_jacobian[:, :, column], numeric, atol=2e-4, rtol=1e-5)  # pixels per unit


def test_projection_jacobian_matches_finite_differences(rig):
    camera = rig[2]
    points = np.random.default_rng(0).normal([0.5, 0.0, -0.2], 0.2, size=(20, 3))
    analytic = projection_jacobian(camera, points)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = 1e-6
        numeric = (camera.project(points + step)[0] - camera.project(points - step)[0]) / 2e-6
        np.testing.assert_allclose(analytic[:, :, axis], numeric, atol=1e-5)
