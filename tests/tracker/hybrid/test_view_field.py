"""One view's silhouette as the hybrid's fit reads it, cut by the image's border: the border is no edge of the
person, and beyond the image nothing is observed."""

import numpy as np
from scipy.ndimage import binary_erosion, distance_transform_edt, map_coordinates

from tracker.geometry.rigs import cameras
from tracker.hybrid.view_field import ViewField, eroded, gradient_at


def test_a_silhouette_cut_by_the_border_has_no_edge_there_and_nothing_beyond_the_image():
    camera = cameras(width=80, height=60)[0]
    silhouette = np.zeros((60, 80), bool)
    silhouette[10:50, 0:30] = True  # a block out of the image on the left
    field = ViewField(silhouette, camera, edge_points=10_000)
    u, v = field.edge.T
    # The block's top and bottom rows and its right column, not the image's left column.
    assert u.min() == 1 and u.max() == 29 and v.min() == 10 and v.max() == 49
    assert len(field.edge) == 2 * 29 + 38
    # Right of the block: its distance, pointing away; inside: 0; beyond the image's left border: nothing.
    value, gradient = field.sample(np.array([[35.0, 30.0], [10.0, 30.0], [-3.0, 30.0], [-0.4, 30.0]]))
    np.testing.assert_allclose(value, [6.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(gradient[0], [1.0, 0.0])
    np.testing.assert_array_equal(gradient[2], [0.0, 0.0])
    # Below the block, further than the window reaches, a point in the image still reads a distance.
    value, _ = field.sample(np.array([[10.0, 59.0]]))
    assert value[0] == 10.0


def test_a_view_that_lost_the_person_reads_nothing():
    camera = cameras(width=80, height=60)[0]
    field = ViewField(np.zeros((60, 80), bool), camera, edge_points=100)
    value, gradient = field.sample(np.array([[10.0, 10.0], [40.0, 30.0], [-5.0, 3.0]]))
    assert len(field.edge) == 0 and not value.any() and not gradient.any()


def test_the_field_reads_as_scipy_interpolates_it_to_the_bit():
    """`ViewField.sample` against `scipy.ndimage.map_coordinates` (order 1, mode "nearest"), an independent
    implementation, field by field: points inside the window, on its pixels and borders, and beyond it on every side
    (read at the border), on a silhouette blob whose fields vary everywhere."""
    rng = np.random.default_rng(3)
    camera = cameras(width=120, height=90)[0]
    rows, cols = np.mgrid[:90, :120]
    silhouette = (rows - 45) ** 2 / 400 + (cols - 60) ** 2 / 150 + 0.3 * np.sin(cols / 3) < 1
    field = ViewField(silhouette, camera, edge_points=100)
    height, width = field.outside.shape
    local = np.c_[rng.uniform(-8, width + 8, 3000), rng.uniform(-8, height + 8, 3000)]
    local[:400] = np.round(local[:400])  # whole pixels, the window's border among them
    local[400:450, 0], local[450:500, 1] = width - 1, height - 1
    uv = local + field.offset
    uv = uv[np.all((uv >= -0.5) & (uv <= field.image_size - 0.5), axis=1)]  # beyond the image reads 0 (above)
    value, gradient = field.sample(uv)
    coordinates = np.stack([(uv - field.offset)[:, 1], (uv - field.offset)[:, 0]])
    expected = [map_coordinates(f, coordinates, order=1, mode="nearest") for f in (field.outside, *field.gradient)]
    np.testing.assert_array_equal(value, expected[0])
    np.testing.assert_array_equal(gradient, np.stack(expected[1:], axis=1))
    assert len(uv) > 2000 and len(np.unique(value)) > 1000  # not a vacuous comparison


def test_the_distance_fields_are_scipys_exact_transform_to_the_bit():
    """The outside and inside distances (`tracker.tbf.costs.euclidean_distance`) against
    `scipy.ndimage.distance_transform_edt`, on a ragged blob; and a silhouette that fills its whole image, whose
    inside has no outside pixel to measure from."""
    camera = cameras(width=120, height=90)[0]
    rows, cols = np.mgrid[:90, :120]
    silhouette = (rows - 45) ** 2 / 500 + (cols - 60) ** 2 / 300 + 0.4 * np.sin(cols / 2) * np.cos(rows / 3) < 1
    field = ViewField(silhouette, camera, edge_points=100)
    v0, u0 = int(field.offset[1]), int(field.offset[0])
    window = silhouette[v0 : v0 + field.outside.shape[0], u0 : u0 + field.outside.shape[1]]
    np.testing.assert_array_equal(field.outside, distance_transform_edt(~window))
    np.testing.assert_array_equal(field.inside, distance_transform_edt(window))
    assert field.outside.max() > 30 and field.inside.max() > 10
    full = ViewField(np.ones((90, 120), bool), camera, edge_points=100)
    np.testing.assert_array_equal(full.inside, distance_transform_edt(np.ones((90, 120), bool)))


def test_the_erosion_and_the_gradient_at_pixels_are_scipys_and_numpys():
    rng = np.random.default_rng(5)
    mask = rng.random((40, 50)) < 0.7
    np.testing.assert_array_equal(eroded(mask), binary_erosion(mask))
    values = rng.normal(size=(40, 50))
    rows, cols = np.r_[0, 39, 0, 39, rng.integers(0, 40, 200)], np.r_[0, 0, 49, 49, rng.integers(0, 50, 200)]
    expected = np.stack([g[rows, cols] for g in np.gradient(values)[::-1]], axis=1)
    np.testing.assert_array_equal(gradient_at(values, rows, cols), expected)
