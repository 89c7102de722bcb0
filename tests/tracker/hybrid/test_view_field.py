"""One view's silhouette as the hybrid's fit reads it, cut by the image's border: the border is no edge of the
person, and beyond the image nothing is observed."""

import numpy as np

from tracker.geometry.rigs import cameras
from tracker.hybrid.view_field import ViewField


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
