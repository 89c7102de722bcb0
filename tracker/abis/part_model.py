"""One part's model samples as a function of the parameters AbIS fits, with their Jacobian (paper 1, eq 3-8).

The part being fitted sees its parent's world transform as fixed (estimation is top-down, 4.2.2). Its free
parameters (`free_parameter_names`):
    root  - all 17 of eq 4: the 11 shape parameters, c (world translation) and r;
    child - the 11 shape parameters and r; its c follows from the joint (its bottom pole on the parent's top
            pole, as `tracker.models.dsq_arm.DSQArm.connect` places it), so the joint stays connected:
            ``p_parent = j_parent + R(r) (s(q) - j_child(q))``.
Jacobians are ``(n, 3, n_free)`` for world points and ``(n, 2, n_free)`` for pixels. Their rotation columns are
by the Euler angles r (``local_rotation=False``) or, for fitting, by a rotation increment w in the part's own frame,
``R(r) Exp(w)`` at w = 0: eq 4's Euler angles lose a degree of freedom at r2 = +-pi/2 (the upper arm's pose
points its axis along +x with r2 = pi/2), an increment never does.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tracker.geometry.rotations import euler_to_matrix, euler_to_matrix_derivatives, local_rotation_derivatives
from tracker.models.dsq import (
    PARAM_INDEX,
    PARAM_NAMES,
    SHAPE_NAMES,
    SurfaceTrig,
    dsq_points_at,
    dsq_points_jacobian_at,
)

_C = slice(PARAM_INDEX["c1"], PARAM_INDEX["c3"] + 1)
_R = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)
_BOTTOM_POLE = (np.array([-math.pi / 2]), np.zeros(1))


def free_parameter_names(is_root: bool) -> tuple[str, ...]:
    return PARAM_NAMES if is_root else (*SHAPE_NAMES, "r1", "r2", "r3")


def free_parameter_indices(is_root: bool) -> np.ndarray:
    """Positions of the free parameters in the 17-vector q."""
    return np.array([PARAM_INDEX[name] for name in free_parameter_names(is_root)])


def posed_coordinates(eta: np.ndarray, omega: np.ndarray, is_root: bool) -> SurfaceTrig:
    """The trigonometry `part_world_points` poses: the samples at (eta, omega), and for a child its bottom pole
    (its joint) riding along as the last point: one evaluation, not two."""
    if not is_root:
        eta, omega = np.append(eta, _BOTTOM_POLE[0]), np.append(omega, _BOTTOM_POLE[1])
    return SurfaceTrig.of(eta, omega)


def part_world_points(
    q: np.ndarray,
    coordinates: SurfaceTrig,
    parent_world: np.ndarray | None = None,
    joint_in_parent: np.ndarray | None = None,
    local_rotation: bool = False,
) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
    """World points ``(n, 3)`` of the samples at ``coordinates`` (`posed_coordinates`), and what makes their
    Jacobian over the free parameters ``(n, 3, n_free)`` when asked.

    For a root pass neither ``parent_world`` nor ``joint_in_parent``; for a child pass the parent's ``(4, 4)``
    world transform and the joint in the parent's frame (its top pole).
    """
    q = np.array(q, dtype=np.float64)  # a copy: the Jacobian is made later, whatever becomes of the caller's array
    rotation = euler_to_matrix(q[_R])
    local = dsq_points_at(q, coordinates)
    if parent_world is None:
        points = local @ rotation.T + q[_C]
    else:
        relative = local[:-1] - local[-1]
        in_parent = relative @ rotation.T + joint_in_parent
        points = in_parent @ parent_world[:3, :3].T + parent_world[:3, 3]

    def jacobian() -> np.ndarray:
        if local_rotation:
            rotation_derivatives = local_rotation_derivatives(rotation)
        else:
            rotation_derivatives = euler_to_matrix_derivatives(q[_R])
        local_jacobian = dsq_points_jacobian_at(q, coordinates)  # (n, 3, 11)
        if parent_world is None:
            shape_jacobian = np.einsum("ij,njk->nik", rotation, local_jacobian)
            translation_jacobian = np.broadcast_to(np.eye(3), (len(local), 3, 3))
            rotation_jacobian = np.einsum("kij,nj->nik", rotation_derivatives, local)
            return np.concatenate([shape_jacobian, translation_jacobian, rotation_jacobian], axis=2)
        parent_rotation = parent_world[:3, :3]
        shape_jacobian = np.einsum("ij,njk->nik", parent_rotation @ rotation, local_jacobian[:-1] - local_jacobian[-1])
        rotation_jacobian = np.einsum("ij,kjl,nl->nik", parent_rotation, rotation_derivatives, relative)
        return np.concatenate([shape_jacobian, rotation_jacobian], axis=2)

    return points, jacobian
