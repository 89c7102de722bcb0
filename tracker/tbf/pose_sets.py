"""Where pose samples come from (paper 2, 3.1: motion capture, "mainly side-on with the right arm moved variously").

`arm_grid` walks both arms of the standing body over grids of angles (`tracker.motion.posture.arms_pose`);
`tracker.motion.arm_capture` gives a capture session of the side-on person moving the right arm in various ways;
`clip_samples` takes every frame of CMU-style BVH clips at a chosen rate, each clip turned to face ``yaw_deg`` at
its first frame and centred over the origin. Either gives pose vectors; `remove_near_duplicates` then
keeps no two within ``min_joint_deg`` in every joint (the paper's rule), for `tracker.tbf.samples.load_or_build`.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_NAMES
from tracker.motion.mocap import MocapScene
from tracker.motion.posture import arms_pose
from tracker.tol import ZERO_LENGTH


def arm_grid(
    body: BodyMesh,
    swing_deg: Sequence[float],
    abduction_deg: Sequence[float],
    elbow_deg: Sequence[float],
    left_swing_deg: Sequence[float] = (0.0,),
    left_abduction_deg: float = 8.0,
    yaw_deg: float = -90.0,
) -> np.ndarray:
    """``(n, POSE_SIZE)``: the right arm at every (swing, abduction, elbow) of the grids, for each left-arm swing."""
    combinations = itertools.product(left_swing_deg, swing_deg, abduction_deg, elbow_deg)
    return np.array([arms_pose(body, right=(swing, abduction, elbow), left=(left, left_abduction_deg, 0.0),
                               yaw_deg=yaw_deg) for left, swing, abduction, elbow in combinations])  # fmt: skip


def clip_samples(body: BodyMesh, paths: Iterable[str | Path], fps: float = 30.0, yaw_deg: float = -90.0) -> np.ndarray:
    """``(n, POSE_SIZE)``: every frame of each clip at ``fps``."""
    return np.concatenate([MocapScene(str(path), fps=fps, yaw_deg=yaw_deg).poses(body) for path in paths])


def varied(poses: np.ndarray, turns_deg: Sequence[float], copies: int, jitter_deg: float,
           rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """Procedural variation of ``poses``: each turned in place about the vertical by every angle of
    ``turns_deg``, and for each of those ``copies`` more with every joint rotated by a random rotation vector
    of ``jitter_deg`` standard deviation per component (the root's position kept)."""
    out = []
    for turn in turns_deg:
        turned = np.array(poses, dtype=np.float64)
        spin = Rotation.from_euler("z", np.radians(turn))
        turned[:, 3:6] = (spin * Rotation.from_rotvec(turned[:, 3:6])).as_rotvec()
        out.append(turned)
        for _ in range(copies):
            jittered = turned.copy()
            joints = Rotation.from_rotvec(jittered[:, 6:].reshape(-1, 3))
            noise = Rotation.from_rotvec(rng.normal(0.0, np.radians(jitter_deg), (len(joints), 3)))
            jittered[:, 6:] = (joints * noise).as_rotvec().reshape(len(turned), -1)
            out.append(jittered)
    return np.concatenate(out)


def joint_angle_differences(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., J)`` degrees between the joint rotations of pose vectors ``a`` and ``b`` (broadcast)."""
    qa, qb = _quaternions(a), _quaternions(b)
    cosine = np.abs(np.einsum("...jk,...jk->...j", qa, qb))
    return np.degrees(2 * np.arccos(np.clip(cosine, 0.0, 1.0)))


def _quaternions(poses: np.ndarray) -> np.ndarray:
    poses = np.asarray(poses, dtype=np.float64)
    rotvecs = poses[..., 3:].reshape(*poses.shape[:-1], len(JOINT_NAMES), 3)
    return Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_quat().reshape(*rotvecs.shape[:-1], 4)


CANDIDATE_COMPONENTS = 8  # measured at 58,843 poses: 0.9 s for 8 (50k candidates), 15 s for all 124


def remove_near_duplicates(poses: np.ndarray, min_joint_deg: float = 5.0) -> np.ndarray:
    """Indices of the poses kept, in order: a pose is dropped when a kept one is within ``min_joint_deg`` in
    every joint (the paper's rule). Root positions are not compared.

    Two poses within ``angle`` in every joint have joint quaternions (signs made consistent) within
    ``2 sin(angle / 4)`` in every component, so also in any few of them: candidates come from a KD-tree over the
    `CANDIDATE_COMPONENTS` components that vary most (a KD-tree over all of them is slow in so many dimensions),
    each candidate pair is then checked exactly (all at once), and the greedy pass walks the close pairs in order:
    O(n log n) rather than O(n^2)."""
    quaternions = _quaternions(poses)  # (n, J, 4)
    quaternions *= np.where(quaternions[..., 3:4] < 0, -1.0, 1.0)  # same hemisphere: w >= 0
    flat = quaternions.reshape(len(quaternions), -1)
    radius = 2 * np.sin(np.radians(min_joint_deg) / 4) + ZERO_LENGTH
    varied = np.argsort(flat.std(axis=0))[-CANDIDATE_COMPONENTS:]
    pairs = cKDTree(flat[:, varied]).query_pairs(r=radius, p=np.inf, output_type="ndarray")  # (m, 2): i < j
    threshold = np.cos(np.radians(min_joint_deg) / 2)
    close = np.ones(len(pairs), bool)
    for first in range(0, len(pairs), 1 << 16):  # in blocks: m x J x 4 at once would be large
        block = pairs[first : first + (1 << 16)]
        dots = np.abs(np.einsum("kjc,kjc->kj", quaternions[block[:, 0]], quaternions[block[:, 1]]))
        close[first : first + len(block)] = (dots >= threshold).all(axis=1)
    pairs = pairs[close]
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    bounds = np.searchsorted(pairs[:, 0], np.arange(len(poses) + 1))
    dropped = np.zeros(len(poses), bool)
    for index in np.unique(pairs[:, 0]):  # in order: a pose still kept drops every later pose close to it
        if not dropped[index]:
            dropped[pairs[bounds[index] : bounds[index + 1], 1]] = True
    return np.flatnonzero(~dropped)
