"""Pairs on a triangle mesh (AbIS on the skinned body): a pair's own point is a face and barycentric coordinates.

Where the arm's pair keeps surface coordinates (eta, omega) refined under its feature, a body pair keeps the point
where its feature's viewing ray met the part's surface on the estimate when the pair formed (`ray_hits`): a face
of the mesh and the point's barycentric coordinates in it, so that the point rides on the skinned surface as the
pose changes (`MeshPairs.points`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
    camera: Camera, pixels: np.ndarray, vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the viewing rays of ``pixels`` ``(n, 2)`` first meet the triangles ``faces`` ``(m, 3)`` (indices into
    ``vertices`` ``(V, 3)``; both sides count): per pixel the row of the face hit (-1 for none) and the hit's
    barycentric coordinates ``(n, 3)`` (Moller-Trumbore, every ray against every face)."""
    n = len(pixels)
    hit_face, barycentric = np.full(n, -1), np.zeros((n, 3))
    if n == 0 or len(faces) == 0:
        return hit_face, barycentric
    directions = (
        np.column_stack([(pixels[:, 0] - camera.cx) / camera.fx, (pixels[:, 1] - camera.cy) / camera.fy, np.ones(n)])
        @ camera.rotation.T
    )
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    edge1, edge2 = b - a, c - a  # (m, 3)
    p = np.cross(directions[:, None, :], edge2[None])  # (n, m, 3)
    determinant = np.einsum("nmd,md->nm", p, edge1)
    usable = np.abs(determinant) > ZERO_LENGTH
    inverse = np.where(usable, 1.0 / np.where(usable, determinant, 1.0), 0.0)
    to_origin = camera.position - a  # (m, 3)
    u = np.einsum("nmd,md->nm", p, to_origin) * inverse
    q = np.cross(to_origin, edge1)  # (m, 3)
    v = np.einsum("nd,md->nm", directions, q) * inverse
    depth = np.einsum("md,md->m", edge2, q)[None] * inverse  # along the ray, in units of its direction (z)
    inside = usable & (u >= 0) & (v >= 0) & (u + v <= 1) & (depth > 0)
    depth = np.where(inside, depth, np.inf)
    nearest = np.argmin(depth, axis=1)
    rows = np.arange(n)
    found = np.isfinite(depth[rows, nearest])
    hit_face[found] = nearest[found]
    u_hit, v_hit = u[rows, nearest][found], v[rows, nearest][found]
    barycentric[found] = np.column_stack([1 - u_hit - v_hit, u_hit, v_hit])
    return hit_face, barycentric
