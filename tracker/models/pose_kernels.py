"""One pose of the skinned body (`tracker.models.body_mesh.BodyMesh`) in compiled loops (numba), for the fits that
pose it at every step (`tracker.hybrid.pose_terms`, `tracker.abis.body_fitting`): Rodrigues' rotation, the bone
chain, the bones' offsets, a vertex's levers about the joints and the joints' axes (`tracker.models.skinning_jacobian`
says what they are). The arithmetic is numpy's pipeline's, summed in its own order: the same numbers to rounding,
not to the bit.
"""

from __future__ import annotations

import numba
import numpy as np

from tracker.tol import SERIES_ANGLE_RAD


@numba.njit(cache=True, nogil=True)
def rotation_matrix(vector: np.ndarray, out: np.ndarray) -> None:
    """Rodrigues, as `tracker.geometry.rotations.rotation_vectors_to_matrices`: ``I + a [v]x + b [v]x^2``."""
    x, y, z = vector[0], vector[1], vector[2]
    angle = np.sqrt(x * x + y * y + z * z)
    if angle < SERIES_ANGLE_RAD:
        first, second = 1.0 - angle**2 / 6, 0.5 - angle**2 / 24
    else:
        first, second = np.sin(angle) / angle, (1 - np.cos(angle)) / angle**2
    identity_plus(vector, first, second, out)


@numba.njit(cache=True, nogil=True)
def identity_plus(vector: np.ndarray, first: float, second: float, out: np.ndarray) -> None:
    """``out = I + first [v]x + second [v]x^2`` of ``vector`` v: Rodrigues' form, and the right Jacobian's."""
    x, y, z = vector[0], vector[1], vector[2]
    cross = ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
    for a in range(3):
        for b in range(3):
            square = cross[a][0] * cross[0][b] + cross[a][1] * cross[1][b] + cross[a][2] * cross[2][b]
            out[a, b] = (1.0 if a == b else 0.0) + first * cross[a][b] + second * square


@numba.njit(cache=True, nogil=True)
def product_3x3(left: np.ndarray, right: np.ndarray, out: np.ndarray) -> None:
    """``out = left @ right`` of 3x3 matrices."""
    for a in range(3):
        for b in range(3):
            out[a, b] = left[a, 0] * right[0, b] + left[a, 1] * right[1, b] + left[a, 2] * right[2, b]


@numba.njit(cache=True, nogil=True)
def bone_chain(
    pose: np.ndarray, parents: np.ndarray, rest_heads: np.ndarray, alignment: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """`BodyMesh.bone_transforms` of one pose: each bone's rotation from rest ``(J, 3, 3)`` and posed head
    ``(J, 3)`` (parents come first)."""
    joints = len(parents)
    from_t_pose, rotations, heads = np.empty((joints, 3, 3)), np.empty((joints, 3, 3)), np.empty((joints, 3))
    local = np.empty((3, 3))
    for joint in range(joints):
        rotation_matrix(pose[3 + 3 * joint : 6 + 3 * joint], local)
        parent = parents[joint]
        if parent < 0:
            from_t_pose[joint] = local
            heads[joint] = pose[:3]
        else:
            product_3x3(from_t_pose[parent], local, from_t_pose[joint])
            for a in range(3):
                heads[joint, a] = heads[parent, a]
                for b in range(3):
                    heads[joint, a] += rotations[parent, a, b] * (rest_heads[joint, b] - rest_heads[parent, b])
        product_3x3(from_t_pose[joint], alignment[joint], rotations[joint])
    return rotations, heads


@numba.njit(cache=True, nogil=True)
def bone_offsets(rotations: np.ndarray, heads: np.ndarray, rest_heads: np.ndarray) -> np.ndarray:
    """``(J, 3)``: each bone's o_b = h'_b - R_b h_b, so that it carries a rest point x to ``R_b x + o_b``."""
    offsets = np.empty((len(rotations), 3))
    for bone in range(len(rotations)):
        for a in range(3):
            r = rotations[bone, a]
            offsets[bone, a] = heads[bone, a] - (
                r[0] * rest_heads[bone, 0] + r[1] * rest_heads[bone, 1] + r[2] * rest_heads[bone, 2]
            )
    return offsets


@numba.njit(cache=True, nogil=True)
def joint_axes(pose, rotations, alignment, joints):
    """``(K, 3, 3)``: ``[k, c]`` the world axis about which joint k's rotation vector's component c turns its
    bones, the columns of ``F_j J_r(r_j)`` (F_j: the joint's world rotation from the T-pose)."""
    axes = np.empty((len(joints), 3, 3))
    from_t_pose, rate = np.empty((3, 3)), np.empty((3, 3))
    for k in range(len(joints)):
        joint = joints[k]
        for a in range(3):  # F_j = R_j A_j^T
            for b in range(3):
                from_t_pose[a, b] = (
                    rotations[joint, a, 0] * alignment[joint, b, 0]
                    + rotations[joint, a, 1] * alignment[joint, b, 1]
                    + rotations[joint, a, 2] * alignment[joint, b, 2]
                )
        x, y, z = pose[3 + 3 * joint], pose[4 + 3 * joint], pose[5 + 3 * joint]
        angle = np.sqrt(x * x + y * y + z * z)  # J_r = I - first [r]x + second [r]x^2 (`right_jacobian`)
        if angle < SERIES_ANGLE_RAD:
            first, second = 0.5 - angle**2 / 24, 1.0 / 6 - angle**2 / 120
        else:
            first, second = (1 - np.cos(angle)) / angle**2, (angle - np.sin(angle)) / angle**3
        identity_plus(pose[3 + 3 * joint : 6 + 3 * joint], -first, second, rate)
        for c in range(3):
            for a in range(3):
                axes[k, c, a] = (
                    from_t_pose[a, 0] * rate[0, c] + from_t_pose[a, 1] * rate[1, c] + from_t_pose[a, 2] * rate[2, c]
                )
    return axes


@numba.njit(cache=True, nogil=True)
def add_vertex_levers(
    vertex, share, rest, indptr, indices, weights, rotations, offsets, joint_heads, below, out, reached
):
    """Adds ``share`` times the weight sum and the levers of ``vertex`` to ``out`` ``(1 + 3 K,)`` (``[0]`` the
    weight sum, then each of the K joints' lever), from the skinning weights (CSR: a vertex's few bones), the bones'
    ``rotations`` and ``offsets`` o_b, the joints' posed heads and ``below`` ``(J, K)``, the bones each joint turns:
    each bone b of the vertex carries it to ``p_b = R_b v + o_b`` and adds ``w_b (p_b - h'_k)`` to its lever about
    every joint k above b, which it marks in ``reached`` ``(K,)``."""
    carried = np.empty(3)
    for entry in range(indptr[vertex], indptr[vertex + 1]):
        bone, weight = indices[entry], share * weights[entry]
        out[0] += weight
        for a in range(3):
            r = rotations[bone, a]
            carried[a] = r[0] * rest[vertex, 0] + r[1] * rest[vertex, 1] + r[2] * rest[vertex, 2] + offsets[bone, a]
        for k in range(joint_heads.shape[0]):
            if below[bone, k]:
                reached[k] = True
                for a in range(3):
                    out[1 + 3 * k + a] += weight * (carried[a] - joint_heads[k, a])
