"""Where pose samples come from (paper 2, 3.1: motion capture, "mainly side-on with the right arm moved variously").

`arm_grid` walks both arms of the standing body over grids of angles (`tracker.motion.posture.arms_pose`);
`tracker.motion.arm_capture` gives a capture session of the side-on person moving the right arm in various ways;
`clip_sequences` takes every frame of BVH clips of any known skeleton (`tracker.motion.retarget`) at a chosen rate,
each clip turned to face ``yaw_deg`` at its first frame and centred over the origin; `varied` turns them about the
vertical and jitters copies, `mirrored` swaps left and right. Either gives pose vectors; `remove_near_duplicates`
then keeps no two within ``min_joint_deg`` in every joint (the paper's rule), for
`tracker.tbf.sample_build.load_or_build`.

Clip poses come in sequences (one per clip and per variation of it): `successors` links each pose to the next
frame of its sequence, and `near_duplicate_representatives` says which kept pose stands for each dropped one, so
that the clips' consecutive frames become transitions between kept samples (`learned_transitions`, for
`tracker.tbf.motion.LearnedTransitions`).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_NAMES, MIRROR_JOINTS, joint_quaternions, turned_about_vertical
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
    return np.array(
        [
            arms_pose(body, right=(swing, abduction, elbow), left=(left, left_abduction_deg, 0.0), yaw_deg=yaw_deg)
            for left, swing, abduction, elbow in combinations
        ]
    )


def clip_sequences(
    body: BodyMesh,
    paths: Iterable[str | Path],
    fps: float = 30.0,
    yaw_deg: float = -90.0,
    true_fps: Sequence[float | None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(n, POSE_SIZE)``: every frame of each clip at ``fps`` (each file read at its ``true_fps`` when given), and
    ``(n,)`` each pose's sequence: the index of its clip."""
    paths = list(paths)
    rates = list(true_fps) if true_fps is not None else [None] * len(paths)
    poses = [
        MocapScene(str(path), fps=fps, yaw_deg=yaw_deg, true_fps=rate).poses(body)
        for path, rate in zip(paths, rates, strict=True)
    ]
    return np.concatenate(poses), np.repeat(np.arange(len(poses)), [len(p) for p in poses])


def mirrored(poses: np.ndarray) -> np.ndarray:
    """``poses`` reflected left for right through the body frame's x = 0 plane: each rotation ``R -> M R M``
    (``M = diag(-1, 1, 1)``; a rotation vector's y and z change sign), the left and right joints swapped, and the
    root's x negated."""
    out = np.array(poses, dtype=np.float64)
    rotations = out[:, 3:].reshape(len(out), len(JOINT_NAMES), 3) * [1.0, -1.0, -1.0]  # a new array
    out[:, 0] *= -1.0
    out[:, 3:] = rotations[:, MIRROR_JOINTS].reshape(len(out), -1)
    return out


def grounded(body: BodyMesh, poses: np.ndarray) -> np.ndarray:
    """``poses`` raised or lowered so that the lowest vertex of their feet stands on the floor, z = 0, as at rest: a
    posture in place stands on the floor. (The DAZ-friendly clips' T-pose frames stand 14-18 cm lower than their
    motion, so their frames would float.)"""
    poses = np.array(poses, dtype=np.float64)
    poses[:, 2] -= body.feet_heights(poses)
    return poses


def successors(sequence: np.ndarray) -> np.ndarray:
    """``(n,)`` the index of each pose's next frame in its sequence (poses in frame order), -1 at a sequence's end."""
    sequence = np.asarray(sequence)
    following = np.full(len(sequence), -1)
    same = sequence[1:] == sequence[:-1]
    following[:-1][same] = np.flatnonzero(same) + 1
    return following


def repeated_sequences(sequence: np.ndarray, blocks: int) -> np.ndarray:
    """The sequences of ``blocks`` variations of poses laid end to end (as `varied` and `mirrored` give them): each
    block's sequences are new ones."""
    sequence = np.asarray(sequence)
    return np.concatenate([sequence + block * (int(sequence.max()) + 1) for block in range(blocks)])


def varied(
    poses: np.ndarray, turns_deg: Sequence[float], copies: int, jitter_deg: float, rng: np.random.Generator
) -> np.ndarray:
    """Procedural variation of ``poses``: each turned in place about the vertical by every angle of
    ``turns_deg``, and for each of those ``copies`` more with every joint rotated by a random rotation vector
    of ``jitter_deg`` standard deviation per component (the root's position kept)."""
    out = []
    for turn in turns_deg:
        turned = turned_about_vertical(poses, np.radians(turn))
        out.append(turned)
        for _ in range(copies):
            jittered = turned.copy()
            joints = Rotation.from_rotvec(jittered[:, 6:].reshape(-1, 3))
            noise = Rotation.from_rotvec(rng.normal(0.0, np.radians(jitter_deg), (len(joints), 3)))
            jittered[:, 6:] = (joints * noise).as_rotvec().reshape(len(turned), -1)
            out.append(jittered)
    return np.concatenate(out)


CANDIDATE_COMPONENTS = 8  # few: a KD-tree slows with its dimensions far more than the exact check of more candidates


def remove_near_duplicates(poses: np.ndarray, min_joint_deg: float = 5.0) -> np.ndarray:
    """Indices of the poses kept, in order: a pose is dropped when a kept one is within ``min_joint_deg`` in
    every joint (the paper's rule). Root positions are not compared (`near_duplicate_representatives`)."""
    return near_duplicate_representatives(poses, min_joint_deg)[0]


def near_duplicate_representatives(poses: np.ndarray, min_joint_deg: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """The indices of the poses kept (`remove_near_duplicates`) and ``(n,)`` for every pose the position among
    them of the kept pose that stands for it: itself, or the first kept pose within ``min_joint_deg`` of it.

    Two poses within ``angle`` in every joint have joint quaternions (signs made consistent) within
    ``2 sin(angle / 4)`` in every component, so also in any few of them: candidates come from a KD-tree over the
    `CANDIDATE_COMPONENTS` components that vary most (a KD-tree over all of them is slow in so many dimensions),
    each candidate pair is then checked exactly (all at once), and the greedy pass walks the close pairs in order:
    O(n log n) rather than O(n^2)."""
    quaternions = joint_quaternions(poses)  # (n, J, 4)
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
    standing_for = np.arange(len(poses))
    for index in np.unique(pairs[:, 0]):  # in order: a pose still kept drops every later pose close to it
        if not dropped[index]:
            close_ones = pairs[bounds[index] : bounds[index + 1], 1]
            fresh = close_ones[~dropped[close_ones]]
            dropped[fresh] = True
            standing_for[fresh] = index
    kept = np.flatnonzero(~dropped)
    position = np.full(len(poses), -1)
    position[kept] = np.arange(len(kept))
    return kept, position[standing_for]


def learned_transitions(successor: np.ndarray, representative: np.ndarray) -> np.ndarray:
    """``(m, 3)`` int: the distinct transitions ``(from, to, count)`` between kept samples that the sequences'
    consecutive frames make (``successor``: `successors` of every pose before removal; ``representative``: its
    kept sample, `near_duplicate_representatives`)."""
    moves = np.flatnonzero(successor >= 0)
    pairs = np.stack([representative[moves], representative[successor[moves]]], axis=1)
    distinct, counts = np.unique(pairs, axis=0, return_counts=True)
    return np.column_stack([distinct, counts]).astype(np.int64)
