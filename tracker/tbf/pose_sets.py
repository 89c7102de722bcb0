"""Where pose samples come from (paper 2, 3.1: motion capture, "mainly side-on with the right arm moved variously").

`arm_grid` walks both arms of the standing body over grids of angles (`tracker.motion.body_swing.arms_pose`);
`clip_samples` takes every frame of CMU-style BVH clips at a chosen rate, each clip turned to face ``yaw_deg`` at
its first frame and centred over the origin. Either gives pose vectors for
`tracker.tbf.samples.remove_near_duplicates` and `tracker.tbf.samples.load_or_build`.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from tracker.models.body_mesh import BodyMesh
from tracker.motion.body_swing import arms_pose
from tracker.motion.mocap import MocapScene


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
