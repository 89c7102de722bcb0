"""Scoring many model silhouettes at once equals the pair-by-pair definition (`tracker.tbf.costs`), moved or not."""

import numpy as np
import pytest

from tests.tracker.tbf.test_costs import box
from tracker.registry import COSTS
from tracker.tbf.costs import full_window, silhouette_distance
from tracker.tbf.scoring import ObservationScorer, RunBoundaries, ShiftedRunBoundaries, SilhouetteRuns, SilhouetteStack


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
    np.testing.assert_array_equal(runs.masks((5, 6)), masks)  # decoded back: the inverse of from_masks
    np.testing.assert_array_equal(runs.masks((5, 6), np.array([4, 2, 4])), masks[[4, 2, 4]])
    stack = SilhouetteStack((10, 20, 16, 25), runs)  # a window of 6 x 5 pixels
    assert stack.shape == (5, 6) and len(stack) == 7 and np.array_equal(stack.mask(4), masks[4])
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
        assert boundaries.sums(values, rows).tobytes() == boundaries.sums(values)[rows].tobytes()  # the product's bits


def test_run_indices_take_two_bytes_up_to_65535_pixels_and_read_as_wider_ones():
    """A window of 257 x 255 = 65,535 pixels keeps its runs' pixel indices in 2 bytes, one of 256 x 256 in 4 (its last
    run ends at 65,536); either way the sums, moved or not, and the masks are those of the same runs held in 8-byte
    integers (as a set stored before held them in 4), to the bit."""
    rng = np.random.default_rng(11)
    for shape, index in (((257, 255), np.uint16), ((256, 256), np.uint32)):
        masks = rng.random((5, *shape)) < 0.3
        masks[:, -1, -2:] = True  # a run to the window's last pixel: the largest index
        runs = SilhouetteRuns.from_masks(masks)
        assert runs.starts.dtype == runs.ends.dtype == index and int(runs.ends.max()) == masks[0].size
        wide = SilhouetteRuns(runs.starts.astype(np.int64), runs.ends.astype(np.int64), runs.ptr)  # the same runs
        values, rows = rng.normal(size=masks[0].size), np.array([4, 0, 2, 4])
        shifts = np.array([[3, -2], [-shape[1] + 5, 1], [0, shape[0] - 2], [0, 0]])
        assert runs.sums(values).tobytes() == wide.sums(values).tobytes()
        assert runs.sums(values, rows).tobytes() == wide.sums(values, rows).tobytes()
        moved = runs.shifted_sums(values, shape[1], rows, shifts)
        assert moved.tobytes() == wide.shifted_sums(values, shape[1], rows, shifts).tobytes()
        np.testing.assert_array_equal(runs.masks(shape, rows), masks[rows])
        np.testing.assert_allclose(moved[3], masks[4].ravel() @ values, atol=1e-9)  # not moved: its plain sum


def _framed_moved_sums(runs, values, width, rows, shifts):
    """`SilhouetteRuns.shifted_sums` the plain way: the window's values framed by zeros as wide as the largest
    shift, one prefix sum over the frame, and each run's pieces (one a window row) read there moved, added in the
    kernel's order (every run's first piece, silhouette by silhouette, then every second, ...)."""
    height = len(values) // width
    margin_u, margin_v = int(np.abs(shifts[:, 0]).max()), int(np.abs(shifts[:, 1]).max())
    framed = np.zeros((height + 2 * margin_v, width + 2 * margin_u))
    framed[margin_v : margin_v + height, margin_u : margin_u + width] = values.reshape(height, width)
    prefix = np.r_[0.0, np.cumsum(framed.ravel())]
    pieces = [[] for _ in rows]  # per silhouette, per run, its pieces' sums
    for i, (row, (du, dv)) in enumerate(zip(rows, shifts, strict=True)):
        for run in range(runs.ptr[row], runs.ptr[row + 1]):
            start, end, read = int(runs.starts[run]), int(runs.ends[run]), []
            while start < end:
                v = start // width
                piece_end = min(end, (v + 1) * width)
                at = (v + dv + margin_v) * framed.shape[1] + margin_u + du - v * width
                read.append(prefix[at + piece_end] - prefix[at + start])
                start = piece_end
            pieces[i].append(read)
    sums = np.zeros(len(rows))
    for piece in range(max((len(read) for runs_read in pieces for read in runs_read), default=0)):
        for i, runs_read in enumerate(pieces):
            for read in runs_read:
                if piece < len(read):
                    sums[i] += read[piece]
    return sums


