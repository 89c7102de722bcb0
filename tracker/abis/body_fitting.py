"""Fitting one body part to its pairs (AbIS on the skinned body): paper 1's eq 8 over the part's own joints.

A body part (`tracker.models.body_skeleton.PART_BONES`) is moved by the rotation vectors of its bones' joints
(`part_joints`; the pelvis also by the root's position). Fitting is top-down over the part tree (`part_parents`,
`topdown_parts`): each part's joints are fitted with every ancestor's freshly fitted pose held, as the arm's parts
are. The pairs' points are skinned surface points (barycentric in a face, `tracker.abis.mesh_pairs`), whose
Jacobian is the skinned vertices' analytic one (`tracker.models.skinning_jacobian`) blended by the barycentric weights,
each made in one compiled pass (`tracker.models.pose_kernels`; numpy's calls on a few hundred vertices took over ten
times as long); the cost, its robust rho, the prior rows and the optimiser are the arm's (`tracker.abis.fitting`).
Rotation vectors are stepped additively: the Jacobian is by their components.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numba
import numpy as np

from tracker.abis.fitting import PixelProblem, Prior
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_INDEX, PART_BONES, POSE_SIZE
from tracker.models.pose_kernels import add_vertex_levers, bone_chain, bone_offsets, joint_axes
from tracker.tol import MIN_DEPTH_M, ZERO_LENGTH

ROOT_POSITION = np.arange(3)  # the pose vector's root position entries


def part_joints() -> list[np.ndarray]:
    """Per part (`PART_NAMES` order), the joints whose rotations move it relative to its parent part."""
    return [np.array([JOINT_INDEX[bone] for bone in bones]) for bones in PART_BONES.values()]


def part_parents(joint_parents: np.ndarray) -> list[int | None]:
    """Per part, its parent part: the part holding its first joint's parent joint (None for the root's part)."""
    joints = part_joints()
    part_of_joint = {int(joint): part for part, own in enumerate(joints) for joint in own}
    return [None if joint_parents[own[0]] < 0 else part_of_joint[int(joint_parents[own[0]])] for own in joints]


def topdown_parts(parents: Sequence[int | None]) -> list[int]:
    """Parts parent before children, depth first from the root's part, siblings in part order."""
    order: list[int] = []

    def visit(part: int) -> None:
        order.append(part)
        for child in (k for k, parent in enumerate(parents) if parent == part):
            visit(child)

    for root in (k for k, parent in enumerate(parents) if parent is None):
        visit(root)
    return order


def carried_parts(parents: Sequence[int | None], part: int) -> np.ndarray:
    """``part`` and every part below it in the part tree (``parents``: each part's parent part)."""
    below = [part]
    for child in (k for k, parent in enumerate(parents) if parent == part):
        below.extend(carried_parts(parents, child))
    return np.array(sorted(below))


def free_columns(joints: np.ndarray, root: bool) -> np.ndarray:
    """The pose vector's entries a part fits: its joints' rotation vectors, and the root position for the root."""
    rotations = (3 + 3 * joints[:, None] + np.arange(3)).ravel()
    return np.concatenate([ROOT_POSITION, rotations]) if root else rotations


@dataclass(frozen=True, eq=False)
class MeshViewPairs:
    """One view's pairs of the part: each pair's face corners ``(m, 3)`` (vertex indices), barycentric coordinates
    ``(m, 3)`` and observed feature pixels ``(m, 2)``."""

    camera: Camera
    corners: np.ndarray
    barycentric: np.ndarray
    observed: np.ndarray


