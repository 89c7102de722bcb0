"""Depth flips: the pose samples one silhouette cannot tell from each other.

Seen by one camera, a person and his mirror image through the vertical plane facing the camera (through his
root, across the line of sight) cast nearly the same silhouette: only perspective tells them apart (the nearer
foot lower in the image, the nearer limbs larger). That mirror image is itself a person's pose, his left and right
swapped: a person facing the camera flips to one turned away, a side view's lead leg to the other leg. A pose's
**flip** is the pose sample nearest that mirror image, by the root-aligned distance of every joint (the squared
distances summed).

The filter moves a share of each frame's prior from every sample to its flip (`tracker.tbf.filter.FilterSettings
.flip_share`): without it, its motion model never reaches the other side, and the side it started on, or slipped
to, lasts the whole clip.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from tracker.geometry.cameras import Camera
from tracker.models.body_skeleton import MIRROR_JOINTS


def mirrored_through(joints: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(n, J, 3)`` root-aligned joint positions (joint 0 the root) mirrored through the plane of ``normal`` (a
    unit vector) through the root, each joint's position given to its mirror twin: the joints of the person whose
    body is that mirror image."""
    aligned = joints - joints[:, :1]
    reflected = aligned - 2.0 * (aligned @ normal)[..., None] * normal
    return reflected[:, list(MIRROR_JOINTS)]


def line_of_sight(camera: Camera, point: np.ndarray) -> np.ndarray:
    """The horizontal unit vector from ``camera`` towards ``point``."""
    direction = np.asarray(point, dtype=np.float64) - camera.position
    direction[2] = 0.0
    length = np.linalg.norm(direction)
    if length == 0:
        raise ValueError("the point is straight below or above the camera: no line of sight across the floor")
    return direction / length


def depth_flips(joints: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(n,)``: each sample's flip (see the module docstring) through the plane of ``normal`` (`line_of_sight`):
    the index of the sample whose root-aligned ``joints`` ``(n, J, 3)`` are nearest its mirror image's (a KD-tree
    over the samples' joints: postures fill few of their ~90 components' directions, and the search is quick)."""
    joints = np.asarray(joints, dtype=np.float64)
    aligned = (joints - joints[:, :1]).reshape(len(joints), -1)
    _, flips = cKDTree(aligned).query(mirrored_through(joints, normal).reshape(len(joints), -1))
    return flips.astype(np.int64)
