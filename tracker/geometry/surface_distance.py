"""Distances from points to a triangle mesh: the nearest point on the surface, not the nearest vertex.

`point_triangle_distance` is Ericson's closest point on a triangle (Real-Time Collision Detection, 5.1.5), for many
point-triangle pairs at once. `point_mesh_distance` is exact: libigl's AABB tree over the triangles finds each
point's nearest triangle; the distance is then Ericson's to that triangle and, for a point nearest to its edge or
corner, to every triangle sharing a corner with it (across a seam too, where the mesh repeats vertices and says so:
``weld``), the smallest kept. A point nearest to an edge or a corner is as near to the triangles around it (a tie in
exact arithmetic whose rounding differs from triangle to triangle): whichever of them the tree returns, the same
bits come out as from trying every triangle.

Building the tree is most of a query's time (three quarters, for a few hundred points on a DSQ part's 3648
triangles), so the last `TREES_KEPT` trees are kept (`RigidTrees`): a mesh that is one of them moved rigidly (to
`RIGID_M` at every vertex: a rigid part of a model, its shape unchanged since the frame before) is searched in that
tree, the points moved back onto it; the distances are still taken on the mesh as given. Where two triangles that
are not neighbours tie for a point to the last bits (overlapping triangles with the point on both), the one a tree
returns decides those bits: a kept tree and a new one may differ there by 1e-17 m.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass

import igl
import numpy as np
from scipy import sparse


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


def point_mesh_distance(
    points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, weld: np.ndarray | None = None
) -> np.ndarray:
    """``(n,)`` distance from each point ``(n, 3)`` to the nearest point of the mesh's surface (exact; see the
    module). ``weld``: per vertex, the vertex that stands for its position (a mesh whose seams repeat vertices, as
    `tracker.models.dsq.MeshTopology.weld` says); None: no vertex repeats another."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    nearest, closest = _TREES.nearest(points, vertices, faces)
    a, b, c = (vertices[faces[nearest, j]] for j in range(3))
    # Inside its triangle, a point's nearest point is nearer than any other triangle's; on an edge or at a corner
    # (or on a sliver, whose coordinates are NaN), the triangles around it tie and are tried too.
    on_edge = ~(barycentric(closest, a, b, c).min(axis=1) > ON_EDGE)
    corners = faces if weld is None else np.asarray(weld, dtype=np.int64)[faces]
    ptr, around = _corner_neighbours(corners.tobytes(), len(vertices))
    edge = np.flatnonzero(on_edge)
    first, counts = ptr[nearest[edge]], ptr[nearest[edge] + 1] - ptr[nearest[edge]]
    gathered = np.arange(counts.sum()) + np.repeat(first - (np.cumsum(counts) - counts), counts)
    point = np.r_[np.flatnonzero(~on_edge), np.repeat(edge, counts)]
    triangle = np.r_[nearest[~on_edge], around[gathered]]
    corners = vertices[faces[triangle]]
    best = np.full(len(points), np.inf)
    np.minimum.at(best, point, point_triangle_distance(points[point], corners[:, 0], corners[:, 1], corners[:, 2]))
    return best


ON_EDGE = 1e-6  # a barycentric coordinate this small puts the nearest point on the triangle's edge