class BodyPartProblem(PixelProblem):
    """A body part's pairs (and prior) as functions of its joints' entries of the pose vector."""

    def __init__(
        self, body: BodyMesh, views: Sequence[MeshViewPairs], joints: np.ndarray, root: bool, prior: Prior | None = None
    ) -> None:
        views = [view for view in views if len(view.corners)]
        super().__init__(
            [view.camera for view in views], [view.observed for view in views], free_columns(joints, root), prior
        )
        self.body, self.joints, self.root = body, np.asarray(joints, dtype=np.int64), root
        corners = np.concatenate([view.corners for view in views]) if views else np.empty((0, 3), int)
        self._barycentric = np.concatenate([view.barycentric for view in views]) if views else np.empty((0, 3))
        # Each vertex skinned once however many pairs' faces share it.
        self._vertices, inverse = np.unique(corners, return_inverse=True)
        self._corners = inverse.reshape(corners.shape).astype(np.int64)
        self._below = np.ascontiguousarray(body.descendants[self.joints].T)  # (J, K): the bones each joint turns
        cameras = [view.camera for view in views]  # each pair's view's camera, as the compiled passes read it
        self._view_of_pair = np.repeat(np.arange(len(views), dtype=np.int64), [len(view.corners) for view in views])
        self._camera_positions = np.array([c.position for c in cameras], dtype=np.float64).reshape(-1, 3)
        self._camera_rotations = np.array([c.rotation for c in cameras], dtype=np.float64).reshape(-1, 3, 3)
        self._intrinsics = np.array([[c.fx, c.fy, c.cx, c.cy] for c in cameras], dtype=np.float64).reshape(-1, 4)
        weights = body.sparse_weights  # what both compiled passes read after the pose's chain: skinning, pairs' faces
        self._skinned = (body.rest_heads, weights.indptr, weights.indices, weights.data, body.rest_vertices)
        self._skinned += (self._vertices, self._corners, self._barycentric)

    def points(self, q: np.ndarray) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        q = np.array(q, dtype=np.float64)  # as asked, whatever becomes of the caller's array
        rotations, heads = self._chain(q)
        return self._points_at(rotations, heads), lambda: self.points_jacobian(q, rotations, heads)

    def points_jacobian(self, q: np.ndarray, rotations: np.ndarray, heads: np.ndarray) -> np.ndarray:
        """``(M, 3, n_free)``: the pair points' Jacobian at ``q``, whose chain is ``rotations`` and ``heads``."""
        alignment = self.body.t_pose_alignment
        return _pair_jacobian(q, rotations, heads, alignment, self.joints, self._below, self.root, *self._skinned)

    def pixel_terms(
        self, q: np.ndarray, huber_px: float | None
    ) -> tuple[np.ndarray, float, np.ndarray, Callable[[], np.ndarray]]:
        """`PixelProblem.pixel_terms` in one compiled pass, and the rows in another: the points, their pixels
        (`Camera.project`), the residuals and eq 7-8's cost and weights (a pixel behind a camera: NaN)."""
        q = np.array(q, dtype=np.float64)
        rotations, heads = self._chain(q)
        views = (self._view_of_pair, self._camera_positions, self._camera_rotations, self._intrinsics)
        huber = np.nan if huber_px is None else float(huber_px)
        residual, cost, weights, in_cameras = _pair_residuals(
            self._points_at(rotations, heads), *views, self._observed_rows, huber
        )

        def rows() -> np.ndarray:
            of_points = self.points_jacobian(q, rotations, heads)
            return _pixel_rows(in_cameras, of_points, self._view_of_pair, self._camera_rotations, self._intrinsics)

        return residual, cost, weights, rows

    def _chain(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return bone_chain(q, self.body.parents, self.body.rest_heads, self.body.t_pose_alignment)

    def _points_at(self, rotations: np.ndarray, heads: np.ndarray) -> np.ndarray:
        """The pair points of the pose whose chain is ``rotations`` and ``heads``."""
        return _pair_points(rotations, heads, *self._skinned)


@numba.njit(cache=True, nogil=True)
def _pair_points(rotations, heads, rest_heads, indptr, indices, weights, rest, vertices, corners, barycentric):
    """``(M, 3)``: each pair's skinned surface point, its face's ``corners`` (into ``vertices``) blended by its
    ``barycentric`` weights, each vertex skinned as `BodyMesh.posed_vertices` does."""
    offsets = bone_offsets(rotations, heads, rest_heads)  # bone b carries x to R_b x + o_b
    skinned = np.zeros((len(vertices), 3))
    for i in range(len(vertices)):
        x = rest[vertices[i]]
        for entry in range(indptr[vertices[i]], indptr[vertices[i] + 1]):
            bone, weight = indices[entry], weights[entry]
            for a in range(3):
                r = rotations[bone, a]
                skinned[i, a] += weight * (r[0] * x[0] + r[1] * x[1] + r[2] * x[2] + offsets[bone, a])
    points = np.zeros((len(corners), 3))
    for m in range(len(corners)):
        for c in range(3):
            for a in range(3):
                points[m, a] += barycentric[m, c] * skinned[corners[m, c], a]
    return points


@numba.njit(cache=True, nogil=True)
def _pair_jacobian(
    pose,
    rotations,
    heads,
    alignment,
    joints,
    below,
    root,
    rest_heads,
    indptr,
    indices,
    weights,
    rest,
    vertices,
    corners,
    barycentric,
):
    """``(M, 3, n_free)``: d (pair point) / d (the root's position if ``root``, then ``joints``' rotation vectors),
    `tracker.models.skinning_jacobian.vertex_jacobian`'s per vertex (``a x L``: a joint's axis by the vertex's
    lever about it) blended as the points are."""
    count = len(joints)
    offsets = bone_offsets(rotations, heads, rest_heads)
    axes = joint_axes(pose, rotations, alignment, joints)
    joint_heads = np.empty((count, 3))
    for k in range(count):
        joint_heads[k] = heads[joints[k]]
    first = 0 if root else 3  # the root's position's columns kept, or not
    of_vertices = np.zeros((len(vertices), 3, 3 + 3 * count))
    levers, reached = np.empty(1 + 3 * count), np.zeros(count, np.bool_)
    for i in range(len(vertices)):
        levers[:] = 0.0
        add_vertex_levers(
            vertices[i], 1.0, rest, indptr, indices, weights, rotations, offsets, joint_heads, below, levers, reached
        )
        for d in range(3):
            of_vertices[i, d, d] = levers[0]
        for k in range(count):
            l0, l1, l2 = levers[1 + 3 * k], levers[2 + 3 * k], levers[3 + 3 * k]
            for c in range(3):
                a0, a1, a2 = axes[k, c, 0], axes[k, c, 1], axes[k, c, 2]
                of_vertices[i, 0, 3 + 3 * k + c] = a1 * l2 - a2 * l1
                of_vertices[i, 1, 3 + 3 * k + c] = a2 * l0 - a0 * l2
                of_vertices[i, 2, 3 + 3 * k + c] = a0 * l1 - a1 * l0
    jacobian = np.zeros((len(corners), 3, 3 + 3 * count - first))
    for m in range(len(corners)):
        for c in range(3):
            share, i = barycentric[m, c], corners[m, c]
            for d in range(3):
                for column in range(first, 3 + 3 * count):
                    jacobian[m, d, column - first] += share * of_vertices[i, d, column]
    return jacobian


@numba.njit(cache=True, nogil=True)
def _pair_residuals(points, view_of_pair, positions, rotations, intrinsics, observed, huber_px):
    """Each pair's pixel (`Camera.project` by its view's camera; NaN behind it) less its feature's ``(M, 2)``; eq 8's
    cost, or eq 7's with Huber at ``huber_px`` (NaN: plain squares); each pair's IRLS weight (`robust_cost`); and
    each point in its view's camera frame ``(M, 3)`` (`Camera.world_to_camera`: what `_pixel_rows` reads)."""
    residual, weights, in_cameras = np.empty((len(points), 2)), np.ones(len(points)), np.empty((len(points), 3))
    cost = 0.0
    for m in range(len(points)):
        view = view_of_pair[m]
        turn, at = rotations[view], positions[view]
        rx, ry, rz = points[m, 0] - at[0], points[m, 1] - at[1], points[m, 2] - at[2]
        for a in range(3):
            in_cameras[m, a] = rx * turn[0, a] + ry * turn[1, a] + rz * turn[2, a]
        x, y, z = in_cameras[m, 0], in_cameras[m, 1], in_cameras[m, 2]
        u = v = np.nan
        if z > MIN_DEPTH_M:
            u, v = intrinsics[view, 0] * x / z + intrinsics[view, 2], intrinsics[view, 1] * y / z + intrinsics[view, 3]
        residual[m, 0], residual[m, 1] = u - observed[m, 0], v - observed[m, 1]
        distance = np.sqrt(residual[m, 0] ** 2 + residual[m, 1] ** 2)
        if np.isnan(huber_px) or distance <= huber_px:
            cost += distance**2
        else:
            cost += 2 * huber_px * distance - huber_px**2
        if not np.isnan(huber_px):
            weights[m] = np.nan if np.isnan(distance) else min(1.0, huber_px / max(distance, ZERO_LENGTH))
    return residual, cost, weights, in_cameras


@numba.njit(cache=True, nogil=True, error_model="numpy")  # a point on a camera's plane: inf, as numpy gives
def _pixel_rows(in_cameras, of_points, view_of_pair, rotations, intrinsics):
    """``(2M, n)``: the pairs' pixels' Jacobian, u then v of each, from their points in their cameras' frames
    ``(M, 3)`` (`_pair_residuals`), the points' Jacobian ``(M, 3, n)`` and the projection's
    (`tracker.geometry.cameras.projection_jacobian`)."""
    rows = np.zeros((2 * len(in_cameras), of_points.shape[2]))
    for m in range(len(in_cameras)):
        view = view_of_pair[m]
        turn = rotations[view]
        x, y, z = in_cameras[m, 0], in_cameras[m, 1], in_cameras[m, 2]
        for b in range(3):  # d pixel / d world coordinate b (the camera's axes: the rotation's rows)
            du = intrinsics[view, 0] * (turn[b, 0] * z - x * turn[b, 2]) / z**2
            dv = intrinsics[view, 1] * (turn[b, 1] * z - y * turn[b, 2]) / z**2
            for k in range(of_points.shape[2]):
                rows[2 * m, k] += du * of_points[m, b, k]
                rows[2 * m + 1, k] += dv * of_points[m, b, k]
    return rows


def pose_prior_sigmas(translation_m: float, rotation_rad: float) -> np.ndarray:
    """``(POSE_SIZE,)`` one sigma of change per frame: the root position's, every rotation vector component's."""
    sigmas = np.full(POSE_SIZE, float(rotation_rad))
    sigmas[ROOT_POSITION] = translation_m
    return sigmas
