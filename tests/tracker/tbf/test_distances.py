import math

import numpy as np
import pytest

from tracker.registry import COSTS
from tracker.tbf.distances import (
    EmptySilhouette,
    ObservationScorer,
    RunBoundaries,
    ShiftedRunBoundaries,
    SilhouetteRuns,
    SilhouetteStack,
    full_window,
    silhouette_distance,
    weight_map,
)


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


def test_the_batch_scorer_equals_the_pair_function(body_silhouettes):
    observed, models = body_silhouettes[0], body_silhouettes[1:]
    window = (2, 1, 70, 58)
    stack = SilhouetteStack.crop(models, window)
    for cost in COSTS.names():
        settings = {"w": 0.7} if cost == "wxor" else {}
        scores = ObservationScorer(cost, observed, window, **settings).scores(stack)
        expected = [silhouette_distance(cost, observed, model, window, **settings) for model in models]
        # (the scores come from prefix sums: their rounding is absolute, of the order of eps times the largest)
        np.testing.assert_allclose(scores, expected, rtol=1e-9, atol=1e-12 * max(expected))


def test_runs_hold_exactly_the_inside_pixels():
    rng = np.random.default_rng(3)
    masks = rng.random((7, 5, 6)) < 0.4
    masks[2] = False  # an empty silhouette
    masks[4, 1, 4:], masks[4, 2, :2] = True, True  # a run that wraps from one image row into the next
    labels = masks * rng.integers(1, 16, masks.shape)  # part labels: inside where nonzero
    runs = SilhouetteRuns.from_masks(labels, block=3)
    rebuilt = np.zeros((7, 30), bool)
    for index in range(7):
        for r in range(runs.ptr[index], runs.ptr[index + 1]):
            rebuilt[index, runs.starts[r] : runs.ends[r]] = True
    np.testing.assert_array_equal(rebuilt, masks.reshape(7, -1))
    values = rng.normal(size=30)
    np.testing.assert_allclose(runs.sums(values), masks.reshape(7, -1) @ values, atol=1e-12)
    rows = np.array([4, 2, 0, 4])
    np.testing.assert_allclose(runs.sums(values, rows), masks.reshape(7, -1)[rows] @ values, atol=1e-12)
    masks[6, 4, 3:] = True  # a run that reaches the last pixel
    assert SilhouetteRuns.from_masks(masks).ends.max() == 30
    wide, tall = np.zeros((2, 7, 5, 6), bool)
    wide[:, 1:3], tall[:, :, 1:3] = True, True  # two rows: one run a row, six a column; two columns: the reverse
    for shapes, by_columns in ((masks, None), (wide, False), (tall, True)):  # the sums as one sparse product
        boundaries = RunBoundaries(shapes)
        assert len(boundaries) == 7 and by_columns in (None, boundaries.by_columns)
        np.testing.assert_allclose(boundaries.sums(values), shapes.reshape(7, -1) @ values, atol=1e-12)
        np.testing.assert_allclose(boundaries.sums(values, rows), shapes.reshape(7, -1)[rows] @ values, atol=1e-12)


def _moved(mask, du, dv):
    """``mask`` moved by whole pixels pixel by pixel, what leaves the image lost (the naive reference)."""
    moved = np.zeros_like(mask)
    for v, u in zip(*np.nonzero(mask), strict=True):
        if 0 <= v + dv < mask.shape[0] and 0 <= u + du < mask.shape[1]:
            moved[v + dv, u + du] = True
    return moved


@pytest.mark.parametrize("tall", [False, True])  # runs along the rows, or down the columns
def test_silhouettes_moved_by_whole_pixels_score_as_if_moved_first(tall):
    """Each silhouette moved by its own shift before scoring: from its runs (any rows) and from its run boundaries
    (all, moved by a reference pixel minus its own), against the distance to the moved mask; some shifts take
    pixels out of the window, and two silhouettes touch both sides of it (runs that wrap into the next row)."""
    rng = np.random.default_rng(5)
    height, width, count = 23, 17, 40
    masks = np.zeros((count, height, width), bool)
    for mask in masks:
        row, column = rng.integers(0, height - 5), rng.integers(0, width - 5)
        mask[row : row + rng.integers(2, 8), column : column + rng.integers(2, 9)] = True
    masks[0, 5:7, :] = True
    masks[1, 3:, 0], masks[1, 3:10, -1] = True, True
    for mask, column in zip(masks, rng.integers(0, width, count), strict=True) if tall else ():
        mask[1:22, column] = True  # a pole down each: fewer runs down the columns than along the rows
    observed = box((height, width), (4, 15), (3, 12))
    pixels = rng.integers(-3, 4, (count, 2))
    reference = pixels[7]
    rows = np.array([3, 0, 1, 39, 3])
    for cost in COSTS.names():
        scorer = ObservationScorer(cost, observed, full_window((height, width)))
        expected = np.array(
            [
                silhouette_distance(cost, observed, _moved(mask, *(reference - pixel)))
                for mask, pixel in zip(masks, pixels, strict=True)
            ]
        )
        by_runs = scorer.scores_of_shifted(SilhouetteRuns.from_masks(masks), rows, reference - pixels[rows])
        np.testing.assert_allclose(by_runs, expected[rows], rtol=1e-12, atol=1e-15)
        boundaries = ShiftedRunBoundaries(masks, pixels)
        np.testing.assert_allclose(scorer.scores_of_placed(boundaries, reference), expected, rtol=1e-12, atol=1e-15)
        assert boundaries.by_columns == tall
    assert len({round(value, 9) for value in expected}) > 20  # the shifts change the scores: not a vacuous test
    with pytest.raises(ValueError, match="outside the silhouettes' pixels"):
        ShiftedRunBoundaries(masks, pixels).sums(np.ones(height * width), pixels.max(axis=0) + 1)


def test_an_empty_observation_has_no_weighted_distance():
    for cost in ("wxor", "nwxor"):
        with pytest.raises(EmptySilhouette, match="the silhouette is empty"):
            weight_map(cost, np.zeros((6, 8), bool))
    assert silhouette_distance("xor", np.zeros((6, 8), bool), box((6, 8), (1, 2), (1, 3))) == pytest.approx(2 / 48)


@pytest.fixture(scope="module")
def body_silhouettes(body):
    """Silhouettes of the body at 80x60 in 12 poses of the arm swing (side-on)."""
    from tracker.geometry.rigs import mono
    from tracker.motion.body_swing import BodySwing
    from tracker.render.offscreen import SceneRenderer

    camera = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=120.0, width=80, height=60)
    swing = BodySwing()
    with SceneRenderer(80, 60) as renderer:
        return np.array(
            [
                renderer.render_depth_labels(camera, body.surface_meshes(swing.params(body, 3 * k)))["main"].labels > 0
                for k in range(12)
            ]
        )


def test_distances_are_exact_euclidean_and_the_same_bits_after_rendering(body_silhouettes, renderer, body):
    from scipy import ndimage

    from tracker.tbf.distances import euclidean_distance

    silhouette = body_silhouettes[4]
    before = euclidean_distance(~silhouette)
    exact = np.sqrt(np.rint(ndimage.distance_transform_edt(~silhouette) ** 2))  # SciPy's exact transform
    np.testing.assert_array_equal(before, exact)
    renderer.render_depth_labels([], [])  # an OpenGL context at work in this process
    assert euclidean_distance(~silhouette).tobytes() == before.tobytes()
