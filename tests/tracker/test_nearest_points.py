"""The exact nearest-point search against every distance computed (brute force)."""

import numpy as np
import pytest

from tracker.geometry.nearest_points import nearest_points


def brute_force(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    distances = ((queries[:, None, :] - points[None, :, :]) ** 2).sum(axis=2)
    return np.argmin(distances, axis=1)  # of equal distances, the first


@pytest.mark.parametrize("spread", [(60.0, 20.0), (20.0, 60.0), (1.0, 1.0)])  # wide, tall (sorted by v), small
def test_the_nearest_point_is_the_brute_force_ones(spread):
    rng = np.random.default_rng(int(spread[0]))
    points = rng.normal(size=(700, 2)) * spread + 100
    queries = np.r_[rng.normal(size=(400, 2)) * np.multiply(spread, 1.3) + 100, points[:20], [[-1e3, -1e3]]]
    np.testing.assert_array_equal(nearest_points(points, queries), brute_force(points, queries))


def test_of_points_at_the_same_distance_the_first_is_the_nearest():
    points = np.array([[5.0, 0.0], [0.0, 5.0], [-5.0, 0.0], [0.0, -5.0], [0.0, 5.0]])
    queries = np.array([[0.0, 0.0], [0.0, 6.0], [-1.0, 1.0]])
    np.testing.assert_array_equal(nearest_points(points, queries), [0, 1, 1])
    np.testing.assert_array_equal(nearest_points(points[:1], queries), [0, 0, 0])
    assert nearest_points(points, np.empty((0, 2))).shape == (0,)
    with pytest.raises(ValueError, match="no points"):
        nearest_points(np.empty((0, 2)), queries)
