"""The articulated tree shared by every model: parts with a parent, forward kinematics (paper 1 eq 3).

Convention: part k's *local* transform ``(4, 4)`` maps its frame to its parent's frame (the world for a root);
its *world* transform maps its frame to the world. Transforms stacks are ``(n_parts, 4, 4)`` float64, indexed by
part. A parent always has a smaller index than its children (checked), so index order is a top-down order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tracker.geometry.rotations import euler_to_matrix, invert_rigid, rigid_transform


@dataclass(frozen=True)
class KinematicTree:
    """Part names and parent indices (``None`` for a root)."""

    names: tuple[str, ...]
    parents: tuple[int | None, ...]

    def __post_init__(self) -> None:
        if len(self.names) != len(self.parents):
            raise ValueError(f"{len(self.names)} part names but {len(self.parents)} parents")
        for index, parent in enumerate(self.parents):
            if parent is not None and not 0 <= parent < index:
                raise ValueError(
                    f"part {self.names[index]!r} (index {index}) has parent {parent}: a parent must be an earlier part"
                )

    def __len__(self) -> int:
        return len(self.names)

    def children(self, part: int) -> list[int]:
        return [k for k, parent in enumerate(self.parents) if parent == part]

    def topdown_order(self) -> list[int]:
        """Depth-first from each root, parent before its children, siblings in index order (paper 1, 4.2.2)."""
        order: list[int] = []

        def visit(part: int) -> None:
            order.append(part)
            for child in self.children(part):
                visit(child)

        for root in (k for k, parent in enumerate(self.parents) if parent is None):
            visit(root)
        return order


def forward_kinematics(tree: KinematicTree, local: np.ndarray) -> np.ndarray:
    """``(n, 4, 4)`` local transforms -> ``(n, 4, 4)`` world transforms (eq 3, composed down the tree)."""
    world = np.empty_like(local)
    for part, parent in enumerate(tree.parents):  # parents precede children
        world[part] = local[part] if parent is None else world[parent] @ local[part]
    return world


def local_from_world(tree: KinematicTree, world: np.ndarray) -> np.ndarray:
    """Inverse of `forward_kinematics`: each part's transform relative to its parent."""
    local = np.empty_like(world)
    for part, parent in enumerate(tree.parents):
        local[part] = world[part] if parent is None else invert_rigid(world[parent]) @ world[part]
    return local


def jointed_translation(rotation: np.ndarray, joint_in_parent: np.ndarray, joint_in_child: np.ndarray) -> np.ndarray:
    """The translation c that puts the child's joint point onto the parent's: ``c = j_parent - R j_child``."""
    return joint_in_parent - rotation @ joint_in_child


def local_transforms(params: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
    """Stack of local transforms from per-part ``(..., c1, c2, c3, r1, r2, r3)`` (the last 6 entries of each row)."""
    params = np.asarray(params, dtype=np.float64)
    return np.stack([rigid_transform(euler_to_matrix(row[-3:]), row[-6:-3]) for row in params])
