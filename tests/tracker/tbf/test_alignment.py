"""Moving the observed silhouette onto the samples' feet, and the estimate's root back by as much."""

import numpy as np
import pytest

from tracker.geometry.cameras import look_at
from tracker.tbf.alignment import feet_anchor, shifted, world_offset


def test_the_feet_are_the_middle_of_the_silhouettes_bottom_rows():
    mask = np.zeros((100, 80), bool)
    mask[10:90, 30:40] = True  # a body
    mask[85:90, 40:56] = True  # a foot forward
    mask[60:70, 40:70] = True  # an arm: not the feet
    u, v = feet_anchor(mask)
    assert v == 89.0
    assert u == np.median(np.arange(30, 56))  # the bottom 6 % (5 rows) span columns 30-55
    assert feet_anchor(np.zeros((4, 4), bool)) is None


@pytest.mark.parametrize(("du", "dv"), [(3, -2), (-5, 4), (0, 0), (120, 0)])
def test_a_shift_moves_every_pixel_and_loses_what_leaves(du, dv):
    rng = np.random.default_rng(0)
    mask = rng.random((30, 40)) < 0.3
    moved = shifted(mask, du, dv)
    expected = np.zeros_like(mask)
    for v, u in zip(*np.nonzero(mask), strict=True):
        if 0 <= v + dv < 30 and 0 <= u + du < 40:
            expected[v + dv, u + du] = True
    assert np.array_equal(moved, expected)


def test_the_world_offset_moves_the_projection_by_the_pixels_asked():
    camera = look_at("main", np.array([4.0, 0.0, 0.9]), np.array([0.0, 0.0, 0.9]), np.array([0.0, 0.0, 1.0]),
                     width=320, height=240, focal_px=480.0)  # fmt: skip
    point = np.array([0.1, -0.2, 0.95])
    offset = world_offset(camera, point, 7.0, -3.0)
    before, _ = camera.project(point[None])
    after, _ = camera.project((point + offset)[None])
    np.testing.assert_allclose(after[0] - before[0], [7.0, -3.0], atol=1e-9)
    depths = camera.world_to_camera(np.array([point, point + offset]))[:, 2]
    assert depths[1] == pytest.approx(depths[0])  # parallel to the image plane
