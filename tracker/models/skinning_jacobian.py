"""How the skinned body's vertices move with its pose (`BodyMesh.posed_vertices`), analytically: the levers of
each joint's turn on the vertices, and from them the vertices' Jacobian.

The root's position moves every vertex as it moves (the weights sum to 1). Turning joint j's rotation vector r_j by
dr turns every bone below it (j included) about the world axis ``a = F_j J_r(r_j) dr`` through j's posed head h'_j
(F_j: j's world rotation from the T-pose, J_r: `right_jacobian`), so a vertex moves by ``a x L_j`` with its lever
``L_j = sum over those bones b of w_b (p_b - h'_j)``, where ``p_b = R_b (v - h_b) + h'_b`` is the vertex as bone b
alone would carry it. Columns are the root position's three, then each asked joint's three (its rotation vector's
components) in the order asked.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numba
import numpy as np

from tracker.geometry.rotations import right_jacobian
from tracker.models.body_mesh import BodyMesh
from tracker.models.pose_kernels import add_vertex_levers


class SkinningLevers(NamedTuple):
    """For some vertices and joints: each vertex's ``weight_sums`` ``(V,)`` (what the root's position moves it by),
    its ``levers`` ``(V, K, 3)`` about each joint, and each joint's ``axes`` ``(K, 3, 3)``: ``[k, c]`` the world
    axis its rotation vector's component c turns about."""

    weight_sums: np.ndarray
    levers: np.ndarray
    axes: np.ndarray


def skinning_levers(
    body: BodyMesh,
    pose: np.ndarray,
    subset: np.ndarray,
    joints: Iterable[int] | None = None,
    transforms: tuple[np.ndarray, np.ndarray] | None = None,
) -> SkinningLevers:
    """The levers of ``joints`` (None: every joint) on the skinned vertices ``subset`` at ``pose`` (``transforms``:
    the pose's `BodyMesh.bone_transforms`, when the caller has them)."""
    pose = np.asarray(pose, dtype=np.float64)
    rotations, heads = transforms or body.bone_transforms(pose)
    from_t_pose = rotations @ np.transpose(body.t_pose_alignment, (0, 2, 1))  # F_j
    subset = np.asarray(subset, dtype=np.int64)
    joints = np.arange(len(body.parents)) if joints is None else np.fromiter(joints, dtype=np.int64)
    weights = body.sparse_weights
    offsets = heads - np.einsum("jab,jb->ja", rotations, body.rest_heads)  # o_b = h'_b - R_b h_b
    levers = _levers(
        weights.indptr,
        weights.indices,
        weights.data,
        subset,
        body.rest_vertices,
        np.ascontiguousarray(rotations),
        offsets,
        np.ascontiguousarray(heads[joints]),
        np.ascontiguousarray(body.descendants[joints].T),
    )
    weight_sums, levers = levers[:, 0], levers[:, 1:].reshape(len(subset), len(joints), 3)
    rates = right_jacobian(pose[3:].reshape(-1, 3)[joints])
    axes = np.transpose(from_t_pose[joints] @ rates, (0, 2, 1))  # (K, 3, 3): dr's three components -> axes
    return SkinningLevers(weight_sums, levers, axes)


@numba.njit(cache=True, nogil=True)
def _levers(
    indptr: np.ndarray,
    indices: np.ndarray,
    weights: np.ndarray,
    subset: np.ndarray,
    rest: np.ndarray,
    rotations: np.ndarray,
    offsets: np.ndarray,
    joint_heads: np.ndarray,
    below: np.ndarray,
) -> np.ndarray:
    """`skinning_levers`' weight sums and levers, ``(len(subset), 1 + 3 K)``: per vertex of ``subset``
    `add_vertex_levers` (numpy's dense product of every vertex's weights by every bone's carrier took four times as
    long)."""
    levers, reached = np.zeros((len(subset), 1 + 3 * joint_heads.shape[0])), np.zeros(joint_heads.shape[0], np.bool_)
    for i in range(len(subset)):
        add_vertex_levers(
            subset[i], 1.0, rest, indptr, indices, weights, rotations, offsets, joint_heads, below, levers[i], reached
        )
    return levers


def vertex_jacobian(
    body: BodyMesh,
    pose: np.ndarray,
    subset: np.ndarray,
    joints: Iterable[int] | None = None,
    transforms: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """``(len(subset), 3, 3 + 3 * len(joints))``: d v'/d (root position, ``joints``' rotation vectors) of the
    skinned vertices ``subset`` at ``pose`` (``joints`` None: every joint, so the columns are the pose vector's)."""
    weight_sums, levers, axes = skinning_levers(body, pose, subset, joints, transforms)
    jacobian = np.empty((len(weight_sums), 3, 3 + 3 * len(axes)))
    jacobian[:, :, :3] = np.eye(3) * weight_sums[:, None, None]
    # a x lever per vertex, joint and component, one world coordinate d at a time (np.cross's products and
    # differences, without its overhead: this runs at every step of a fit)
    axis, lever = axes[None], levers[:, :, None, :]  # (1, K, 3, 3), (V, K, 1, 3)
    for d, (e, f) in enumerate(((1, 2), (2, 0), (0, 1))):
        jacobian[:, d, 3:] = (axis[..., e] * lever[..., f] - axis[..., f] * lever[..., e]).reshape(len(weight_sums), -1)
    return jacobian
