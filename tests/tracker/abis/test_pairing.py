"""Pairing features with visible samples (paper 1, 4.3.2): the nearest sample within the radius, each sample once
(the nearest feature wins it), never a sample already taken; with regions, each feature only with its region's
part, in one search the same pairs as each part paired alone."""

import numpy as np

from tracker.abis.correspondences import Pairs, pair_features
from tracker.abis.visibility import VisibleSamples

GRID_ETA, GRID_OMEGA = np.linspace(-1.5, 1.5, 40), np.linspace(-3.1, 3.1, 40)


def test_each_sample_goes_to_its_nearest_feature_within_the_radius_and_a_taken_one_to_none():
    visible = VisibleSamples(
        np.array([0, 0, 1]), np.array([3, 7, 3]), np.array([[10.0, 10.0], [20.0, 10.0], [30.0, 10]])
    )
    points = np.array([[10.5, 10.0], [10.2, 10.0], [25.0, 10.0], [29.0, 10.0]])  # two want sample 3; one too far
    pairs = pair_features(np.array([1, 2, 3, 4]), points, visible, 2.0, GRID_ETA, GRID_OMEGA)
    assert pairs.feature_ids.tolist() == [2, 4] and pairs.parts.tolist() == [0, 1] and pairs.samples.tolist() == [3, 3]
    np.testing.assert_array_equal(pairs.eta, GRID_ETA[[3, 3]])
    taken = Pairs(np.array([9]), np.array([1]), np.array([3]), np.zeros(1), np.zeros(1))
    again = pair_features(np.array([1, 2, 3, 4]), points, visible, 2.0, GRID_ETA, GRID_OMEGA, taken=taken)
    assert again.feature_ids.tolist() == [2]


def test_features_with_regions_pair_in_one_search_as_each_part_alone():
    rng = np.random.default_rng(4)
    for _ in range(20):
        m, n = 300, 120
        visible = VisibleSamples(rng.integers(0, 3, m), rng.integers(0, 40, m), rng.uniform(0, 40, (m, 2)))
        visible.uv[:20], visible.part[:20] = visible.uv[20:40], (visible.part[20:40] + 1) % 3  # other parts' samples
        # on the same pixel (two of one part at one distance may be taken either way, alone or together)
        points = rng.uniform(0, 40, (n, 2))
        ids, regions = np.arange(100, 100 + n), rng.integers(-1, 3, n)
        taken = Pairs(np.array([1]), visible.part[:1], visible.sample[:1], np.zeros(1), np.zeros(1))
        together = pair_features(ids, points, visible, 2.0, GRID_ETA, GRID_OMEGA, taken, feature_parts=regions)
        alone = []
        for part in range(3):
            own = visible.part == part
            offered = VisibleSamples(visible.part[own], visible.sample[own], visible.uv[own])
            mine = regions == part
            alone.append(pair_features(ids[mine], points[mine], offered, 2.0, GRID_ETA, GRID_OMEGA, taken))
        expected = Pairs.joined(alone)
        assert len(expected) > 30
        for name in ("feature_ids", "parts", "samples", "eta", "omega"):
            np.testing.assert_array_equal(getattr(together, name), getattr(expected, name))
