"""Motion capture clips (BVH) as body pose vectors (`tracker.models.body_mesh` conventions).

A CMU clip's frame 0 is a T-pose added by the conversion (its README); the body's zero rotations are that
T-pose too, so each joint's rotation is taken relative to frame 0: ``W_j(t) = G_j(t) G_j(0)^T`` in the file's
frame, turned into the body frame (`BVH_TO_BODY`) and made relative to the parent. The root moves by the clip's
root displacement from frame 0, scaled so that the clip's leg length becomes the body's. Which file joint drives
which CMU joint, and how their T-poses differ, is the skeleton's retargeting table (`tracker.motion.retarget`):
the MotionBuilder-friendly CMU skeleton of ``mocap/`` maps one to one, the DAZ-friendly one of ``mocap_daz/`` by
its own table.

The motion starts at the file frame after the T-pose, or later where the skeleton's conversion eases into it
(`Skeleton.motion_from`: the DAZ-friendly files' frames 1-8); ``start_s`` counts from there.

A file whose header states a wrong frame rate (the DAZ-friendly salsa clips say 120 fps, were captured at 60) is
read at its true rate when one is given (``true_fps``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Annotated, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from tracker.data import data_path
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import BVH_TO_BODY, JOINT_INDEX, JOINT_NAMES, POSE_SIZE
from tracker.motion.bvh import BvhClip, BvhError, read_bvh
from tracker.motion.retarget import CMU, SKELETONS, Skeleton, skeleton_of
from tracker.ranges import Finite, NonNegative, Positive, Range
from tracker.registry import SCENES
from tracker.tol import COUNT_ROUNDING


@dataclass(frozen=True)
class ClipSelection:
    """Which part of a clip to use: from ``start`` (seconds after the motion's first frame) for ``frames`` frames at
    ``fps`` (``frames=None``: to the end)."""

    start_s: float = 0.0
    frames: int | None = None
    fps: float = 30.0


def clip_poses(clip: BvhClip, body: BodyMesh, selection: ClipSelection = ClipSelection()) -> np.ndarray:
    """``(n, POSE_SIZE)`` body pose vectors of ``clip`` resampled at ``selection.fps`` (slerp between frames)."""
    skeleton = retargeting(clip)
    times = _sample_times(clip, selection)
    order = np.array([clip.index(skeleton.sources[name]) for name in JOINT_NAMES])
    before = np.clip(np.floor(times / clip.frame_time).astype(int), skeleton.motion_from, clip.frames - 1)
    after = np.minimum(before + 1, clip.frames - 1)
    fraction = np.clip(times / clip.frame_time - before, 0.0, 1.0)[:, None]
    frames = np.unique(np.concatenate([[0], before, after]))
    world = clip.global_rotations(frames)[:, order]  # (k, J, 3, 3) file frame
    relative = world @ world[frames == 0].transpose(0, 1, 3, 2)  # from the T-pose, file frame
    relative = BVH_TO_BODY @ relative @ BVH_TO_BODY.T
    if skeleton.rest_bones:
        relative = relative @ skeleton.rest_corrections(
            clip.joint_positions([0])[0], clip.names, body.t_pose_heads, BVH_TO_BODY
        )
    parents = body.parents
    local = relative.copy()
    local[:, 1:] = relative[:, parents[1:]].transpose(0, 1, 3, 2) @ relative[:, 1:]
    root = (clip.root_positions(frames) - clip.root_positions([0])) @ BVH_TO_BODY.T * _scale(clip, body, skeleton)

    row = {frame: k for k, frame in enumerate(frames)}
    first, second = np.array([row[f] for f in before]), np.array([row[f] for f in after])
    poses = np.empty((len(times), POSE_SIZE))
    poses[:, :3] = body.rest_heads[0] + (1 - fraction) * root[first] + fraction * root[second]
    for joint in range(len(JOINT_NAMES)):
        start, end = Rotation.from_matrix(local[first, joint]), Rotation.from_matrix(local[second, joint])
        rotations = start * Rotation.from_rotvec(fraction * (start.inv() * end).as_rotvec())  # slerp
        poses[:, 3 + 3 * joint : 6 + 3 * joint] = rotations.as_rotvec()
    return poses


def motion_seconds(clip: BvhClip) -> float:
    """How long the clip's motion lasts, from its first frame (`Skeleton.motion_from`) to its last."""
    return max(clip.frames - 1 - retargeting(clip).motion_from, 0) * clip.frame_time


def _sample_times(clip: BvhClip, selection: ClipSelection) -> np.ndarray:
    """Times (s, from frame 0) of the wanted frames; the motion starts at the skeleton's `Skeleton.motion_from`."""
    if selection.fps <= 0:
        raise ValueError(f"fps={selection.fps}: must be > 0")
    motion_from = retargeting(clip).motion_from
    if clip.frames <= motion_from:
        raise BvhError(f"{clip.path}: has {clip.frames} frame(s), no motion: its motion starts at frame {motion_from}")
    first = clip.frame_time * (motion_from + selection.start_s / clip.frame_time)
    last = clip.frame_time * (clip.frames - 1)
    if first > last:
        raise BvhError(
            f"{clip.path}: start {selection.start_s} s is past the clip's end ({motion_seconds(clip):.2f} s of motion)"
        )
    available = int(np.floor((last - first) * selection.fps + COUNT_ROUNDING)) + 1
    count = available if selection.frames is None else selection.frames
    if count > available:
        raise BvhError(
            f"{clip.path}: {count} frames at {selection.fps:g} fps from {selection.start_s} s need "
            f"{(count - 1) / selection.fps:.2f} s of motion; the clip has {last - first:.2f} s from there"
        )
    return first + np.arange(count) / selection.fps


def available_frames(clip: BvhClip, start_s: float, fps: float) -> int:
    """How many frames at ``fps`` the clip holds from ``start_s`` (0 when it starts past the end)."""
    try:
        return len(_sample_times(clip, ClipSelection(start_s, None, fps)))
    except BvhError:
        return 0


def _scale(clip: BvhClip, body: BodyMesh, skeleton: Skeleton) -> float:
    """Metres per clip unit: the body's hip-knee-ankle length over the clip's."""
    clip_length = sum(np.linalg.norm(clip.offsets[clip.index(name)]) for name in skeleton.leg[1:])
    heads = body.rest_heads[[JOINT_INDEX[name] for name in CMU.leg]]
    return float(np.linalg.norm(np.diff(heads, axis=0), axis=1).sum() / clip_length)


def retargeting(clip: BvhClip) -> Skeleton:
    """The retargeting table for ``clip``'s skeleton, or `BvhError` saying which skeletons are known."""
    skeleton = skeleton_of(clip.names)
    if skeleton is None:
        missing = {s.name: sorted(s.joints() - set(clip.names)) for s in SKELETONS}
        nearest = min(missing, key=lambda name: len(missing[name]))
        raise BvhError(
            f"{clip.path}: no retargeting table fits its skeleton ({len(clip.names)} joints rooted at "
            f"{clip.names[0]!r}): the nearest, {nearest}, needs joints {', '.join(missing[nearest])}; "
            f"known skeletons: {', '.join(missing)} (tracker/motion/retarget.py)"
        )
    return skeleton


def read_clip(path: str, true_fps: float | None = None) -> BvhClip:
    """The BVH clip at ``path`` (a data path), read at ``true_fps`` when its header's frame rate is wrong."""
    clip = read_bvh(path)
    return clip if true_fps is None else replace(clip, frame_time=1.0 / true_fps)


def read_body_clip(path: str, key: str, true_fps: float | None = None) -> BvhClip:
    """The clip at ``path`` with a skeleton the body can be driven by, or ``ValueError`` naming the config key
    ``key`` (its value is ``path``)."""
    try:
        clip = read_clip(path, true_fps)
        retargeting(clip)
        return clip
    except BvhError as error:  # its message may name the file, as the key already does
        message, located = str(error), data_path(path)
        for named, pronoun in ((f"{located}: ", ""), (f"{located} is ", "it is ")):
            message = pronoun + message.removeprefix(named) if message.startswith(named) else message
        raise ValueError(f"{key}={path}: {message}") from None


def check_clip(scene: MocapScene, frames: int, key: str, model: str) -> None:
    """Before a run: the scene's file is a readable clip of a known skeleton holding ``frames`` frames from its start.
    Raises ``ValueError`` naming the config keys (``key``: the scene's, e.g. ``scene``)."""
    clip = read_body_clip(scene.path, f"{key}.path", scene.true_fps)
    motion_s = motion_seconds(clip)
    if motion_s <= 0:
        raise ValueError(f"{key}.path={scene.path}: the clip has {clip.frames} frame(s), no motion to track")
    if scene.start_s >= motion_s:
        raise ValueError(
            f"{key}.start_s={scene.start_s}: past the end of {scene.path} ({motion_s:.2f} s of motion); "
            f"allowed below {motion_s:.2f}"
        )
    available = available_frames(clip, scene.start_s, scene.fps)
    if frames > available:
        raise ValueError(
            f"frames={frames}: {key}.path={scene.path} has {available} frames at {scene.fps:g} fps "
            f"from {key}.start_s={scene.start_s} ({motion_s - scene.start_s:.2f} s of motion); allowed at most "
            f"{available}"
        )


@SCENES.register("bvh", models=("body_mesh",), check=check_clip)
@dataclass(frozen=True)
class MocapScene:
    """A BVH clip of a known skeleton (`tracker.motion.retarget`) drives the body, resampled at ``fps`` from
    ``start_s``.

    The body is turned about the vertical so that it faces ``yaw_deg`` (world xy angle from +x; -90 faces -y) at
    the first frame. ``center`` says what stands over the world origin: the first frame's root, the middle of the
    root's path over the clip (its bounding box on the ground: a walk stays in view of a camera on the origin), or
    nothing (the clip's own place)."""

    path: str
    start_s: NonNegative = 0.0  # seconds after the motion's first frame (`ClipSelection`)
    fps: Annotated[float, Range(1.0, 1000.0)] = 30.0  # resampled (slerp) to this rate
    yaw_deg: Finite = -90.0
    center: Literal["first_frame", "path", "none"] = "first_frame"
    true_fps: Positive | None = None  # the clip's capture rate when its header's Frame Time is wrong
    # Stand the clip on the floor: moved up or down once so that its feet's lowest vertex is at z = 0 in the median
    # frame (a clip's height comes from its T-pose frame: 69_20 floats 2.4 cm, DAZ-friendly clips 14-18 cm).
    on_floor: bool = True
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)  # the poses of one body

    def poses(self, body: BodyMesh, frames: int | None = None) -> np.ndarray:
        """``(frames, POSE_SIZE)`` the scene's pose vectors (all the clip holds from ``start_s`` when None)."""
        poses = clip_poses(read_clip(self.path, self.true_fps), body, ClipSelection(self.start_s, frames, self.fps))
        poses = face(poses, self.yaw_deg, self.center)
        if self.on_floor:
            poses[:, 2] -= np.median(body.feet_heights(poses))
        return poses

    def params(self, body: BodyMesh, frame: int) -> np.ndarray:
        poses = self._poses(body)
        if frame >= len(poses):
            raise BvhError(
                f"{self.path}: frame {frame} asked, the clip has {len(poses)} frames at {self.fps:g} fps "
                f"from {self.start_s} s"
            )
        return poses[frame]

    def _poses(self, body: BodyMesh) -> np.ndarray:
        """The clip's poses for ``body``, computed once per scene and body."""
        if self._cache.get("body") is not body:
            self._cache.update(body=body, poses=self.poses(body))
        return self._cache["poses"]


def face(poses: np.ndarray, yaw_deg: float, center: str = "first_frame") -> np.ndarray:
    """``poses`` turned about the vertical through the first root position so that the body faces ``yaw_deg``
    at the first frame (its facing: the root's -y axis projected on the ground), then moved on the ground so
    that ``center`` (`MocapScene.center`) stands over the origin."""
    poses = np.array(poses, dtype=np.float64)
    root = Rotation.from_rotvec(poses[:, 3:6])
    facing = root[0].apply([0.0, -1.0, 0.0])
    turn = Rotation.from_euler("z", math.radians(yaw_deg) - math.atan2(facing[1], facing[0]))
    origin = poses[0, :3].copy()
    poses[:, :3] = turn.apply(poses[:, :3] - origin)  # the first root on the origin, at the ground
    poses[:, 3:6] = (turn * root).as_rotvec()
    if center == "path":
        poses[:, :2] -= (poses[:, :2].min(axis=0) + poses[:, :2].max(axis=0)) / 2
    poses[:, :3] += origin if center == "none" else np.array([0.0, 0.0, origin[2]])
    return poses
