"""One view's observed silhouette as the hybrid's silhouette fit (`tracker.hybrid.silhouette_fit`) reads it: its
distance field outside the silhouette, with the field's gradient, and its edge points with their outward normals.
Pixels are ``(u, v)``: column, row; pixel ``(u, v)`` covers ``[u - 1/2, u + 1/2] x [v - 1/2, v + 1/2]``.

A person partly out of the view is cut by the image's border: where the silhouette meets the border, the border is
where the view ends, not his outline, so it gives no edge points; and a point beyond the image is seen by no pixel,
so it reads no distance (0, no gradient). A view that lost him altogether reads no distance anywhere: it says only
that he is not in its image, which the views that see him place him by."""

from __future__ import annotations

import numba
import numpy as np
from scipy.ndimage import binary_erosion, distance_transform_edt

from tracker.geometry.cameras import Camera
from tracker.tbf.costs import euclidean_distance


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
        rows, cols = np.nonzero(silhouette)
        low = np.maximum([rows.min(), cols.min()] if len(rows) else [0, 0], self.MARGIN_PX) - self.MARGIN_PX
        high = np.array([rows.max(), cols.max()]) + self.MARGIN_PX + 1 if len(rows) else np.array(silhouette.shape)
        self.offset = np.array([low[1], low[0]], dtype=np.float64)  # the window's corner, (u, v)
        window = silhouette[low[0] : high[0], low[1] : high[1]]
        outside = euclidean_distance(~window) if window.any() else np.zeros(window.shape)  # none: no term
        self._sampled = np.stack([outside, *np.gradient(outside)[::-1]])  # what `sample` reads, one array
        self.outside, self.gradient = self._sampled[0], self._sampled[1:]  # (h, w); (d/du, d/dv), each (h, w)
        rows, cols = np.nonzero(window & ~binary_erosion(window))
        on_border = (rows + low[0] == 0) | (rows + low[0] == silhouette.shape[0] - 1)
        on_border |= (cols + low[1] == 0) | (cols + low[1] == silhouette.shape[1] - 1)
        rows, cols = rows[~on_border], cols[~on_border]
        step = max(1, int(np.ceil(len(rows) / edge_points)))
        rows, cols = rows[::step], cols[::step]
        self.edge = np.stack([cols, rows], axis=1) + self.offset  # (n, 2) pixels (u, v)
        # The outward normal at each edge point: the gradient of the signed distance (outside minus inside).
        # (a window all inside has no pixel to measure from: scipy's transform then measures from beyond its border)
        self.inside = euclidean_distance(window) if not window.all() else distance_transform_edt(window)
        normals = np.stack([g[rows, cols] for g in np.gradient(self.outside - self.inside)[::-1]], axis=1)
        self.edge_normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)

    def sample(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``outside`` and its ``(n, 2)`` gradient at pixels ``uv`` (bilinear; beyond the window, its border's;
        beyond the image, 0)."""
        sampled = bilinear(self._sampled, np.ascontiguousarray(uv - self.offset, dtype=np.float64))
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


@numba.njit(cache=True, nogil=True)
def bilinear(fields: np.ndarray, local: np.ndarray) -> np.ndarray:
    """``(n, F)``: each of ``fields`` ``(F, h, w)`` at the window's pixels ``local`` ``(n, 2)`` ``(u, v)``, bilinear;
    beyond the window, each corner read at the border's pixel. Every field at once, and as
    `scipy.ndimage.map_coordinates` (``order=1, mode="nearest"``) makes each to the bit: its weights ``1 - x`` and
    ``1 - (1 - x)``, its corners row by row, each value times the row's weight, then the column's, added to 0."""
    height, width = fields.shape[1], fields.shape[2]
    sampled = np.empty((len(local), len(fields)))
    corners, weights = np.empty((2, 2), np.int64), np.empty((2, 2))  # a point's, by axis (row, column)
    for k in range(len(local)):
        for axis, (at, size) in enumerate(((local[k, 1], height), (local[k, 0], width))):
            first = np.floor(at)
            for corner in range(2):  # beyond the border, the border's pixel
                corners[axis, corner] = min(max(np.int64(first) + corner, 0), size - 1)
            weights[axis, 0] = 1.0 - (at - first)
            weights[axis, 1] = 1.0 - weights[axis, 0]
        for f in range(len(fields)):
            total = 0.0
            for a in range(2):
                for b in range(2):
                    total += fields[f, corners[0, a], corners[1, b]] * weights[0, a] * weights[1, b]
            sampled[k, f] = total
    return sampled
