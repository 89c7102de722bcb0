"""Where a tree filter's pose samples come from (`tracker.tbf.settings.TbfSettings.samples`): a grid of right-arm
poses, a capture session of the right arm moving, and/or BVH clips of any known skeleton with procedural variation
(mirrored, turned, jittered), near-duplicates removed (`tracker.tbf.pose_sets`). `sample_poses` gives the poses
and the transitions the clips' consecutive frames make between them (for ``motion=learned``).
"""

from __future__ import annotations

import glob
import hashlib
from dataclasses import dataclass, field
from fnmatch import fnmatch
from pathlib import Path
from typing import Annotated

import numpy as np

from tracker.data import data_dir, data_files, data_path
from tracker.memo import file_digest, memoized
from tracker.models.body_mesh import BodyMesh
from tracker.motion.arm_capture import ArmRanges, capture_poses
from tracker.ranges import Finite, Fraction, NonNegative, Positive, Range, Seed, Span
from tracker.settings import to_plain
from tracker.tbf.pose_sets import (
    arm_grid,
    clip_sequences,
    grounded,
    learned_transitions,
    mirrored,
    near_duplicate_representatives,
    repeated_sequences,
    successors,
    varied,
)

DegreeSpan = Span  # in degrees


def span_values(span: tuple[float, float, float]) -> np.ndarray:
    """A `Span`'s values: start to stop (included) by step."""
    start, stop, step = span
    return np.arange(start, stop + step / 2, step)


@dataclass(frozen=True)
class GridSpec:
    """The right-arm grid (`tracker.tbf.pose_sets.arm_grid`): ranges as ``[start, stop, step]`` degrees, stop
    included; lists of values for the left arm's swing and the body's yaw."""

    swing_deg: DegreeSpan = (-60.0, 120.0, 6.0)  # in front (+) / behind (-) the vertical
    abduction_deg: DegreeSpan = (0.0, 40.0, 8.0)
    elbow_deg: DegreeSpan = (0.0, 60.0, 30.0)
    left_swing_deg: tuple[Finite, ...] = (0.0, 20.0)
    yaw_deg: tuple[Finite, ...] = (-100.0, -90.0, -80.0)

    def poses(self, body: BodyMesh) -> np.ndarray:
        return np.concatenate(
            [
                arm_grid(
                    body,
                    span_values(self.swing_deg),
                    span_values(self.abduction_deg),
                    span_values(self.elbow_deg),
                    self.left_swing_deg,
                    yaw_deg=yaw,
                )
                for yaw in self.yaw_deg
            ]
        )


@dataclass(frozen=True)
class CaptureSpec:
    """Samples as paper 2's capture gave them (`tracker.motion.arm_capture`): a continuous session of the side-on
    person moving the right arm in various ways over the ranges (``[low, high]`` degrees) while standing naturally
    (`tracker.motion.posture.NATURAL_SPREAD` times ``amplitude``), every frame at ``fps``; drawn from ``seed``."""

    seconds: Annotated[float, Range(0.1, 36000.0)] = 120.0
    fps: Positive = 30.0
    swing_deg: tuple[Finite, Finite] = (-60.0, 120.0)
    abduction_deg: tuple[Finite, Finite] = (0.0, 40.0)
    elbow_deg: tuple[Finite, Finite] = (0.0, 90.0)
    yaw_deg: Finite = -90.0
    amplitude: Fraction = 1.0
    seed: Seed = 0

    def poses(self, body: BodyMesh) -> np.ndarray:
        ranges = ArmRanges(self.swing_deg, self.abduction_deg, self.elbow_deg)
        return capture_poses(
            body, ranges, self.seconds, self.fps, self.yaw_deg, self.amplitude, np.random.default_rng(self.seed)
        )


@dataclass(frozen=True)
class TrueRate:
    """The capture rate of the clips matching ``files`` (a data path with wildcards) whose header is wrong."""

    files: str
    fps: Positive


@dataclass(frozen=True)
class SampleSpec:
    """Where the pose samples come from: a grid, a capture session of the right arm moving, and/or BVH clips
    with procedural variation."""

    grid: GridSpec | None = field(default_factory=GridSpec)
    capture: CaptureSpec | None = None
    # BVH files of any known skeleton (data paths, wildcards allowed): every frame at clip_fps, facing
    # clip_yaw_deg at its start. With motion=learned, clip_fps is the tracking rate the transitions are learned at.
    clips: tuple[str, ...] = ()
    clip_true_fps: tuple[TrueRate, ...] = ()  # clips whose header states a wrong frame rate
    clip_fps: Positive = 10.0
    clip_yaw_deg: Finite = -90.0
    # Postures only: every clip pose's root moved over the origin, its feet on the floor (`pose_sets.grounded`).
    clip_in_place: bool = True
    clip_mirror: bool = False  # procedural variation: each clip pose also mirrored left for right ...
    clip_turns_deg: tuple[Finite, ...] = (0.0,)  # ... and each of those turned by these about the vertical ...
    # ... and this many copies of each with every joint jittered by clip_jitter_deg per axis.
    clip_copies: Annotated[int, Range(0, 1000)] = 0
    clip_jitter_deg: NonNegative = 10.0
    seed: Seed = 0  # of the jitter
    min_joint_deg: NonNegative = 5.0  # near-duplicates (within this in every joint) are removed


