"""Meshes in a run's recording, written again only when they change shape: a part that only moved gets a
Transform3D of its last logged vertices, so a rigid arm's meshes cost a few transforms a frame."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rerun as rr

from tracker.geometry.rotations import fit_rigid
from tracker.render.mesh import SurfaceMesh
from tracker.tol import RIGID_MESH_M


@dataclass(frozen=True)
class LoggedMesh:
    """A mesh entity as the viewer shows it: ``vertices`` as logged, moved by a logged transform (``moved``) to
    ``shown`` (world, float64)."""

    vertices: np.ndarray
    shown: np.ndarray
    moved: bool


class MeshLog:
    """The meshes logged to one recording stream, per entity."""

    def __init__(self, stream: rr.RecordingStream) -> None:
        self.stream = stream
        self._static: set[str] = set()  # entities whose faces and colour are logged
        self._logged: dict[str, LoggedMesh] = {}

    def log(self, kind: str, meshes: Sequence[SurfaceMesh], rgba: tuple[int, int, int, int] | None = None) -> None:
        """``world/<kind>/<part>``: faces and colour once (static); when the part moved, a Transform3D if it moved
        rigidly from its last logged vertices (a pose change), else its new vertices (a shape change)."""
        for mesh in meshes:
            path = f"world/{kind}/{mesh.key}"
            if path not in self._static:
                colour = rgba if rgba is not None else (*mesh.color, 255)
                self.stream.log(
                    path, rr.Mesh3D.from_fields(triangle_indices=mesh.faces, albedo_factor=colour), static=True
                )
                self._static.add(path)
            logged = self._logged.get(path)
            if logged is not None and np.array_equal(mesh.vertices, logged.shown):
                continue
            transform, residual = fit_rigid(logged.vertices, mesh.vertices) if logged else (None, np.inf)
            if residual <= RIGID_MESH_M:
                self.stream.log(path, rr.Transform3D(translation=transform[:3, 3], mat3x3=transform[:3, :3]))
                self._logged[path] = LoggedMesh(logged.vertices, mesh.vertices, moved=True)
                continue
            # positions only (the viewer shades without normals), and the transform reset in the same row
            vertices = rr.Mesh3D.from_fields(vertex_positions=mesh.vertices.astype(np.float32))
            identity = [rr.Transform3D(translation=np.zeros(3), mat3x3=np.eye(3))] if logged and logged.moved else []
            self.stream.log(path, vertices, *identity)
            self._logged[path] = LoggedMesh(mesh.vertices, mesh.vertices, moved=False)
