"""Distances from points to a triangle mesh: the nearest point on the surface, not the nearest vertex.

`point_triangle_distance` is Ericson's closest point on a triangle (Real-Time Collision Detection, 5.1.5), for many
point-triangle pairs at once. `point_mesh_distance` is exact: the smallest of those distances over every triangle,
found by a tree over the triangles (`tracker.geometry.triangle_tree`), whose closest point is computed as
`point_triangle_distance` computes it, to the bit. A point nearest to an edge or a corner shared by several triangles
gets their common distance, whichever of them is returned.

A dot product of two 3-vectors adds its products x, z, then y (`dot3`): the order numpy's einsum added them in when
these distances were first measured, written out so that every processor adds them so.
"""

from __future__ import annotations

import numpy as np

from tracker.geometry.triangle_tree import nearest_triangles


def dot3(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(n,)`` dot products of 3-vectors ``(n, 3)``: x, z, then y added (see the module docstring)."""
    return (u[:, 0] * v[:, 0] + u[:, 2] * v[:, 2]) + u[:, 1] * v[:, 1]


def point_triangle_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(n,)`` distance from each point ``(n, 3)`` to its triangle ``(a, b, c)`` (each ``(n, 3)``)."""
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = dot3(ab, ap), dot3(ac, ap)
    bp = points - b
    d3, d4 = dot3(ab, bp), dot3(ac, bp)
    cp = points - c
    d5, d6 = dot3(ab, cp), dot3(ac, cp)
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


def point_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(n,)`` distance from each point ``(n, 3)`` to the nearest point of the mesh's surface (exact: see the
    module); NaN for a point not finite, or a mesh with no finite triangle."""
    return nearest_triangles(points, vertices, faces)[1]
