"""Distances from points to a triangle mesh: the nearest point on the surface, not the nearest vertex.

`point_triangle_distance` is Ericson's closest point on a triangle (Real-Time Collision Detection, 5.1.5), for many
point-triangle pairs at once. `point_mesh_distance` is exact, with far fewer pairs than every point against every
triangle: each point is first tried against the `CANDIDATES` triangles whose centroids are nearest to it, which
bounds its distance from above (``best``); then against every other triangle that could be nearer. No point of a
triangle is farther from its centroid than its farthest corner (its radius ``r``), so only a triangle whose
centroid lies within ``best + r`` of the point can be nearer. The triangles are grouped by radius, each group's
radii within a factor of `RADIUS_STEP`, and each group's centroids are searched (a KD-tree) within ``best`` plus its
largest radius: slivers and fans do not widen the search for the rest.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

CANDIDATES = 4  # triangles tried first per point, by centroid distance: the distance's first upper bound
RADIUS_STEP = 2.0  # a group of triangles spans radii within this factor
SPHERE_SLACK_M = 1e-9  # a triangle counts as possibly nearer within this: rounding never drops the nearest


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
    """``(n,)`` distance from each point ``(n, 3)`` to the nearest point of the mesh's surface (exact; see the
    module)."""
    points = np.asarray(points, dtype=np.float64)
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (m, 3, 3)
    centroids = corners.mean(axis=1)
    radii = np.linalg.norm(corners - centroids[:, None], axis=2).max(axis=1)
    k = min(CANDIDATES, len(corners))
    _, nearest = cKDTree(centroids).query(points, k=k)
    nearest = np.asarray(nearest).reshape(len(points), k)
    best = _pairs(points, corners, np.repeat(np.arange(len(points)), k), nearest.ravel()).reshape(-1, k).min(axis=1)
    for group in _radius_groups(radii):
        lists = cKDTree(centroids[group]).query_ball_point(points, best + radii[group].max() + SPHERE_SLACK_M)
        point = np.repeat(np.arange(len(points)), [len(found) for found in lists])
        triangle = group[np.fromiter(itertools.chain.from_iterable(lists), np.int64, len(point))]
        near = (
            np.linalg.norm(points[point] - centroids[triangle], axis=1) - radii[triangle]
            <= best[point] + SPHERE_SLACK_M
        )
        point, triangle = point[near], triangle[near]
        if len(point):
            np.minimum.at(best, point, _pairs(points, corners, point, triangle))
    return best


def _radius_groups(radii: np.ndarray) -> list[np.ndarray]:
    """The triangles' indices in groups of radii within a factor of `RADIUS_STEP` (degenerate ones with the
    smallest)."""
    smallest = max(float(radii[radii > 0].min()) if np.any(radii > 0) else 1.0, 1e-300)
    level = np.floor(np.log(np.maximum(radii, smallest) / smallest) / np.log(RADIUS_STEP)).astype(np.int64)
    return [np.flatnonzero(level == value) for value in np.unique(level)]


def _pairs(points: np.ndarray, corners: np.ndarray, point_index: np.ndarray, triangle_index: np.ndarray) -> np.ndarray:
    return point_triangle_distance(points[point_index], *(corners[triangle_index, j] for j in range(3)))