def test_moved_sums_read_the_windows_own_prefix_sums_with_the_bits_of_a_framed_one():
    """Cutting each moved piece at the window's edges and reading the window's prefix sums gives the bits of
    reading a prefix sum over the window framed by zeros (zeros added change no sum): shifts within and beyond the
    window's size each way, runs that wrap over several rows, an empty silhouette, and silhouettes that some shifts
    keep within the window (read without cutting)."""
    rng = np.random.default_rng(17)
    height, width = 9, 7
    masks = rng.random((12, height, width)) < 0.45
    masks[3] = False
    masks[5, 2:6, :] = True  # one run over four rows
    masks[6, :, -2:], masks[6, :, :2] = True, True  # runs wrapping from each row's end into the next's start
    masks[7], masks[8] = False, False
    masks[7, 3:6, 2:5], masks[8, 2:7, 1:3], masks[8, 4, 4:6] = True, True, True  # within the window, one way or two
    runs = SilhouetteRuns.from_masks(masks)
    extents = runs.extents(width)  # read without cutting: 7 and 8 where a shift keeps them in; never 3 and 6
    np.testing.assert_array_equal(extents[[7, 8]], [[3, 5, 2, 5], [2, 6, 1, 6]])
    assert extents[3, 1] == extents[6, 1] == -1
    values = rng.normal(size=height * width) * 10.0 ** rng.integers(-6, 6, height * width)  # rounding shows
    rows = np.array([5, 6, 0, 3, 11, 6, 5, 2, 9, 1, 4, 7, 8, 10])
    for shifts in (
        rng.integers(-3, 4, (len(rows), 2)),
        rng.integers(-2 * height, 2 * height, (len(rows), 2)),
        np.array([[width, 0], [-width, 0], [0, height], [0, -height], [width - 1, height - 1]] + [[0, 0]] * 9),
        np.array(
            [[0, 0], [1, -1], [-1, 2], [2, 3], [-2, -3], [1, 1], [-1, -1], [2, 0], [0, 3], [1, 0], [0, 0]]
            + [[1, -2], [-1, 2], [0, 0]]
        ),  # 7 and 8 moved within the window
    ):
        expected = _framed_moved_sums(runs, values, width, rows, shifts)
        assert runs.shifted_sums(values, width, rows, shifts).tobytes() == expected.tobytes()


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
    pixels out of the window, some further than its size, and two silhouettes touch both sides of it (runs that wrap
    into the next row; one runs on over three rows), and one has no pixel."""
    rng = np.random.default_rng(5)
    height, width, count = 23, 17, 40
    masks = np.zeros((count, height, width), bool)
    for mask in masks:
        row, column = rng.integers(0, height - 5), rng.integers(0, width - 5)
        mask[row : row + rng.integers(2, 8), column : column + rng.integers(2, 9)] = True
    masks[0, 5:8, :] = True
    masks[1, 3:, 0], masks[1, 3:10, -1] = True, True
    masks[2] = False  # no runs at all
    for mask, column in zip(masks, rng.integers(0, width, count), strict=True) if tall else ():
        mask[1:22, column] = True  # a pole down each: fewer runs down the columns than along the rows
    observed = box((height, width), (4, 15), (3, 12))
    pixels = rng.integers(-3, 4, (count, 2))
    reference = pixels[7]
    rows = np.array([3, 0, 1, 39, 3, 2])
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
        # moved further than the window is wide or high: out of it, wholly or but for a sliver
        far = np.array([[width + 4, 0], [0, -height - 3], [-width + 1, 2], [3, height - 1]])
        expected_far = [silhouette_distance(cost, observed, _moved(masks[0], *shift)) for shift in far]
        by_runs = scorer.scores_of_shifted(SilhouetteRuns.from_masks(masks), np.zeros(len(far), np.int64), far)
        np.testing.assert_allclose(by_runs, expected_far, rtol=1e-12, atol=1e-15)
        boundaries = ShiftedRunBoundaries(masks, pixels)
        np.testing.assert_allclose(scorer.scores_of_placed(boundaries, reference), expected, rtol=1e-12, atol=1e-15)
        placed = scorer.scores_of_placed(boundaries, reference, rows)
        np.testing.assert_array_equal(placed, scorer.scores_of_placed(boundaries, reference)[rows])
        assert boundaries.by_columns == tall
    assert len({round(value, 9) for value in expected}) > 20  # the shifts change the scores: not a vacuous test
    with pytest.raises(ValueError, match="outside the silhouettes' pixels"):
        ShiftedRunBoundaries(masks, pixels).sums(np.ones(height * width), pixels.max(axis=0) + 1)


def test_the_top_levels_sums_of_some_rows_are_the_sparse_products_of_those_rows():
    """A top level's sums of the rows asked, unmoved (every row's product, then those rows) and moved (a compiled
    loop over those rows alone, each row's entries added one by one from 0 as scipy's product adds them), are the
    product of those rows' copy, bit for bit, for any rows (repeated, unordered, none)."""
    rng = np.random.default_rng(11)
    masks = rng.random((60, 19, 23)) < 0.45
    masks[5] = False
    values = rng.normal(size=19 * 23) * 10.0 ** rng.integers(-6, 7, 19 * 23)  # widely spread: rounding shows
    pixels = rng.integers(-2, 3, (60, 2))
    boundaries, placed = RunBoundaries(masks), ShiftedRunBoundaries(masks, pixels)
    framed = np.pad(values.reshape(19, 23), ((placed.margin[1],) * 2, (placed.margin[0],) * 2))
    flat = (framed.T if placed.by_columns else framed).ravel()
    slid = np.zeros(len(flat) + 1 + 2 * placed.reach)
    np.cumsum(flat, out=slid[placed.reach + 1 : placed.reach + 1 + len(flat)])
    slid[placed.reach + 1 + len(flat) :] = slid[placed.reach + len(flat)]
    start = int(placed.flat(pixels[9] - placed.low))
    for rows in (None, np.array([7, 3, 3, 59, 0, 5]), np.zeros(0, np.int64)):
        picked = np.arange(60) if rows is None else rows
        unmoved = values.reshape(19, 23).T.ravel() if boundaries.by_columns else values
        by_product = boundaries.matrix[picked] @ np.r_[0.0, np.cumsum(unmoved)]
        np.testing.assert_array_equal(boundaries.sums(values, rows), by_product)
        by_product = placed.matrix[picked] @ slid[start : start + placed.matrix.shape[1]]
        np.testing.assert_array_equal(placed.sums(values, pixels[9], rows), by_product)


