"""Pinhole cameras: world -> camera (paper 1, eq 5), projection (eq 6), and the one conversion to OpenGL.

Convention:
    Camera frame is OpenCV's: x right, y down, z forward (the viewing direction); metres.
    A camera holds ``rotation`` = R_v, the camera axes expressed in the world (camera -> world, columns x, y, z),
    and ``position`` = T_v, the optical centre in the world. World -> camera: ``p_v = R_v^T (p_world - T_v)``.
    Pixels: ``u = fx x/z + cx``, ``v = fy y/z + cy``; u grows right, v grows down, and the centre of pixel
    (row j, column i) is at ``(u, v) = (i, j)`` (OpenCV's convention; image arrays are indexed ``[v, u]``).
    The paper's eq 6 is the special case ``fx = fy = f``, ``cx = cy = 0``.
    pyrender uses OpenGL's camera frame (x right, y up, z backward) and puts pixel centres at half-integers;
    `opengl_camera` is the only place that converts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tracker.tol import MIN_DEPTH_M, ZERO_LENGTH

# OpenCV camera axes expressed in OpenGL camera axes (and back: the matrix is its own inverse).
_CV_TO_GL_AXES = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True, eq=False)
class Camera:
    """A calibrated pinhole camera. ``rotation`` (3, 3) camera -> world; ``position`` (3,) metres."""

    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    rotation: np.ndarray
    position: np.ndarray

    @property
    def intrinsic_matrix(self) -> np.ndarray:
        """The ``(3, 3)`` matrix K with ``[u, v, 1]^T ~ K p_camera``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def world_to_camera(self, points: np.ndarray) -> np.ndarray:
        """``(n, 3)`` world points -> ``(n, 3)`` camera-frame points (eq 5)."""
        return (np.asarray(points, dtype=np.float64) - self.position) @ self.rotation

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(n, 3)`` world points -> ``(n, 2)`` pixels ``(u, v)`` and ``(n,)`` depth z (eq 6).

        Points with ``z <= MIN_DEPTH_M`` (behind or on the camera) get NaN pixels.
        """
        return _pixels(self.world_to_camera(points), self.fx, self.fy, self.cx, self.cy)


def projection_jacobian(camera: Camera, points: np.ndarray) -> np.ndarray:
    """``(n, 2, 3)``: derivatives of `Camera.project`'s pixels with respect to the world points."""
    return _projection_jacobian(camera.world_to_camera(points), camera.fx, camera.fy, camera.rotation.T)


