"""The silhouette costs (paper 2, eq 6-9): their weights by hand and against their definitions."""

import math

import numpy as np
import pytest

from tracker.registry import COSTS
from tracker.tbf.costs import EmptySilhouette, silhouette_distance, weight_map


def box(shape, rows, cols):
    mask = np.zeros(shape, bool)
    mask[rows[0] : rows[1], cols[0] : cols[1]] = True
    return mask


def test_xor_of_identical_silhouettes_is_zero_and_of_disjoint_ones_the_pixel_count_over_the_window():
    p = box((10, 10), (1, 3), (1, 4))  # 6 pixels
    q = box((10, 10), (6, 7), (5, 9))  # 4 pixels
    for cost in COSTS.names():
        assert silhouette_distance(cost, p, p) == 0.0
    assert silhouette_distance("xor", p, q) == pytest.approx((6 + 4) / 100)
    assert silhouette_distance("xor", p, q, window=(0, 0, 10, 5)) == pytest.approx(6 / 50)  # q lies outside


def test_wxor_by_hand():
    p = box((7, 7), (2, 5), (2, 5))  # a 3x3 square in a 7x7 window
    weights = weight_map("wxor", p, w=0.5)
    assert weights[3, 3] == 2.0 and weights[2, 3] == 1.0 and weights[2, 2] == 1.0  # inside: to the outside
    assert weights[0, 0] == pytest.approx(0.5 * math.sqrt(8)) and weights[1, 3] == 0.5  # outside: to the square
    q = box((7, 7), (3, 4), (3, 7))  # the centre row from the square's centre to the right edge
    # XOR: P's 7 pixels off that row (all on P's rim: D_P = 1), and Q's (3, 5) and (3, 6), 1 and 2 px outside P.
    expected = 7 * 1.0 + 0.5 * 1 + 0.5 * 2
    assert silhouette_distance("wxor", p, q, w=0.5) == pytest.approx(expected / 49)


def test_nwxor_by_hand():
    p = box((3, 5), (1, 2), (1, 4))  # a one-pixel line: it is its own medial axis
    weights = weight_map("nwxor", p)
    np.testing.assert_allclose(weights[1, 1:4], 1.0)  # D_P / (D_P + 0)
    # Outside: distance to the line; the largest is sqrt(2) at the corners, so w' = 1 / sqrt(2).
    assert weights[0, 0] == pytest.approx(1.0) and weights[0, 2] == pytest.approx(1 / math.sqrt(2))
    q = box((3, 5), (0, 3), (2, 3))  # the middle column
    assert silhouette_distance("nwxor", p, q) == pytest.approx((1 + 1 + 2 / math.sqrt(2)) / 15)


def test_nwxor_weighs_a_thin_limbs_centre_like_the_torsos_and_wxor_does_not():
    torso = box((80, 120), (10, 71), (20, 51))  # 61 x 31 px
    arm = box((80, 120), (38, 43), (51, 110))  # 5 px thick, sticking out sideways
    shape = torso | arm
    normalised, core = weight_map("nwxor", shape), weight_map("wxor", shape)
    arm_centre, torso_centre = (40, 85), (40, 35)
    assert normalised[arm_centre] == pytest.approx(normalised[torso_centre], rel=0.10)
    assert normalised[torso_centre] == pytest.approx(1.0, rel=0.10)
    assert core[arm_centre] / core[torso_centre] < 0.25  # wXOR: 3 px deep against 16


def test_an_empty_observation_has_no_weighted_distance():
    for cost in ("wxor", "nwxor"):
        with pytest.raises(EmptySilhouette, match="the silhouette is empty"):
            weight_map(cost, np.zeros((6, 8), bool))
    assert silhouette_distance("xor", np.zeros((6, 8), bool), box((6, 8), (1, 2), (1, 3))) == pytest.approx(2 / 48)


def test_distances_are_exact_euclidean_and_the_same_bits_after_rendering(body_silhouettes, renderer, body):
    from scipy import ndimage

    from tracker.tbf.costs import euclidean_distance

    silhouette = body_silhouettes[4]
    before = euclidean_distance(~silhouette)
    exact = np.sqrt(np.rint(ndimage.distance_transform_edt(~silhouette) ** 2))  # SciPy's exact transform
    np.testing.assert_array_equal(before, exact)
    renderer.render_depth_labels([], [])  # an OpenGL context at work in this process
    assert euclidean_distance(~silhouette).tobytes() == before.tobytes()


def test_the_exact_distance_is_scipys_to_the_bit_on_any_shape():
    from scipy import ndimage

    from tracker.tbf.costs import euclidean_distance

    rng = np.random.default_rng(7)
    shapes = [np.zeros((1, 1), bool), np.ones((1, 9), bool), np.ones((9, 1), bool), np.ones((5, 6), bool)]
    shapes[1][0, 4] = shapes[2][6, 0] = shapes[3][4, 0] = False  # one pixel off each: every distance measured to it
    for _ in range(60):  # blobs and specks, thin and wide, scattered over images of every proportion
        height, width = rng.integers(1, 48, 2)
        rows, columns = np.ogrid[:height, :width]
        away = np.ones((height, width), bool)
        for _ in range(rng.integers(1, 4)):
            centre, radii = rng.uniform(0, (height, width)), rng.uniform(0.5, 20, 2)
            away &= ((rows - centre[0]) / radii[0]) ** 2 + ((columns - centre[1]) / radii[1]) ** 2 > 1
        away &= rng.random((height, width)) > rng.uniform(0, 0.05)
        shapes += [away, ~away] if away.any() and not away.all() else []
    for away in shapes:
        assert euclidean_distance(away).tobytes() == ndimage.distance_transform_edt(away).tobytes()
    assert np.isinf(euclidean_distance(np.ones((4, 3), bool))).all()  # nothing to measure to