def _plain_runs(image: np.ndarray) -> list[tuple[int, int]]:
    """The runs of inside pixels along ``image`` flattened, pixel by pixel (the naive reference)."""
    flat, runs, start = image.ravel(), [], None
    for pixel, inside in enumerate(flat):
        if inside and start is None:
            start = pixel
        elif not inside and start is not None:
            runs.append((start, pixel))
            start = None
    return runs + ([(start, len(flat))] if start is not None else [])


def test_runs_of_framed_silhouettes_are_those_of_the_padded_images_and_all_sums_add_as_bincount():
    """`SilhouetteRuns.from_masks` framed by rows and columns of outside, along the rows or down the columns, gives
    the runs of the images padded (np.pad) and flattened (transposed first for the columns), pixel by pixel; a frame
    with no columns lets a run go on into the next row, one with some ends it at the row's end. Every silhouette's
    sum adds its runs in order from 0, as ``np.bincount`` adds them (the bits), and the masks painted back from the
    runs are the images."""
    rng = np.random.default_rng(17)
    masks = rng.random((9, 7, 6)) < 0.5
    masks[2] = False  # no runs
    masks[3] = True  # one run over the whole image
    masks[4, 1, 3:], masks[4, 2, :4] = True, True  # a run from one row into the next
    labels = masks * rng.integers(1, 9, masks.shape)  # part labels: inside where nonzero
    for frame in ((0, 0), (2, 0), (0, 3), (1, 2)):
        padded = np.pad(masks, ((0, 0), (frame[0],) * 2, (frame[1],) * 2))
        for down_columns in (False, True):
            runs = SilhouetteRuns.from_masks(labels, block=4, frame=frame, down_columns=down_columns)
            for index, image in enumerate(padded):
                found = list(
                    zip(
                        runs.starts[runs.ptr[index] : runs.ptr[index + 1]].tolist(),
                        runs.ends[runs.ptr[index] : runs.ptr[index + 1]].tolist(),
                        strict=True,
                    )
                )
                assert found == _plain_runs(image.T if down_columns else image), (frame, down_columns, index)
        framed = RunBoundaries(masks, frame=frame)
        plain = RunBoundaries(padded)
        assert framed.shape == plain.shape and framed.by_columns == plain.by_columns
        assert (framed.matrix != plain.matrix).nnz == 0
    runs = SilhouetteRuns.from_masks(masks)
    values = rng.normal(size=42) * 10.0 ** rng.integers(-6, 7, 42)  # widely spread: rounding shows
    prefix = np.r_[0.0, np.cumsum(values)]
    owner = np.repeat(np.arange(len(runs)), np.diff(runs.ptr))
    by_bincount = np.bincount(owner, weights=prefix[runs.ends] - prefix[runs.starts], minlength=len(runs))
    assert runs.sums(values).tobytes() == by_bincount.tobytes()
    np.testing.assert_array_equal(runs.masks((7, 6)), masks)
    np.testing.assert_array_equal(runs.masks((7, 6), np.array([4, 2, 4])), masks[[4, 2, 4]])
