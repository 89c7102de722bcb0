"""The model image's prediction of occlusion: the feature regions (occluding edges between parts in a label image and
the silhouette's margin kept out), and the points another part's edge reaches by the next frame, each against a
naive implementation."""

import numpy as np
import pytest

from tracker.abis.visibility import VisibleSamples, reached_by_other_parts, region_labels_at


def naive_occlusion_edges(labels, margin):
    """A part's pixels with another part (not the background) in the square window of ``margin`` around them."""
    edges = np.zeros(labels.shape, bool)
    for y, x in zip(*np.nonzero(labels), strict=True):
        window = labels[max(0, y - margin) : y + margin + 1, max(0, x - margin) : x + margin + 1]
        edges[y, x] = np.any((window != labels[y, x]) & (window != 0))
    return edges


def naive_near_another_label(labels, margin):
    """Pixels with any other label, the background among them, in the square window of ``margin`` around them."""
    near = np.zeros(labels.shape, bool)
    for y, x in np.ndindex(labels.shape):
        window = labels[max(0, y - margin) : y + margin + 1, max(0, x - margin) : x + margin + 1]
        near[y, x] = np.any(window != labels[y, x])
    return near


def three_parts(rng):
    labels = np.zeros((40, 50), np.uint8)
    labels[5:30, 5:25] = 1
    labels[10:35, 20:45] = 2  # overlaps part 1: an occluding edge along x = 20
    labels[12:16, 30:34] = 3
    labels[rng.uniform(size=labels.shape) < 0.02] = 0  # specks of background
    return labels


def regions_everywhere(labels, occlusion_margin, boundary_margin):
    rows, columns = np.indices(labels.shape).reshape(2, -1)
    return region_labels_at(labels, rows, columns, occlusion_margin, boundary_margin).reshape(labels.shape)


def test_feature_regions_drop_occlusion_edges_and_the_silhouettes_margin_as_a_naive_window_does():
    """Every pixel of a label image, margins 0 to 3: the label, or 0 on an occlusion edge or near another label. The
    parts within the image, in a corner of a larger one, reaching its edges (where the neighbourhoods are cut), and
    none at all."""
    labels = three_parts(np.random.default_rng(0))
    in_a_corner = np.zeros((70, 90), np.uint8)
    in_a_corner[:40, :50] = labels
    at_the_edges = np.zeros((40, 50), np.uint8)
    at_the_edges[15:, 10:] = labels[10:35, 5:45]  # part 2 reaches the bottom and the right edge (turned: the top, left)
    top_and_bottom = np.zeros((40, 50), np.uint8)
    top_and_bottom[:6, :20], top_and_bottom[-6:, :20] = 1, 2  # two parts across the image from each other
    images = (
        labels,
        in_a_corner,
        at_the_edges,
        at_the_edges[::-1, ::-1].copy(),
        top_and_bottom,
        np.zeros((10, 12), np.uint8),
    )
    for image in images:
        for occlusion_margin, boundary_margin in [(0, 0), (1, 0), (3, 0), (0, 2), (3, 2), (1, 3)]:
            dropped = naive_occlusion_edges(image, occlusion_margin) | naive_near_another_label(image, boundary_margin)
            expected = np.where(dropped, 0, image)
            np.testing.assert_array_equal(regions_everywhere(image, occlusion_margin, boundary_margin), expected)
    regions = regions_everywhere(labels, 3, 0)
    assert regions[20, 6] == 1 and regions[32, 40] == 2  # a part's own silhouette is no occlusion edge
    assert regions[20, 20] == 0 and regions[20, 18] == 0  # where parts 1 and 2 meet, and within 3 px of it


def test_the_boundary_margin_drops_a_band_at_every_edge():
    labels = np.zeros((20, 30), np.uint8)
    labels[5:15, 5:15], labels[5:15, 15:25] = 1, 2
    interior = regions_everywhere(labels, 0, 2)
    assert (interior[7:13, 7:13] == 1).all() and (interior[7:13, 17:23] == 2).all()
    assert (interior[:, 13:17] == 0).all()  # the boundary between the parts
    assert (interior[5:7] == 0).all() and (interior[:, 5:7] == 0).all()  # the silhouette


@pytest.mark.parametrize(
    ("margin", "most", "spread"), [(4.0, 6.0, 100), (0.0, 0.0, 100), (7.0, 15.0, 640), (2.0, 0.0, 5)]
)
def test_points_are_reached_within_the_margin_plus_the_relative_motion_of_another_parts_samples(margin, most, spread):
    """Against every (point, sample) pair tried: reaches wide and none at all, samples spread over an image or
    crowded into a few pixels, points on whole pixels, some on a sample."""
    rng = np.random.default_rng(1)
    samples_uv = rng.uniform(0, spread, (300, 2))
    visible = VisibleSamples(rng.integers(0, 3, 300), np.arange(300), samples_uv)
    sample_motion = rng.normal(0, 3, (300, 2))
    points = np.round(rng.uniform(0, spread, (80, 2)))
    points[:10] = samples_uv[:10]
    parts = rng.integers(0, 3, 80)
    motion = rng.normal(0, 3, (80, 2))
    reached = reached_by_other_parts(points, parts, motion, visible, sample_motion, margin, most)
    naive = np.zeros(80, bool)
    for i in range(80):
        for j in range(300):
            if visible.part[j] == parts[i]:
                continue
            relative = min(np.linalg.norm(sample_motion[j] - motion[i]), most)
            naive[i] |= np.linalg.norm(samples_uv[j] - points[i]) <= margin + relative
    np.testing.assert_array_equal(reached, naive)
    assert naive.any() and (spread < 10 or not naive.all())  # crowded into 5 px, every point is reached
    # Standing still, only the margin counts; a part's own samples never count.
    still = reached_by_other_parts(points, parts, np.zeros((80, 2)), visible, np.zeros((300, 2)), margin, most)
    one_part = np.zeros(80, int)
    own = reached_by_other_parts(
        points, one_part, motion, VisibleSamples(one_part, np.arange(80), points), motion, margin, most
    )
    assert still.sum() <= reached.sum() and not own.any()


def test_a_sample_exactly_at_the_farthest_reach_counts():
    """Margin plus the most relative motion, 4 + 6 = 10 px, met exactly (a 6-8-10 triangle) by a sample moving
    faster than the most: reached; a hair farther: not."""
    margin, most = 4.0, 6.0
    points, parts, motion = np.array([[50.0, 50.0], [10.0, 10.0]]), np.array([0, 0]), np.zeros((2, 2))
    for offset, expected in ((np.array([6.0, 8.0]), True), (np.array([6.0, 8.0 + 1e-9]), False)):
        samples = np.array([points[0] + offset, [200.0, 200.0]])
        visible = VisibleSamples(np.array([1, 1]), np.arange(2), samples)
        reached = reached_by_other_parts(points, parts, motion, visible, np.full((2, 2), 40.0), margin, most)
        np.testing.assert_array_equal(reached, [expected, False])
