import cv2
import numpy as np
import pytest

from tracker.models.textures import block_noise_texture
from tracker.observe.features import FeatureSettings, FeatureTracker, away_from, detection_box


def textured_image(seed=0, size=(240, 320)):
    """Blocks of random grey on a plain background, slightly blurred like a camera image."""
    texture = block_noise_texture(np.random.default_rng(seed), (size[0] // 8, size[1] // 8), (255, 255, 255))
    return cv2.GaussianBlur(texture[: size[0], : size[1]], (3, 3), 0.8)


def shifted(image, du, dv):
    matrix = np.float32([[1, 0, du], [0, 1, dv]])
    return cv2.warpAffine(
        image, matrix, (image.shape[1], image.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
    )


def test_tracks_follow_a_subpixel_shift():
    image = textured_image()
    tracker = FeatureTracker()
    first = tracker.step(image)
    assert len(first.ids) > 100 and first.new.all() and len(first.lost_ids) == 0
    second = tracker.step(shifted(image, 1.7, -0.6))
    tracked = second.tracked
    before = dict(zip(first.ids, first.points, strict=True))
    moves = np.array([p - before[i] for i, p in zip(second.ids[tracked], second.points[tracked], strict=True)])
    interior = np.all((second.points[tracked] > 20) & (second.points[tracked] < [300, 220]), axis=1)
    np.testing.assert_allclose(np.median(moves[interior], axis=0), [1.7, -0.6], atol=0.05)
    assert np.mean(np.linalg.norm(moves[interior] - [1.7, -0.6], axis=1) < 0.2) > 0.9


def test_occluded_features_are_lost_and_new_ones_fill_the_gap():
    image = textured_image(seed=1)
    tracker = FeatureTracker(FeatureSettings(max_features=400))
    first = tracker.step(image)
    covered = image.copy()
    # Something else moves in front; its texture is off the first one's block grid (corners do not coincide).
    covered[60:180, 80:240] = shifted(textured_image(seed=2), 3.5, 4.5)[60:180, 80:240]
    second = tracker.step(covered)
    inside = lambda p: (p[:, 0] > 85) & (p[:, 0] < 235) & (p[:, 1] > 65) & (p[:, 1] < 175)  # noqa: E731
    hidden_ids = first.ids[inside(first.points)]
    assert len(hidden_ids) > 20
    assert np.isin(hidden_ids, second.lost_ids).mean() > 0.9  # forward-backward rejects them
    assert np.isin(second.ids[second.tracked], hidden_ids).sum() <= 0.1 * len(hidden_ids)
    assert inside(second.points[second.new]).sum() > 20  # the new texture gets new corners
    assert len(np.intersect1d(second.ids[second.new], first.ids)) == 0  # new features get new ids
    # The lost ones are the last frame's ids not live now, in increasing order.
    np.testing.assert_array_equal(second.lost_ids, np.setdiff1d(first.ids, second.ids))
    third = tracker.step(image)  # the covered texture is gone again: its corners are lost in turn
    assert len(third.lost_ids) > 20
    np.testing.assert_array_equal(third.lost_ids, np.setdiff1d(second.ids, third.ids))


def test_new_corners_keep_their_distance_from_live_tracks():
    image = textured_image(seed=3)
    settings = FeatureSettings(min_distance_px=6.0)
    tracker = FeatureTracker(settings)
    tracker.step(image)
    frame = tracker.step(shifted(image, 0.5, 0.5))
    tracked, new = frame.points[frame.tracked], frame.points[frame.new]
    if len(new) and len(tracked):
        gaps = np.linalg.norm(new[:, None] - tracked[None], axis=2).min(axis=1)
        assert gaps.min() >= 6.0 - 1.0  # the detection mask is drawn at whole pixels
    assert len(frame.ids) <= settings.max_features
    assert len(np.unique(frame.ids)) == len(frame.ids)


def test_features_leaving_the_image_are_lost():
    image = textured_image(seed=4)
    tracker = FeatureTracker()
    first = tracker.step(image)
    second = tracker.step(shifted(image, -12.0, 0.0))
    near_left = first.ids[first.points[:, 0] < 8]
    assert len(near_left) > 0 and np.isin(near_left, second.lost_ids).all()
    assert (second.points[:, 0] >= 0).all()


def test_a_plain_image_has_no_features():
    frame = FeatureTracker().step(np.full((240, 320, 3), 40, np.uint8))
    assert len(frame.ids) == 0 and frame.points.shape == (0, 2)


@pytest.mark.parametrize("radius", [1, 5, 9])
def test_the_mask_away_from_live_tracks_is_every_disc_drawn_by_opencv(radius):
    rng = np.random.default_rng(radius)
    shape = (60, 90)
    centres = np.rint(rng.uniform([-4, -4], [shape[1] + 3, shape[0] + 3], size=(150, 2))).astype(int)  # some off it
    drawn = np.full(shape, 255, np.uint8)
    for u, v in centres:
        cv2.circle(drawn, (int(u), int(v)), radius, 0, thickness=-1)
    np.testing.assert_array_equal(away_from(shape, centres, radius), drawn)
    np.testing.assert_array_equal(away_from(shape, centres[:0], radius), np.full(shape, 255, np.uint8))


def test_corners_are_found_on_the_detection_box_as_on_the_whole_image():
    """`FeatureTracker` detects on `detection_box` alone: the same corners, in the same order, as
    ``cv2.goodFeaturesToTrack`` on the whole image with the whole mask: textured patches on a plain background,
    in the middle and reaching the image's edges, with live tracks masked out; a noisy image (its whole rectangle);
    a plain one (no corner)."""
    rng = np.random.default_rng(6)
    settings = FeatureSettings(max_features=150)
    cropped = 0
    for case in range(24):
        gray = np.full((120, 160), 40, np.uint8)
        for _ in range(rng.integers(1, 4)):
            v0, u0 = rng.integers(-10, 110), rng.integers(-10, 150)
            patch = cv2.GaussianBlur((rng.random((30, 30)) * 255).astype(np.uint8), (3, 3), 0.8)
            rows, columns = slice(max(v0, 0), min(v0 + 30, 120)), slice(max(u0, 0), min(u0 + 30, 160))
            gray[rows, columns] = patch[: rows.stop - rows.start, : columns.stop - columns.start]
        if case == 0:
            gray = (rng.random(gray.shape) * 255).astype(np.uint8)  # noise everywhere
        existing = rng.uniform(0, [160, 120], (rng.integers(0, 30), 2))
        mask = away_from(gray.shape, np.rint(existing).astype(int), int(np.ceil(settings.min_distance_px)))
        whole = cv2.goodFeaturesToTrack(
            gray,
            settings.max_features - len(existing),
            settings.quality_level,
            settings.min_distance_px,
            mask=mask,
            blockSize=settings.block_size,
        )
        expected = np.empty((0, 2)) if whole is None else whole.reshape(-1, 2).astype(np.float64)
        found = FeatureTracker(settings)._detect(gray, existing)
        v0, v1, u0, u1 = detection_box(gray, 4)
        cropped += (v1 - v0) * (u1 - u0) < gray.size
        assert len(expected) > 0
        assert found.tobytes() == expected.tobytes(), case
    assert cropped >= 12
    assert len(FeatureTracker(settings)._detect(np.full((40, 50), 9, np.uint8), np.empty((0, 2)))) == 0
    assert detection_box(np.full((40, 50), 9, np.uint8), 4) is None
