import numpy as np
from scipy.ndimage import map_coordinates

from tracker.bilinear import bilinear


def test_bilinear_is_scipys_map_coordinates_of_order_one_to_the_bit():
    """Against ``scipy.ndimage.map_coordinates`` (order 1, mode "nearest") of float32 textures and float64 fields:
    points within the image, on whole pixels, in the first pixel (where ``1 - (1 - x)`` is not ``x``), and beyond
    every border; float32 read back in the image's type."""
    rng = np.random.default_rng(12)
    for dtype in (np.float32, np.float64):
        images = (rng.random((3, 37, 53)) * 255).astype(dtype)
        rows, columns = rng.uniform(-4, 41, 3000), rng.uniform(-4, 57, 3000)
        rows[:500], columns[500:1000] = np.round(rows[:500]), np.round(columns[500:1000])
        rows[1000:1500], columns[1500:2000] = rng.uniform(0, 1, (2, 500)) ** 3  # fractions finer than 2^-53
        sampled = bilinear(images, np.column_stack([columns, rows]))
        for k, image in enumerate(images):
            expected = map_coordinates(image, [rows, columns], order=1, mode="nearest")
            assert sampled[:, k].astype(dtype).tobytes() == expected.tobytes()
