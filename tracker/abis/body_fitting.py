"""Fitting one body part to its pairs (AbIS on the skinned body): paper 1's eq 8 over the part's own joints.

A body part (`tracker.models.body_skeleton.PART_BONES`) is moved by the rotation vectors of its bones' joints
(`part_joints`; the pelvis also by the root's position). Fitting is top-down over the part tree (`part_parents`,
`topdown_parts`): each part's joints are fitted with every ancestor's freshly fitted pose held, as the arm's parts
are. The pairs' points are skinned surface points (barycentric in a face, `tracker.abis.mesh_pairs`), whose
Jacobian is the skinned vertices' analytic one (`tracker.models.skinning_jacobian`) blended by the barycentric weights;
the cost, its robust rho, the prior rows and the optimiser are the arm's (`tracker.abis.fitting`). Rotation vectors
are stepped additively: the Jacobian is by their components.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tracker.abis.fitting import PixelProblem, Prior
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh, BoneChain
from tracker.models.body_skeleton import JOINT_INDEX, PART_BONES, POSE_SIZE
from tracker.models.skinning_jacobian import vertex_jacobian

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
        self.body, self.joints = body, joints
        self._columns = slice(0 if root else 3, None)  # `free_columns` among `vertex_jacobian`'s
        corners = np.concatenate([view.corners for view in views]) if views else np.empty((0, 3), int)
        self._barycentric = np.concatenate([view.barycentric for view in views]) if views else np.empty((0, 3))
        # Each vertex skinned once however many pairs' faces share it.
        self._vertices, inverse = np.unique(corners, return_inverse=True)
        self._corners = inverse.reshape(corners.shape)
        self._start: BoneChain | None = None  # the chain of the first pose asked: the others turn only these joints

    def points(self, q: np.ndarray) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        if self._start is None:
            self._start = self.body.chain(q)
        transforms = self.body.chain(q, self._start, self.joints).transforms  # skinning and its Jacobian start here
        vertices = self.body.posed_vertices(q, self._vertices, transforms)
        q = q.copy()  # as asked, whatever becomes of the caller's array

        def jacobian() -> np.ndarray:
            of_vertices = vertex_jacobian(self.body, q, self._vertices, self.joints, transforms)[:, :, self._columns]
            return np.einsum("mc,mcdk->mdk", self._barycentric, of_vertices[self._corners])

        return np.einsum("mc,mcd->md", self._barycentric, vertices[self._corners]), jacobian


def pose_prior_sigmas(translation_m: float, rotation_rad: float) -> np.ndarray:
    """``(POSE_SIZE,)`` one sigma of change per frame: the root position's, every rotation vector component's."""
    sigmas = np.full(POSE_SIZE, float(rotation_rad))
    sigmas[ROOT_POSITION] = translation_m
    return sigmas
