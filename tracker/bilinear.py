"""Bilinear sampling of images, compiled: what `scipy.ndimage.map_coordinates` (``order=1, mode="nearest"``)
makes of each, to the bit, for many points of several images (the hybrid's silhouette fields, AbIS's textures)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def bilinear(fields: np.ndarray, local: np.ndarray) -> np.ndarray:
    """``(n, F)`` float64: each of ``fields`` ``(F, h, w)`` (any real type) at the pixels ``local`` ``(n, 2)``
    ``(u, v)``, bilinear; beyond the image, each corner read at the border's pixel. Every field at once, and as
    `scipy.ndimage.map_coordinates` (``order=1, mode="nearest"``) makes each to the bit, in double precision (cast to
    the field's type, as scipy's output is, where that is narrower): its weights ``1 - x`` and ``1 - (1 - x)``, its
    corners row by row, each value times the row's weight, then the column's, added to 0."""
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
