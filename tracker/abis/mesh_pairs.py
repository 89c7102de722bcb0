"""Pairs on a triangle mesh (AbIS on the skinned body): a pair's own point is a face and barycentric coordinates.

Where the arm's pair keeps surface coordinates (eta, omega) refined under its feature, a body pair keeps the point
where its feature's viewing ray met the part's surface on the estimate when the pair formed (`ray_hits`): a face
of the mesh and the point's barycentric coordinates in it, so that the point rides on the skinned surface as the
pose changes (`MeshPairs.points`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from tracker.abis.correspondences import PairTable
from tracker.geometry.cameras import Camera
from tracker.tol import ZERO_LENGTH


@dataclass(frozen=True, eq=False)
class MeshPairs(PairTable):
    """A mesh's pairs: ``faces`` ``(k,)`` rows of the mesh's faces, ``barycentric`` ``(k, 3)`` in each (samples:
    the seed vertex each pair formed at)."""

    faces: np.ndarray
    barycentric: np.ndarray

    @classmethod
    def empty(cls) -> MeshPairs:
        return cls(np.empty(0, np.int64), np.empty(0, int), np.empty(0, int), np.empty(0, int), np.empty((0, 3)))

    def corners(self, mesh_faces: np.ndarray) -> np.ndarray:
        """``(k, 3)`` the vertex indices of each pair's face."""
        return mesh_faces[self.faces]

    def points(self, vertices: np.ndarray, mesh_faces: np.ndarray) -> np.ndarray:
        """``(k, 3)`` the pairs' points on the mesh posed as ``vertices`` ``(V, 3)``."""
        return np.einsum("kc,kcd->kd", self.barycentric, vertices[self.corners(mesh_faces)])


def ray_hits(
    camera: Camera, pixels: np.ndarray, vertices: np.ndarray, faces: np.ndarray, nearest: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Where the viewing rays of ``pixels`` ``(n, 2)`` first meet the triangles ``faces`` ``(m, 3)`` (indices into
    ``vertices`` ``(V, 3)``; both sides count): per pixel the row of the face hit (-1 for none) and the hit's
    barycentric coordinates ``(n, 3)`` (Moller-Trumbore). Every ray is tried against every face, or with
    ``nearest``, against the ``nearest`` faces whose projected centroids lie nearest its pixel (a whole body's
    faces: the front face under a pixel is among the few around it)."""
    n = len(pixels)
    hit_face, barycentric = np.full(n, -1), np.zeros((n, 3))
    if n == 0 or len(faces) == 0:
        return hit_face, barycentric
    directions = (
        np.column_stack([(pixels[:, 0] - camera.cx) / camera.fx, (pixels[:, 1] - camera.cy) / camera.fy, np.ones(n)])
        @ camera.rotation.T
    )
    if nearest is None or nearest >= len(faces):
        tried = np.arange(len(faces))[None]  # one row, for every ray
    else:
        uv, _ = camera.project(vertices)
        # the mean of the corners as np.mean adds them, without its cost on (m, 3, 2) arrays
        centroids = np.nan_to_num((uv[faces[:, 0]] + uv[faces[:, 1]] + uv[faces[:, 2]]) / 3, nan=-1e6)
        # built once for a few dozen queries: a tree without balancing or compacting builds faster, finds the same
        tree = cKDTree(centroids, balanced_tree=False, compact_nodes=False)
        tried = tree.query(pixels, k=nearest)[1].reshape(n, nearest)
    return _first_hits(
        np.asarray(camera.position, dtype=np.float64),
        np.ascontiguousarray(directions),
        np.ascontiguousarray(vertices, dtype=np.float64),
        np.ascontiguousarray(faces, dtype=np.int64),
        np.ascontiguousarray(tried, dtype=np.int64),
    )


@numba.njit(cache=True, nogil=True)
def _first_hits(origin, directions, vertices, faces, tried):
    """`ray_hits`' search: per ray from ``origin`` along ``directions[i]``, the faces of ``tried[i]`` (or of its one
    row, for every ray) by Moller-Trumbore, the nearest hit in front kept (the first face tried, of equal depths)."""
    hit_face, barycentric = np.full(len(directions), -1), np.zeros((len(directions), 3))
    for i in range(len(directions)):
        d0, d1, d2 = directions[i, 0], directions[i, 1], directions[i, 2]
        row = tried[i] if len(tried) > 1 else tried[0]
        best, best_u, best_v = np.inf, 0.0, 0.0
        for face in row:
            a, b, c = vertices[faces[face, 0]], vertices[faces[face, 1]], vertices[faces[face, 2]]
            e10, e11, e12 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            e20, e21, e22 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
            p0, p1, p2 = d1 * e22 - d2 * e21, d2 * e20 - d0 * e22, d0 * e21 - d1 * e20  # d x edge2
            determinant = p0 * e10 + p1 * e11 + p2 * e12
            if not abs(determinant) > ZERO_LENGTH:
                continue
            inverse = 1.0 / determinant
            t0, t1, t2 = origin[0] - a[0], origin[1] - a[1], origin[2] - a[2]
            u = (p0 * t0 + p1 * t1 + p2 * t2) * inverse
            q0, q1, q2 = t1 * e12 - t2 * e11, t2 * e10 - t0 * e12, t0 * e11 - t1 * e10  # to_origin x edge1
            v = (d0 * q0 + d1 * q1 + d2 * q2) * inverse
            depth = (e20 * q0 + e21 * q1 + e22 * q2) * inverse  # along the ray, in units of its direction (z)
            if u >= 0 and v >= 0 and u + v <= 1 and depth > 0 and depth < best:
                best, best_u, best_v, hit_face[i] = depth, u, v, face
        if hit_face[i] >= 0:
            barycentric[i, 0], barycentric[i, 1], barycentric[i, 2] = 1 - best_u - best_v, best_u, best_v
    return hit_face, barycentric
