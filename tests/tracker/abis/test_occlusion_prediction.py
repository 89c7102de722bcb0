"""The model image's prediction of occlusion: occluding edges between parts in a label image, and the points another
part's edge reaches by the next frame, each against a naive implementation."""

import numpy as np

from tracker.abis.visibility import (
    VisibleSamples,
    interior_labels,
    occlusion_edges,
    reached_by_other_parts,
    region_labels_at,
)


def naive_occlusion_edges(labels, margin):
    height, width = labels.shape
    edges = np.zeros(labels.shape, bool)
    for y in range(height):
        for x in range(width):
            if labels[y, x] == 0:
                continue
            window = labels[max(0, y - margin) : y + margin + 1, max(0, x - margin) : x + margin + 1]
            edges[y, x] = np.any((window != labels[y, x]) & (window != 0))
    return edges


def test_occlusion_edges_are_part_pixels_near_another_part_not_near_the_background():
    rng = np.random.default_rng(0)
    labels = np.zeros((40, 50), np.uint8)
    labels[5:30, 5:25] = 1
    labels[10:35, 20:45] = 2  # overlaps part 1: an occluding edge along x = 20
    labels[12:16, 30:34] = 3
    labels[rng.uniform(size=labels.shape) < 0.02] = 0  # specks of background
    for margin in (0, 1, 3):
        np.testing.assert_array_equal(occlusion_edges(labels, margin), naive_occlusion_edges(labels, margin))
    edges = occlusion_edges(labels, 3)
    assert not edges[20, 6] and not edges[32, 40]  # a part's own silhouette is no occlusion edge


def test_region_labels_at_pixels_read_the_whole_images_there():
    """A feature's region: its label unless on an occlusion edge or within the boundary margin, the same as the two
    whole images combined and read at its pixel (every pixel of a random label image, margins 0 to 3)."""
    rng = np.random.default_rng(2)
    labels = np.zeros((40, 50), np.uint8)
    labels[5:30, 5:25] = 1
    labels[10:35, 20:45] = 2
    labels[12:16, 30:34] = 3
    labels[rng.uniform(size=labels.shape) < 0.02] = 0
    rows, columns = np.indices(labels.shape).reshape(2, -1)
    for occlusion_margin, boundary_margin in [(0, 0), (3, 0), (0, 2), (3, 2), (1, 3)]:
        whole = np.where(occlusion_edges(labels, occlusion_margin), 0, interior_labels(labels, boundary_margin))
        at = region_labels_at(labels, rows, columns, occlusion_margin, boundary_margin)
        np.testing.assert_array_equal(at, whole[rows, columns])
    assert 0 < np.count_nonzero(at) < np.count_nonzero(labels)  # some pixels dropped, some kept


def test_points_are_reached_within_the_margin_plus_the_relative_motion_of_another_parts_samples():
    rng = np.random.default_rng(1)
    samples_uv = rng.uniform(0, 100, (300, 2))
    visible = VisibleSamples(rng.integers(0, 3, 300), np.arange(300), samples_uv)
    sample_motion = rng.normal(0, 3, (300, 2))
    points = rng.uniform(0, 100, (80, 2))
    parts = rng.integers(0, 3, 80)
    motion = rng.normal(0, 3, (80, 2))
    margin, most = 4.0, 6.0
    reached = reached_by_other_parts(points, parts, motion, visible, sample_motion, margin, most)
    naive = np.zeros(80, bool)
    for i in range(80):
        for j in range(300):
            if visible.part[j] == parts[i]:
                continue
            relative = min(np.linalg.norm(sample_motion[j] - motion[i]), most)
            naive[i] |= np.linalg.norm(samples_uv[j] - points[i]) <= margin + relative
    np.testing.assert_array_equal(reached, naive)
    assert 0 < naive.sum() < 80
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
