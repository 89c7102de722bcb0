"""Pairs on a triangle mesh (AbIS on the skinned body): a pair's own point is a face and barycentric coordinates.

Where the arm's pair keeps surface coordinates (eta, omega) refined under its feature, a body pair keeps the point
where its feature's viewing ray met the part's surface on the estimate when the pair formed (`ray_hits`): a face
of the mesh and the point's barycentric coordinates in it, so that the point rides on the skinned surface as the
pose changes (`MeshPairs.points`).
"""

from __future__ import annotations

from dataclasses import dataclass

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
    a, b, c = (vertices[faces[tried, k]] for k in range(3))  # (n or 1, tried, 3)
    edge1, edge2 = b - a, c - a
    p = np.cross(directions[:, None, :], edge2)
    determinant = np.einsum("nmd,nmd->nm", p, edge1)
    usable = np.abs(determinant) > ZERO_LENGTH
    inverse = np.where(usable, 1.0 / np.where(usable, determinant, 1.0), 0.0)
    to_origin = camera.position - a
    u = np.einsum("nmd,nmd->nm", p, to_origin) * inverse
    q = np.cross(to_origin, edge1)
    v = np.einsum("nd,nmd->nm", directions, q) * inverse
    depth = np.einsum("nmd,nmd->nm", edge2, q) * inverse  # along the ray, in units of its direction (z)
    inside = usable & (u >= 0) & (v >= 0) & (u + v <= 1) & (depth > 0)
    depth = np.where(inside, depth, np.inf)
    first = np.argmin(depth, axis=1)
    rows = np.arange(n)
    found = np.isfinite(depth[rows, first])
    hit_face[found] = np.broadcast_to(tried, depth.shape)[rows, first][found]
    u_hit, v_hit = u[rows, first][found], v[rows, first][found]
    barycentric[found] = np.column_stack([1 - u_hit - v_hit, u_hit, v_hit])
    return hit_face, barycentric
