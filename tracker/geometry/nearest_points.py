"""The nearest of a set of points in the plane to each of many queries, exactly (not an approximate search).

For the few hundred points of one body's outline in an image and the few hundred edge points of a silhouette, a
k-d tree's build is most of a query's cost; a sweep is cheaper: the points sorted along the axis they spread over
most, each query scans out from its place in that order both ways, until the gap along the axis alone exceeds the
nearest distance found. Of points at the same distance, the first (lowest index) is the nearest.
"""

from __future__ import annotations

import numba
import numpy as np


def nearest_points(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """``(m,)`` int64: for each of ``queries`` ``(m, 2)``, the index of its nearest of ``points`` ``(n, 2)``
    (Euclidean; n >= 1)."""
    if len(points) == 0:
        raise ValueError("nearest_points: no points to search")
    return nearest_points_compiled(
        np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 2)
    )


@numba.njit(cache=True, nogil=True)
def nearest_points_compiled(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """`nearest_points`, for compiled callers: float64 ``points`` ``(n >= 1, 2)`` and ``queries`` ``(m, 2)``."""
    along = 0 if np.ptp(points[:, 0]) >= np.ptp(points[:, 1]) else 1
    order = np.argsort(points[:, along], kind="mergesort")
    sorted_along, sorted_across = points[order, along], points[order, 1 - along]
    first_after = np.searchsorted(sorted_along, queries[:, along])
    nearest = np.empty(len(queries), np.int64)
    for q in range(len(queries)):
        at, across = queries[q, along], queries[q, 1 - along]
        best, found = np.inf, -1
        for step in (1, -1):  # from the query's place upwards, then downwards
            j = first_after[q] if step == 1 else first_after[q] - 1
            while 0 <= j < len(order):
                gap = sorted_along[j] - at
                if gap * gap > best:
                    break
                off = sorted_across[j] - across
                distance = gap * gap + off * off
                if distance < best or (distance == best and order[j] < found):
                    best, found = distance, order[j]
                j += step
        nearest[q] = found
    return nearest
