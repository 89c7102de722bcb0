"""The body's error measures against independent derivations: PA-MPJPE's similarity against a naive numerical
least-squares fit, and the root's orientation error against a turn made by hand."""

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from tracker.evaluation.body import joint_errors_mm, procrustes_aligned, root_orientation_error_deg
from tracker.tbf.pose_sets import arm_grid


def naive_similarity_fit(points: np.ndarray, reference: np.ndarray) -> float:
    """The least sum of squared distances over s R p + t, found by a general minimiser from several starts (no SVD)."""

    def residual(x):
        moved = np.exp(x[3]) * Rotation.from_rotvec(x[:3]).apply(points) + x[4:]
        return ((moved - reference) ** 2).sum()

    starts = [np.r_[Rotation.random(random_state=k).as_rotvec(), 0.0, np.zeros(3)] for k in range(8)]
    return min(minimize(residual, x0, method="BFGS", options={"gtol": 1e-12}).fun for x0 in starts)


def test_procrustes_alignment_is_the_least_squares_similarity():
    rng = np.random.default_rng(3)
    reference = rng.normal(size=(15, 3))
    points = 1.3 * Rotation.from_rotvec([0.4, -1.1, 2.0]).apply(reference) + [0.5, 2.0, -1.0]
    points += rng.normal(scale=0.2, size=points.shape)  # not an exact copy: the fit has a residual
    ours = ((procrustes_aligned(points, reference) - reference) ** 2).sum()
    assert ours == pytest.approx(naive_similarity_fit(points, reference), rel=1e-6)
    assert ours > 0.1


def test_an_exact_similarity_copy_aligns_to_zero_but_a_mirror_image_does_not():
    rng = np.random.default_rng(4)
    reference = rng.normal(size=(15, 3))
    copy = 0.7 * Rotation.from_rotvec([1.0, 0.2, -0.5]).apply(reference) - [1.0, 0.0, 3.0]
    np.testing.assert_allclose(procrustes_aligned(copy, reference), reference, atol=1e-12)
    mirrored = reference * [-1.0, 1.0, 1.0]  # a reflection is no rotation: it must not be undone
    residual = ((procrustes_aligned(mirrored, reference) - reference) ** 2).sum()
    assert residual == pytest.approx(naive_similarity_fit(mirrored, reference), rel=1e-6)
    assert residual > 1.0


def test_pa_mpjpe_ignores_place_facing_and_size_but_not_posture(body):
    pose = arm_grid(body, [30.0], [8.0], [0.0], [0.0], yaw_deg=-90.0)[0]
    turned = arm_grid(body, [30.0], [8.0], [0.0], [0.0], yaw_deg=-30.0)[0]
    turned[:3] += [0.3, -0.4, 0.0]
    errors = joint_errors_mm(body, pose, turned)
    assert errors["absolute"] > 300 and errors["aligned"] > 50  # moved and turned ...
    assert errors["pa"] == pytest.approx(0.0, abs=1e-6)  # ... but the same posture
    raised = arm_grid(body, [90.0], [8.0], [0.0], [0.0], yaw_deg=-90.0)[0]
    assert joint_errors_mm(body, pose, raised)["pa"] > 10.0


def test_the_root_orientation_error_is_the_turn_between_the_roots(body):
    pose = arm_grid(body, [30.0], [8.0], [0.0], [0.0], yaw_deg=-90.0)[0]
    turned = arm_grid(body, [60.0], [8.0], [0.0], [0.0], yaw_deg=-50.0)[0]  # the arm does not count
    assert root_orientation_error_deg(pose, turned) == pytest.approx(40.0, abs=1e-9)
    assert root_orientation_error_deg(pose, pose) == pytest.approx(0.0, abs=1e-6)