def clip_files(spec: SampleSpec, key: str = "tracker") -> list[tuple[int, str, float | None]]:
    """Every clip file ``spec.clips`` names: the entry it comes from, the file (the entry itself when it holds no
    wildcards) and its true rate (`SampleSpec.clip_true_fps`); ``ValueError`` names an entry that matches no file."""
    files = []
    for index, pattern in enumerate(spec.clips):
        found = [pattern] if not glob.has_magic(pattern) else [str(path) for path in data_files(pattern)]
        if not found:
            raise ValueError(
                f"{key}.samples.clips[{index}]={pattern}: no file matches it in the data directory {data_dir()}"
            )
        files += [(index, path, true_rate(path, spec.clip_true_fps)) for path in found]
    return files


def true_rate(path: str, rates: tuple[TrueRate, ...]) -> float | None:
    """The capture rate of the clip at data path ``path`` by the first of ``rates`` whose files match it (both
    resolved in the data directory), or None: its header's rate holds."""
    return next((rate.fps for rate in rates if fnmatch(str(data_path(path)), str(data_path(rate.files)))), None)


def cached_sample_poses(spec: SampleSpec, body: BodyMesh, cache_dir: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """`sample_poses`, kept in ``cache_dir`` between processes (a capture session's poses take seconds to make),
    under a key of the spec, the body's shape, the clips' contents and the core's code (`tracker.memo`)."""
    clips = [file_digest(data_path(path)) for _, path, _ in clip_files(spec)] if spec.clips else []
    inputs = {"sample poses": to_plain(spec), "body": body.source_key, "clips": clips}
    stored = memoized(
        cache_dir, inputs, lambda: dict(zip(("poses", "transitions"), sample_poses(spec, body), strict=True))
    )
    return stored["poses"], stored["transitions"]


def cached_joint_positions(body: BodyMesh, poses: np.ndarray, cache_dir: str | Path) -> np.ndarray:
    """``body.joint_positions(poses)``, kept in ``cache_dir`` between processes under a key of the body's shape, the
    poses' bytes and the core's code (`tracker.memo`): the evaluation's floor reads a dictionary's after every run,
    and tens of thousands of poses take longer to pose than to read back."""
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    inputs = {"joint positions": body.source_key, "poses": hashlib.sha256(poses.tobytes()).hexdigest()}
    return memoized(cache_dir, inputs, lambda: {"joints": body.joint_positions(poses)})["joints"]


def sample_poses(spec: SampleSpec, body: BodyMesh) -> tuple[np.ndarray, np.ndarray]:
    """The pose samples ``spec`` names, near-duplicates removed (before rendering), and the clips' consecutive
    frames as transitions between them (`learned_transitions`)."""
    parts = []
    if spec.grid is not None:
        parts.append(spec.grid.poses(body))
    if spec.capture is not None:
        parts.append(spec.capture.poses(body))
    following = [np.full(len(part), -1) for part in parts]  # no sequences learned from these
    if spec.clips:
        _, paths, rates = zip(*clip_files(spec), strict=True)
        clips, sequence = clip_sequences(body, paths, spec.clip_fps, spec.clip_yaw_deg, rates)
        if spec.clip_in_place:
            clips[:, :2] = 0.0
            clips = grounded(body, clips)
        if spec.clip_mirror:
            clips, sequence = np.concatenate([clips, mirrored(clips)]), repeated_sequences(sequence, 2)
        clips = varied(
            clips, spec.clip_turns_deg, spec.clip_copies, spec.clip_jitter_deg, np.random.default_rng(spec.seed)
        )
        after = successors(repeated_sequences(sequence, len(clips) // len(sequence)))
        following.append(np.where(after >= 0, after + sum(len(part) for part in parts), -1))
        parts.append(clips)
    if not parts:
        raise ValueError("tracker.samples names no poses: set a grid, a capture or clips")
    poses, following = np.concatenate(parts), np.concatenate(following)
    kept, representative = near_duplicate_representatives(poses, spec.min_joint_deg)
    return poses[kept], learned_transitions(following, representative)
