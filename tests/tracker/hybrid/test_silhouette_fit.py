"""The hybrid's silhouette fit: its analytic Jacobian against finite differences, and a perturbed pose recovered
from real renders of the body (OSMesa) by the fit alone."""

import numpy as np
import pytest

from tracker.evaluation.body import joint_errors_mm
from tracker.geometry.rigs import View, cameras
from tracker.hybrid.silhouette_fit import FIT_COLUMNS, FitSettings, SilhouetteFit, pixel_rows
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.tbf.pose_sets import arm_grid

RIG = cameras(
    views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9)), View("oblique", (3.182, -3.182, 0.9)))
)


@pytest.fixture(scope="module")
def pose(body):
    return arm_grid(body, [50.0], [30.0], [20.0], [10.0], yaw_deg=-90.0)[0]


def silhouettes(renderer, body, pose, rig):
    views = renderer.render(rig, body.surface_meshes(pose))
    return [views[camera.name].labels > 0 for camera in rig]


def test_the_pixel_jacobian_is_the_derivative_of_the_projected_skinned_vertices(body, pose):
    fit = SilhouetteFit(body, RIG)
    points = body.posed_vertices(pose)
    analytic = pixel_rows(RIG[1], points, fit.vertex_rows(pose, np.arange(len(points))))
    step = 1e-6
    for column in (0, 2, 3, 5, 10, 40, len(FIT_COLUMNS) - 1):  # the root's position, the root's and limbs' joints
        moved = pose.copy()
        moved[FIT_COLUMNS[column]] += step
        before, _ = RIG[1].project(body.posed_vertices(pose - (moved - pose)))
        after, _ = RIG[1].project(body.posed_vertices(moved))
        numeric = (after - before) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, column], numeric, rtol=1e-4, atol=1e-4)
    assert np.abs(analytic).max() > 50  # the columns move pixels, the test is not of zeros


def perturbed(pose):
    start = pose.copy()
    start[:3] += [0.04, -0.03, 0.02]
    for joint, turn in (("RightArm", [0.0, 0.3, 0.0]), ("LeftForeArm", [0.25, 0.0, 0.0]), ("Hips", [0, 0, 0.12])):
        start[3 + 3 * JOINT_INDEX[joint] : 6 + 3 * JOINT_INDEX[joint]] += turn
    return start


def test_the_fit_recovers_a_perturbed_pose_from_three_rendered_silhouettes(body, pose, renderer):
    fit = SilhouetteFit(body, RIG, FitSettings(iterations=15))
    fit.observe(silhouettes(renderer, body, pose, RIG))
    start = perturbed(pose)
    refined, cost = fit.refine(start)
    assert cost == fit.fit_cost(refined)  # the cost it returns is its pose's
    before, after = joint_errors_mm(body, pose, start), joint_errors_mm(body, pose, refined)
    assert fit.fit_cost(refined) < 0.2 * fit.fit_cost(start)
    assert after["absolute"] < 0.3 * before["absolute"] and after["aligned"] < 0.6 * before["aligned"], (before, after)


def test_from_one_view_the_fit_recovers_what_the_view_sees(body, pose, renderer):
    """One view cannot tell depth: the joints' pixels are recovered, not their distance from the camera."""
    camera = RIG[0]
    fit = SilhouetteFit(body, [camera], FitSettings(iterations=15))
    fit.observe(silhouettes(renderer, body, pose, [camera]))
    start = perturbed(pose)
    refined, cost = fit.refine(start)
    assert cost == fit.fit_cost(refined)  # the cost it returns is its pose's

    def pixel_error(estimate):
        return np.linalg.norm(
            camera.project(body.joint_positions(estimate))[0] - camera.project(body.joint_positions(pose))[0], axis=1
        ).mean()

    assert fit.fit_cost(refined) < 0.2 * fit.fit_cost(start)
    assert pixel_error(refined) < 0.4 * pixel_error(start), (pixel_error(start), pixel_error(refined))
