"""Rotations and rigid transforms.

Convention:
    Euler angles ``r = (r1, r2, r3)`` (radians) rotate about the x, y and z axes of the *parent* frame, in that
    order: ``R = Rz(r3) @ Ry(r2) @ Rx(r1)`` (SciPy's extrinsic ``"xyz"``). ``R`` maps child-frame vectors to the
    parent frame. A rigid transform is a ``(4, 4)`` float64 matrix ``T = [[R, t], [0, 1]]`` mapping child-frame
    points to the parent frame: ``p_parent = R @ p_child + t`` (paper 1, eq 3). Point sets are ``(n, 3)`` float64.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation

from tracker.tol import LOG_MAP_ANGLE_RAD, SERIES_ANGLE_RAD, TINY, ZERO_LENGTH

_IDENTITY = np.eye(3)
_IDENTITY.flags.writeable = False
# matrix_to_euler's other branch of the same rotation: (r1 + pi, pi - r2, r3 + pi)
_OTHER_BRANCH_SIGNS, _OTHER_BRANCH_TURNS = np.array([1.0, -1.0, 1.0]), np.full(3, np.pi)


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_to_matrix(r: np.ndarray) -> np.ndarray:
    """``(3,)`` Euler angles -> ``(3, 3)`` rotation ``Rz(r3) @ Ry(r2) @ Rx(r1)``."""
    return _euler_matrix(np.asarray(r, dtype=np.float64).reshape(3).tobytes()).copy()


@functools.lru_cache(maxsize=64)
def _euler_matrix(angles: bytes) -> np.ndarray:
    """`euler_to_matrix` of the three float64 angles in ``angles``, kept for the angles last asked: a fit asks again
    for the rotation of the pose it stands at (AbIS's arm: 18 distinct rotations in 80 calls a frame). Keyed by the
    bytes: the same bits in, the same bits out (-0.0 is not taken for 0.0)."""
    r1, r2, r3 = np.frombuffer(angles, dtype=np.float64)
    return rotation_z(r3) @ rotation_y(r2) @ rotation_x(r1)


def rotation_vector_to_matrix(vector: np.ndarray) -> np.ndarray:
    """``(3,)`` rotation vector (axis times angle) -> ``(3, 3)`` rotation (Rodrigues)."""
    vector = np.asarray(vector, dtype=np.float64)
    angle = np.linalg.norm(vector)
    cross = cross_matrix(vector)
    if angle < ZERO_LENGTH:
        return _IDENTITY + cross
    return _IDENTITY + np.sin(angle) / angle * cross + (1 - np.cos(angle)) / angle**2 * (cross @ cross)


def rotation_vectors_to_matrices(vectors: np.ndarray) -> np.ndarray:
    """``(n, 3)`` rotation vectors -> ``(n, 3, 3)`` rotations (Rodrigues, batched)."""
    vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    angle = np.linalg.norm(vectors, axis=1)[:, None, None]
    cross = cross_matrix(vectors)
    small = angle < SERIES_ANGLE_RAD
    safe = np.where(small, 1.0, angle)
    first = np.where(small, 1.0 - angle**2 / 6, np.sin(safe) / safe)
    second = np.where(small, 0.5 - angle**2 / 24, (1 - np.cos(safe)) / safe**2)
    return _IDENTITY + first * cross + second * (cross @ cross)


def matrices_to_rotation_vectors(rotations: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotations -> ``(n, 3)`` rotation vectors, angle in [0, pi] (`matrix_to_rotation_vector`)."""
    return np.array([matrix_to_rotation_vector(rotation) for rotation in np.asarray(rotations).reshape(-1, 3, 3)])


def matrix_to_rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Inverse of `rotation_vector_to_matrix`, angle in [0, pi]."""
    cos_angle = np.clip((np.trace(rotation) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos_angle)
    skew = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1]])
    if angle < LOG_MAP_ANGLE_RAD:  # sin(angle) ~ angle: first order
        return skew / 2.0
    if np.pi - angle < LOG_MAP_ANGLE_RAD:  # sin(angle) ~ 0: the axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(rotation) + 1.0) / 2.0, 0.0))
        axis *= np.where(skew >= 0, 1.0, -1.0) if np.any(skew) else np.sign(rotation[0] + TINY)
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * np.sin(angle)) * skew


def mean_rotation_vectors(vectors: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``(n, k, 3)`` rotation vectors (n poses of k rotations) and ``(n,)`` weights -> ``(k, 3)``: each rotation's
    weighted chordal L2 mean over the poses (SciPy's ``Rotation.mean``: the unit quaternion q maximising
    ``sum_i w_i (q . q_i)^2``, the principal eigenvector of ``sum_i w_i q_i q_i^T``), batched over the k."""
    vectors = np.asarray(vectors, dtype=np.float64)
    quaternions = Rotation.from_rotvec(vectors.reshape(-1, 3)).as_quat().reshape(*vectors.shape[:2], 4)
    scatter = np.einsum("n,nka,nkb->kab", np.asarray(weights, dtype=np.float64), quaternions, quaternions)
    _, eigenvectors = np.linalg.eigh(scatter)
    return Rotation.from_quat(eigenvectors[:, :, -1]).as_rotvec()


def rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The geodesic angle between two rotations (degrees in [0, 180]): the angle of ``a^T b``."""
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))))


def cross_matrix(vectors: np.ndarray) -> np.ndarray:
    """``[v]_x`` ``(..., 3, 3)`` of vectors ``(..., 3)``, with ``[v]_x w = v x w``."""
    vectors = np.asarray(vectors, dtype=np.float64)
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    matrices = np.zeros(vectors.shape[:-1] + (3, 3))
    matrices[..., 0, 1], matrices[..., 0, 2], matrices[..., 1, 2] = -z, y, -x
    matrices[..., 1, 0], matrices[..., 2, 0], matrices[..., 2, 1] = z, -y, x
    return matrices


_AXES_CROSSED = cross_matrix(np.eye(3))  # [e_i]_x, i = 0, 1, 2


def right_jacobian(vectors: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` J_r of rotation vectors r ``(..., 3)``: ``Exp(r + dr) = Exp(r) Exp(J_r(r) dr)`` to first
    order, i.e. ``I - (1 - cos t) / t^2 [r]_x + (t - sin t) / t^3 [r]_x^2`` for t = |r| (series near 0)."""
    vectors = np.asarray(vectors, dtype=np.float64)
    angle = np.linalg.norm(vectors, axis=-1)[..., None, None]
    cross = cross_matrix(vectors)
    small = angle < SERIES_ANGLE_RAD
    with np.errstate(divide="ignore", invalid="ignore"):
        first = np.where(small, 0.5 - angle**2 / 24, (1 - np.cos(angle)) / angle**2)
        second = np.where(small, 1.0 / 6 - angle**2 / 120, (angle - np.sin(angle)) / angle**3)
    return _IDENTITY - first * cross + second * (cross @ cross)


def local_rotation_derivatives(rotation: np.ndarray) -> np.ndarray:
    """``(3, 3, 3)``: ``[i] = d/dw_i R Exp(w)`` at w = 0, i.e. ``R [e_i]_x`` (increments in the rotated frame)."""
    return rotation @ _AXES_CROSSED


def euler_to_matrix_derivatives(r: np.ndarray) -> np.ndarray:
    """``(3, 3, 3)``: ``[i] = dR/dr_i`` of `euler_to_matrix` (i = 0, 1, 2 for r1, r2, r3)."""
    r1, r2, r3 = np.asarray(r, dtype=np.float64)
    rx, ry, rz = rotation_x(r1), rotation_y(r2), rotation_z(r3)
    return np.stack(
        [
            rz @ ry @ _rotation_derivative(0, r1),
            rz @ _rotation_derivative(1, r2) @ rx,
            _rotation_derivative(2, r3) @ ry @ rx,
        ]
    )


def _rotation_derivative(axis: int, angle: float) -> np.ndarray:
    """d/d angle of the rotation about ``axis``: the generator (cross-product matrix of the axis) times it."""
    generator = np.zeros((3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    generator[j, i], generator[i, j] = 1.0, -1.0
    return generator @ (rotation_x, rotation_y, rotation_z)[axis](angle)


def matrix_to_euler(rotation: np.ndarray, near: np.ndarray | None = None) -> np.ndarray:
    """Inverse of `euler_to_matrix`, with ``r2`` in ``[-pi/2, pi/2]``; at ``|r2| = pi/2`` (gimbal lock) ``r1 = 0``.

    With ``near`` (3,), the angles of the same rotation nearest to it instead: of the two triples every rotation
    has, ``(r1, r2, r3)`` and ``(r1 + pi, pi - r2, r3 + pi)``, each angle taken modulo 2 pi, the closer one. A
    tracked rotation's angles then move continuously, also past ``|r2| = pi/2``.
    """
    m = np.asarray(rotation, dtype=np.float64)
    r2 = np.arcsin(min(max(-m[2, 0], -1.0), 1.0))  # np.clip's value, without its cost on one number
    if np.hypot(m[2, 1], m[2, 2]) < ZERO_LENGTH:  # cos(r2) == 0: only r3 - r1 (or r3 + r1) is defined
        angles = np.array([0.0, r2, np.arctan2(-m[0, 1], m[1, 1])])
    else:
        angles = np.array([np.arctan2(m[2, 1], m[2, 2]), r2, np.arctan2(m[1, 0], m[0, 0])])
    if near is None:
        return angles
    near = np.asarray(near, dtype=np.float64)
    branches = np.empty((2, 3))
    branches[0], branches[1] = angles, angles * _OTHER_BRANCH_SIGNS + _OTHER_BRANCH_TURNS
    branches = near + (branches - near + np.pi) % (2 * np.pi) - np.pi  # each angle nearest to near's
    return branches[np.argmin(np.sum((branches - near) ** 2, axis=1))]


def rigid_transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation and ``(3,)`` translation -> ``(4, 4)`` transform."""
    transform = np.eye(4)
    transform[:3, :3] = rotation
    transform[:3, 3] = translation
    return transform


def invert_rigid(transform: np.ndarray) -> np.ndarray:
    """Inverse of a rigid ``(4, 4)`` transform (exact: transpose of the rotation)."""
    rotation_t = transform[:3, :3].T
    return rigid_transform(rotation_t, -rotation_t @ transform[:3, 3])


def transform_points(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a ``(4, 4)`` transform to ``(n, 3)`` points."""
    return points @ transform[:3, :3].T + transform[:3, 3]


def fit_rigid(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, float]:
    """The rigid transform ``T`` (4, 4) that best maps ``(n, 3)`` points ``source`` onto ``target`` in the least
    squares (Kabsch: the SVD of their centred cross-covariance, a reflection excluded), and the largest distance
    left, ``max_i |T source_i - target_i|``."""
    source_mean, target_mean = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - source_mean).T @ (target - target_mean))
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T)) or 1.0])
    rotation = vt.T @ flip @ u.T
    transform = rigid_transform(rotation, target_mean - rotation @ source_mean)
    residual = float(np.linalg.norm(transform_points(transform, source) - target, axis=1).max())
    return transform, residual