def barycentric(points: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(n, 3)`` barycentric coordinates of each point (in its triangle's plane) in its triangle ``(a, b, c)``."""
    ab, ac, ap = b - a, c - a, points - a
    d00, d01, d11 = _dot(ab, ab), _dot(ab, ac), _dot(ac, ac)
    d20, d21 = _dot(ap, ab), _dot(ap, ac)
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = d00 * d11 - d01 * d01
        v, w = (d11 * d20 - d01 * d21) / denominator, (d00 * d21 - d01 * d20) / denominator
    return np.stack([1.0 - v - w, v, w], axis=1)


@functools.lru_cache(maxsize=16)
def _corner_neighbours(face_bytes: bytes, vertex_count: int) -> tuple[np.ndarray, np.ndarray]:
    """For a mesh's faces (their bytes, int64 ``(m, 3)``): every face's own index and those of the faces sharing a
    corner with it, as ``around[ptr[f]:ptr[f + 1]]``."""
    faces = np.frombuffer(face_bytes, dtype=np.int64).reshape(-1, 3)
    incidence = sparse.csr_matrix(
        (np.ones(faces.size, np.int8), (np.repeat(np.arange(len(faces)), 3), faces.ravel())),
        shape=(len(faces), vertex_count),
    )
    shares = (incidence @ incidence.T).tocsr()  # faces sharing at least one corner (and each face itself)
    shares.sort_indices()
    return shares.indptr.astype(np.int64), shares.indices.astype(np.int64)


TREES_KEPT = 8  # the meshes whose AABB trees `point_mesh_distance` keeps (the arm's evaluation asks for six a frame)
RIGID_M = 1e-9  # a mesh within this of another moved rigidly (every vertex, metres) is searched in its tree


class RigidTrees:
    """libigl AABB trees of the last meshes searched, each found again for a mesh that is it moved rigidly."""

    def __init__(self, kept: int = TREES_KEPT) -> None:
        self.kept = kept
        self._trees: list[tuple[bytes, _Centred, igl.AABB]] = []  # the faces' bytes, the vertices, the tree
        self._lock = threading.Lock()  # one caller at a time (a run's evaluation may sit in a thread of a sweep)

    def __len__(self) -> int:
        """The trees kept."""
        return len(self._trees)

    def nearest(self, points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per point (contiguous float64 ``(n, 3)``; the mesh's as contiguous float64 and int64), the index of the
        nearest triangle and the nearest point on it."""
        with self._lock:
            return self._nearest(points, vertices, faces)

    def _nearest(self, points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key, now = faces.tobytes(), _Centred.of(vertices)
        for k, (faces_key, seen, tree) in enumerate(self._trees):
            turn = now.turn_from(seen) if faces_key == key else None
            if turn is not None:
                self._trees.append(self._trees.pop(k))  # the most recent last
                _, nearest, closest = tree.squared_distance(seen.vertices, faces, now.back(points, turn, seen))
                return np.asarray(nearest, dtype=np.int64), seen.back(closest, turn.T, now)
        tree = igl.AABB()
        tree.init(vertices, faces)
        self._trees = [*self._trees, (key, now, tree)][-self.kept :]
        _, nearest, closest = tree.squared_distance(vertices, faces, points)
        return np.asarray(nearest, dtype=np.int64), closest


@dataclass(frozen=True)
class _Centred:
    """A mesh's ``vertices`` ``(V, 3)`` (a copy), their centroid, their ``centred`` coordinates and those's summed
    squares (a rigid motion keeps it)."""

    vertices: np.ndarray
    centroid: np.ndarray
    centred: np.ndarray
    spread: float

    @classmethod
    def of(cls, vertices: np.ndarray) -> _Centred:
        centroid = vertices.mean(axis=0)
        centred = vertices - centroid
        return cls(vertices.copy(), centroid, centred, float(np.einsum("ij,ij->", centred, centred)))

    def turn_from(self, seen: _Centred) -> np.ndarray | None:
        """The rotation R with ``self.centred = seen.centred R^T`` to `RIGID_M` at every vertex, else None (Kabsch:
        the rotation that best maps one onto the other, then checked)."""
        if self.centred.shape != seen.centred.shape or not abs(self.spread - seen.spread) <= 1e-6 * seen.spread:
            return None  # not the same spread about the centroid (or not a number: no tree fits it)
        u, _, vt = np.linalg.svd(seen.centred.T @ self.centred)
        turn = (u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt).T
        return turn if np.abs(seen.centred @ turn.T - self.centred).max() <= RIGID_M else None

    def back(self, points: np.ndarray, turn: np.ndarray, onto: _Centred) -> np.ndarray:
        """``points`` near this mesh moved as it maps onto ``onto`` (``turn``: R of `turn_from`, or its transpose)."""
        return (points - self.centroid) @ turn + onto.centroid


_TREES = RigidTrees()
