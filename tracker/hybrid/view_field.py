"""One view's observed silhouette as the hybrid's silhouette fit (`tracker.hybrid.silhouette_fit`) reads it: its
distance field outside the silhouette, with the field's gradient, and its edge points with their outward normals.
Pixels are ``(u, v)``: column, row; pixel ``(u, v)`` covers ``[u - 1/2, u + 1/2] x [v - 1/2, v + 1/2]``.

A person partly out of the view is cut by the image's border: where the silhouette meets the border, the border is
where the view ends, not his outline, so it gives no edge points; and a point beyond the image is seen by no pixel,
so it reads no distance (0, no gradient). A view that lost him altogether reads no distance anywhere: it says only
that he is not in its image, which the views that see him place him by."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt

from tracker.bilinear import bilinear
from tracker.geometry.cameras import Camera
from tracker.tbf.costs import bounding_box, euclidean_distance


class ViewField:
    """One view's observed silhouette as the fit reads it: its outside distance field (pixels) with its gradient,
    sampled bilinearly, and its edge points (at most ``edge_points``, evenly along the pixel list) with their outward
    normals. The fields are computed in a window of the image around the silhouette, ``MARGIN_PX`` wider on every
    side (beyond it, a point reads the window's border: further than the robust scale, so its direction is what
    counts). The image's border is no edge, and beyond the image nothing is observed (see the module docstring)."""

    MARGIN_PX = 32

    def __init__(self, silhouette: np.ndarray, camera: Camera, edge_points: int) -> None:
        silhouette = np.asarray(silhouette, dtype=bool)
        self.camera = camera
        self.image_size = np.array(silhouette.shape[::-1], dtype=np.float64)  # (width, height)
        box = bounding_box(silhouette)
        seen = box[0].stop > box[0].start
        low = np.maximum([box[0].start, box[1].start] if seen else [0, 0], self.MARGIN_PX) - self.MARGIN_PX
        high = np.array([box[0].stop, box[1].stop]) + self.MARGIN_PX if seen else np.array(silhouette.shape)
        self.offset = np.array([low[1], low[0]], dtype=np.float64)  # the window's corner, (u, v)
        window = silhouette[low[0] : high[0], low[1] : high[1]]
        outside = euclidean_distance(~window) if window.any() else np.zeros(window.shape)  # none: no term
        self.sampled = np.stack([outside, *np.gradient(outside)[::-1]])  # (3, h, w): what `sample` reads
        self.outside, self.gradient = self.sampled[0], self.sampled[1:]  # (h, w); (d/du, d/dv), each (h, w)
        rows, cols = np.nonzero(window & ~eroded(window))
        on_border = (rows + low[0] == 0) | (rows + low[0] == silhouette.shape[0] - 1)
        on_border |= (cols + low[1] == 0) | (cols + low[1] == silhouette.shape[1] - 1)
        rows, cols = rows[~on_border], cols[~on_border]
        step = max(1, int(np.ceil(len(rows) / edge_points)))
        rows, cols = rows[::step], cols[::step]
        self.edge = np.stack([cols, rows], axis=1) + self.offset  # (n, 2) pixels (u, v)
        # The outward normal at each edge point: the gradient of the signed distance (outside minus inside).
        # (a window all inside has no pixel to measure from: scipy's transform then measures from beyond its border)
        self.inside = euclidean_distance(window) if not window.all() else distance_transform_edt(window)
        normals = gradient_at(self.outside - self.inside, rows, cols)
        self.edge_normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)

    def sample(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``outside`` and its ``(n, 2)`` gradient at pixels ``uv`` (bilinear; beyond the window, its border's;
        beyond the image, 0)."""
        sampled = bilinear(self.sampled, np.ascontiguousarray(uv - self.offset, dtype=np.float64))
        value, gradient = sampled[:, 0], sampled[:, 1:]
        unseen = np.any((uv < -0.5) | (uv > self.image_size - 0.5), axis=1)
        if unseen.any():
            value[unseen], gradient[unseen] = 0.0, 0.0
        return value, gradient

    def inside_px(self, uv: np.ndarray) -> np.ndarray:
        """Each pixel's distance inside the silhouette (0 outside it; the nearest pixel's)."""
        local = np.rint(uv - self.offset).astype(np.int64)
        height, width = self.inside.shape
        within = (local[:, 0] >= 0) & (local[:, 0] < width) & (local[:, 1] >= 0) & (local[:, 1] < height)
        distance = np.zeros(len(uv))
        distance[within] = self.inside[local[within, 1], local[within, 0]]
        return distance


_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def eroded(mask: np.ndarray) -> np.ndarray:
    """``mask`` eroded by the 4-neighbour cross, beyond the border outside (`scipy.ndimage.binary_erosion`'s
    default)."""
    return cv2.erode(mask.view(np.uint8), _CROSS, borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)


def gradient_at(values: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``(n, 2)``: `np.gradient` of ``values`` ``(h, w)`` at its pixels ``rows``, ``cols`` as ``(d/du, d/dv)``,
    without the whole image's: central differences, one-sided on the border (h, w >= 2)."""
    height, width = values.shape
    gradient = np.empty((len(rows), 2))
    for axis, (index, size) in enumerate(((cols, width), (rows, height))):
        after, before = np.minimum(index + 1, size - 1), np.maximum(index - 1, 0)
        ahead = values[rows, after] if axis == 0 else values[after, cols]
        behind = values[rows, before] if axis == 0 else values[before, cols]
        gradient[:, axis] = (ahead - behind) / np.where((index > 0) & (index < size - 1), 2.0, 1.0)
    return gradient
