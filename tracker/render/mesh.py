"""What the renderer draws: a triangle mesh in world coordinates with an optional texture and a part label."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class SurfaceMesh:
    """One part's mesh, world frame.

    vertices, normals: ``(n, 3)`` float64 (normals may be None for unlit use: z-buffer, labels);
    faces: ``(m, 3)`` int, counter-clockwise seen from outside; uv: ``(n, 2)`` texture coordinates in [0, 1]
    (or None); texture: ``(h, w, 3)`` uint8 (or None); color: ``(3,)`` uint8 base colour used when there is no
    texture; label: the value this part takes in the label image (1..255). ``key`` names the part across frames
    so the renderer uploads its texture once.
    """

    key: str
    label: int
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None  # None: unlit use only (z-buffer, labels)
    color: tuple[int, int, int]
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, weld: np.ndarray | None = None) -> np.ndarray:
    """Area-weighted unit vertex normals ``(n, 3)`` of a triangle mesh. ``weld`` (optional, ``(n,)``) maps each
    vertex to the one whose position it repeats (a seam or a pole): repeated vertices share one normal."""
    weld = np.arange(len(vertices)) if weld is None else weld
    corners = vertices[faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    accumulated = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(accumulated, weld[faces[:, corner]], face_normals)
    normals = accumulated[weld]
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.where(length > 0, length, 1.0)