@dataclass(frozen=True, eq=False)
class ViewsPoints:
    """Points seen by several cameras in one array, ``counts[k]`` of ``cameras[k]`` after those of the cameras before:
    their pixels and the pixels' Jacobian computed once for all, with each point's camera constants, the same numbers
    as each camera's own (`Camera.project`, `projection_jacobian`)."""

    cameras: tuple[Camera, ...]
    rows: tuple[slice, ...]  # each camera's points
    fx: np.ndarray  # (n, 1), each point's camera's; fy, cx, cy likewise
    fy: np.ndarray
    cx: np.ndarray
    cy: np.ndarray
    axes: np.ndarray  # (n, 3, 3): each point's camera's rotation transposed (d p_camera / d p_world)

    @classmethod
    def of(cls, cameras: Sequence[Camera], counts: Sequence[int]) -> ViewsPoints:
        ends = np.cumsum(counts, dtype=int)
        rows = tuple(slice(end - count, end) for end, count in zip(ends, counts, strict=True))

        def each(values) -> np.ndarray:
            return np.repeat(np.asarray(values, dtype=np.float64), counts, axis=0)

        return cls(
            tuple(cameras),
            rows,
            *(each([getattr(camera, name) for camera in cameras])[:, None] for name in ("fx", "fy", "cx", "cy")),
            axes=each([camera.rotation.T for camera in cameras]).reshape(-1, 3, 3),
        )

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World points ``(n, 3)`` -> each in its camera's frame (camera by camera, as `Camera.world_to_camera`)."""
        if not self.cameras:
            return np.empty((0, 3))
        return np.concatenate(
            [camera.world_to_camera(points[rows]) for camera, rows in zip(self.cameras, self.rows, strict=True)]
        )

    def pixels(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`Camera.project` of camera-frame points ``p`` ``(n, 3)`` (`to_camera`), each by its camera."""
        return _pixels(p, self.fx[:, 0], self.fy[:, 0], self.cx[:, 0], self.cy[:, 0])

    def projection_jacobian(self, p: np.ndarray) -> np.ndarray:
        """`projection_jacobian` ``(n, 2, 3)`` at camera-frame points ``p`` (`to_camera`), each by its camera."""
        return _projection_jacobian(p, self.fx, self.fy, self.axes)


def _pixels(p: np.ndarray, fx, fy, cx, cy) -> tuple[np.ndarray, np.ndarray]:
    """Eq 6 of camera-frame points ``(n, 3)``: pixels ``(n, 2)`` (NaN behind the camera) and depths ``(n,)``;
    ``fx`` .. ``cy`` one camera's or each point's ``(n,)``."""
    z = p[:, 2]
    in_front = z > MIN_DEPTH_M
    safe_z = np.where(in_front, z, 1.0)
    uv = np.empty((len(p), 2))  # filled by column: np.stack's own cost outweighs the arithmetic at a few points
    uv[:, 0], uv[:, 1] = fx * p[:, 0] / safe_z + cx, fy * p[:, 1] / safe_z + cy
    uv[~in_front] = np.nan
    return uv, z


def _projection_jacobian(p: np.ndarray, fx, fy, axes: np.ndarray) -> np.ndarray:
    """``(n, 2, 3)`` d pixels / d world point at camera-frame points ``p`` ``(n, 3)``; ``axes`` the rotation
    transposed, ``(3, 3)`` of one camera or ``(n, 3, 3)`` each point's (``fx``, ``fy`` then ``(n, 1)``)."""
    x, y, z = p[:, 0:1], p[:, 1:2], p[:, 2:3]
    jacobian = np.empty((len(p), 2, 3))
    jacobian[:, 0] = fx * (axes[..., 0, :] * z - x * axes[..., 2, :]) / z**2
    jacobian[:, 1] = fy * (axes[..., 1, :] * z - y * axes[..., 2, :]) / z**2
    return jacobian


def look_at(
    name: str,
    position: np.ndarray,
    target: np.ndarray,
    up: np.ndarray,
    *,
    width: int,
    height: int,
    focal_px: float,
) -> Camera:
    """A camera at ``position`` looking at ``target``; ``up`` (world) appears upwards in the image.

    The principal point is the image centre ``((width - 1) / 2, (height - 1) / 2)``.
    """
    position = np.asarray(position, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - position
    if np.linalg.norm(forward) < MIN_DEPTH_M:
        raise ValueError(f"camera {name!r}: position and target coincide ({position.tolist()})")
    z_axis = forward / np.linalg.norm(forward)
    x_axis = np.cross(z_axis, np.asarray(up, dtype=np.float64))  # image y (down) ~ -up, so x = y cross z = z cross up
    if np.linalg.norm(x_axis) < ZERO_LENGTH:
        raise ValueError(f"camera {name!r}: 'up' {np.asarray(up).tolist()} is parallel to the viewing direction")
    x_axis /= np.linalg.norm(x_axis)
    y_axis = np.cross(z_axis, x_axis)  # right-handed: z cross x = y
    rotation = np.stack([x_axis, y_axis, z_axis], axis=1)
    return Camera(
        name=name,
        width=int(width),
        height=int(height),
        fx=float(focal_px),
        fy=float(focal_px),
        cx=(width - 1) / 2.0,
        cy=(height - 1) / 2.0,
        rotation=rotation,
        position=position,
    )


def resized(camera: Camera, width: int, height: int) -> Camera:
    """The same camera with an image of ``width`` x ``height``: the image plane scaled about its corner, so that
    each new pixel covers the old pixels it spans (pixel centres: ``u' = (u + 0.5) s - 0.5``)."""
    sx, sy = width / camera.width, height / camera.height
    return Camera(
        name=camera.name,
        width=int(width),
        height=int(height),
        fx=camera.fx * sx,
        fy=camera.fy * sy,
        cx=(camera.cx + 0.5) * sx - 0.5,
        cy=(camera.cy + 0.5) * sy - 0.5,
        rotation=camera.rotation,
        position=camera.position,
    )


@dataclass(frozen=True)
class OpenGLCamera:
    """What pyrender's ``IntrinsicsCamera`` and camera node need: intrinsics in its pixel convention and a pose."""

    fx: float
    fy: float
    cx: float
    cy: float
    pose: np.ndarray  # (4, 4) OpenGL camera frame -> world


def opengl_camera(camera: Camera) -> OpenGLCamera:
    """Convert an OpenCV-convention camera to pyrender's OpenGL convention (the only conversion in the code).

    Axes: OpenGL's camera frame is OpenCV's with y and z negated. Pixels: OpenGL samples pixel centres at
    half-integers (window coordinate ``i + 0.5`` for column i) and pyrender maps ``cx`` to the window coordinate
    directly, so OpenCV's ``cx`` becomes ``cx + 0.5`` (likewise ``cy``; pyrender flips rows to top-down).
    """
    pose = np.eye(4)
    pose[:3, :3] = camera.rotation @ _CV_TO_GL_AXES
    pose[:3, 3] = camera.position
    return OpenGLCamera(fx=camera.fx, fy=camera.fy, cx=camera.cx + 0.5, cy=camera.cy + 0.5, pose=pose)


def wholly_in_view(labels: np.ndarray) -> bool:
    """Whether a label image holds the whole object: some of it, and none on the image's border (a silhouette cut
    by the border, or an empty one, is not the object's whole outline)."""
    labels = np.asarray(labels)
    border = (labels[0], labels[-1], labels[:, 0], labels[:, -1])
    return bool(labels.any()) and not any(edge.any() for edge in border)
