"""Distances from points to a triangle mesh: the nearest point on the surface, not the nearest vertex.

`point_triangle_distance` is Ericson's closest point on a triangle (Real-Time Collision Detection, 5.1.5), for many
point-triangle pairs at once. `point_mesh_distance` tries each point against the triangles whose centroids are
nearest to it (`CANDIDATES`, from a KD-tree) and keeps that answer where it is provably the nearest: a triangle
whose centroid is farther than ``r`` from the point is at least ``r - R`` away, ``R`` the largest distance from a
centroid to its own corners. The other points are tried against every triangle whose centroid lies within their
best distance plus ``R``, so the result is exact. The largest triangles form a group of their own (their ``R``
would make the shortcut fail for every point).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

CANDIDATES = 16  # triangles tried first per point, by centroid distance
LARGE_QUANTILE = 0.97  # triangles larger than this share of them are tried against every point


def point_triangle_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(n,)`` distance from each point ``(n, 3)`` to its triangle ``(a, b, c)`` (each ``(n, 3)``)."""
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = points - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = points - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = va + vb + vc
        closest = a + (vb / denominator)[:, None] * ab + (vc / denominator)[:, None] * ac  # inside the face
        regions = [  # (condition, closest point), the first that holds wins: Ericson's order
            ((d1 <= 0) & (d2 <= 0), a),
            ((d3 >= 0) & (d4 <= d3), b),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab),
            ((d6 >= 0) & (d5 <= d6), c),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac),
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b)),
        ]
    decided = np.zeros(len(points), bool)
    for condition, point in regions:
        take = condition & ~decided
        closest[take] = point[take]
        decided |= take
    return np.linalg.norm(points - closest, axis=1)


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", u, v)


def point_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(n,)`` distance from each point to the nearest point of the mesh's surface (exact; see the module).

    The few largest triangles (beyond `LARGE_QUANTILE` of the centroid-to-corner radii, e.g. a cap's fan) are
    searched on their own, so that ``R`` for the others stays small and the shortcut mostly holds."""
    points = np.asarray(points, dtype=np.float64)
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (m, 3, 3)
    centroids = corners.mean(axis=1)
    radii = np.linalg.norm(corners - centroids[:, None], axis=2).max(axis=1)
    large = radii > np.quantile(radii, LARGE_QUANTILE)
    best = np.full(len(points), np.inf)
    for group in (np.flatnonzero(large), np.flatnonzero(~large)):
        if len(group):
            best = np.minimum(best, _nearest_in(points, corners, centroids, radii, group))
    return best


def _nearest_in(
    points: np.ndarray, corners: np.ndarray, centroids: np.ndarray, radii: np.ndarray, group: np.ndarray
) -> np.ndarray:
    """``(n,)`` exact distance from each point to the nearest of the triangles ``group``."""
    tree, reach = cKDTree(centroids[group]), float(radii[group].max())
    k = min(CANDIDATES, len(group))
    centroid_distance, nearest = (a.reshape(len(points), k) for a in tree.query(points, k=k))
    distance = _pairs(points, corners, np.repeat(np.arange(len(points)), k), group[nearest.ravel()])
    best = distance.reshape(len(points), k).min(axis=1)
    unsure = np.flatnonzero(best > centroid_distance[:, -1] - reach) if k < len(group) else np.array([], int)
    if len(unsure):  # a triangle beyond the candidates might be nearer: try every one that could be, at once
        near = tree.query_ball_point(points[unsure], best[unsure] + reach)
        counts = np.array([len(triangles) for triangles in near])
        triangles = group[np.concatenate([np.asarray(t, dtype=np.int64) for t in near])]
        distance = _pairs(points, corners, np.repeat(unsure, counts), triangles)
        best[unsure] = np.minimum(best[unsure], np.minimum.reduceat(distance, np.r_[0, np.cumsum(counts)[:-1]]))
    return best


def _pairs(points: np.ndarray, corners: np.ndarray, point_index: np.ndarray, triangle_index: np.ndarray) -> np.ndarray:
    return point_triangle_distance(points[point_index], *(corners[triangle_index, j] for j in range(3)))
