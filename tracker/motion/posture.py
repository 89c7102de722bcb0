"""A person standing side-on and moving the right arm, as paper 2's captures held them: the posture's few numbers
(`Posture`), their pose vector (`standing_pose`), and the natural variation of everything but the right arm.

A posture extends `arms_pose` (each arm's swing, abduction and elbow, the body's yaw) by
what a standing person does not hold still: the trunk's lean (+ forward), side bend (+ toward the body's left)
and twist (+ turning the chest to the left), split evenly over ``Spine`` and ``Spine1``; the head's nod (+ down)
and turn (+ to the left); each knee's flexion (the thigh forward, the shin back by twice as much and the foot level
again, so the foot stays under the hip); the weight shift (the pelvis rolled, + dropping its left side, the legs
and lower back turned back upright); and the root's offset on the floor. The root is lowered so that the lower
foot stays on the floor. Degrees and metres; rotations in the body frame (`tracker.models.body_skeleton`).

`NATURAL_SPREAD`: the scale of each of those in natural standing; at full amplitude each stays within
`RANGE_SIGMAS` times its scale (`Drifts.natural`). They are set from the usual magnitudes of quiet standing and
shifting weight: trunk sway of a few degrees, the head turning and nodding more freely, knees from straight to
slightly bent.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, fields, replace

import numpy as np

from tracker.geometry.rotations import matrix_to_rotation_vector, rotation_x, rotation_y, rotation_z
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_INDEX, POSE_SIZE

# The T-pose's arms hang this far below the horizontal already (frame 0 of the CMU clips).
_T_POSE_DROOP_DEG = 8.0
RANGE_SIGMAS = 2.0  # every natural variation stays within this many times its NATURAL_SPREAD


@dataclass(frozen=True)
class Posture:
    right: tuple[float, float, float] = (0.0, 8.0, 0.0)  # swing, abduction, elbow (degrees)
    left: tuple[float, float, float] = (0.0, 8.0, 0.0)
    yaw_deg: float = -90.0
    lean_deg: float = 0.0
    side_deg: float = 0.0
    twist_deg: float = 0.0
    nod_deg: float = 0.0
    head_turn_deg: float = 0.0
    left_knee_deg: float = 0.0
    right_knee_deg: float = 0.0
    weight_shift_deg: float = 0.0
    root_offset_m: tuple[float, float] = (0.0, 0.0)


# The scale of each natural variation at full amplitude (see the module docstring); the left arm's entries are its
# swing, abduction and elbow about the posture's own.
NATURAL_SPREAD = {
    "yaw_deg": 4.0,
    "lean_deg": 3.0,
    "side_deg": 2.0,
    "twist_deg": 4.0,
    "nod_deg": 5.0,
    "head_turn_deg": 8.0,
    "left_knee_deg": 4.0,
    "right_knee_deg": 4.0,
    "weight_shift_deg": 2.0,
    "left_swing_deg": 8.0,
    "left_abduction_deg": 4.0,
    "left_elbow_deg": 10.0,
}
# Knees and the elbow bend one way only: they vary from 0 upward.
ONE_SIDED = ("left_knee_deg", "right_knee_deg", "left_elbow_deg")


@dataclass(frozen=True, eq=False)
class Drifts:
    """Slow drifts in [-1, 1], one per name: a sum of three sines whose weights sum to 1, with periods drawn from
    a range and random phases. `natural` turns them into `NATURAL_SPREAD` variations over time."""

    sines: dict[str, np.ndarray]  # name -> (3, 3): weights, periods, phases

    @classmethod
    def draw(cls, rng: np.random.Generator, names: Iterable[str], periods: tuple[float, float]) -> Drifts:
        return cls(
            {
                name: np.stack([rng.dirichlet(np.ones(3)), rng.uniform(*periods, 3), rng.uniform(0.0, 2 * np.pi, 3)])
                for name in names
            }
        )

    def value(self, name: str, t: np.ndarray | float) -> np.ndarray:
        weights, periods, phases = self.sines[name]
        t = np.asarray(t, dtype=np.float64)[..., None]
        return np.sum(weights * np.sin(2 * np.pi * t / periods + phases), axis=-1)

    def natural(self, t: np.ndarray | float, amplitude: float) -> dict[str, np.ndarray]:
        """Every `NATURAL_SPREAD` variation at ``t``: within `RANGE_SIGMAS` of its spread times ``amplitude``
        (one-sided ones in [0, that])."""
        out = {}
        for name, spread in NATURAL_SPREAD.items():
            drift = self.value(name, t)
            out[name] = amplitude * spread * RANGE_SIGMAS * ((drift + 1) / 2 if name in ONE_SIDED else drift)
        return out


def with_offsets(posture: Posture, offsets: dict[str, float]) -> Posture:
    """``posture`` moved by the `NATURAL_SPREAD` variations ``offsets`` (angles added; the left arm's three too)."""
    left = (
        posture.left[0] + offsets["left_swing_deg"],
        posture.left[1] + offsets["left_abduction_deg"],
        posture.left[2] + offsets["left_elbow_deg"],
    )
    names = {f.name for f in fields(Posture)}
    changes = {name: getattr(posture, name) + value for name, value in offsets.items() if name in names}
    return replace(posture, left=left, **changes)


def standing_pose(body: BodyMesh, posture: Posture) -> np.ndarray:
    """The pose vector of ``posture`` (see the module docstring)."""
    return standing_poses(body, [posture])[0]


def standing_poses(body: BodyMesh, postures: Iterable[Posture]) -> np.ndarray:
    """``(n, POSE_SIZE)``: `standing_pose` of each of ``postures``, their feet put on the floor together (the same
    bits as one by one)."""
    poses = np.array([_off_the_floor(body, posture) for posture in postures]).reshape(-1, POSE_SIZE)
    if not len(poses):
        return poses
    feet = [JOINT_INDEX[name] for name in ("LeftFoot", "RightFoot")]
    rest_feet = body.t_pose_heads[feet, 2].min()
    poses[:, 2] -= body.joint_positions(poses)[:, feet, 2].min(axis=1) - rest_feet
    return poses


def _off_the_floor(body: BodyMesh, posture: Posture) -> np.ndarray:
    """The pose vector of ``posture`` before its lower foot is put on the floor."""
    pose = arms_pose(body, right=posture.right, left=posture.left, yaw_deg=posture.yaw_deg)
    shift = math.radians(posture.weight_shift_deg)
    set_joint(pose, "Hips", rotation_z(math.radians(posture.yaw_deg + 90.0)) @ rotation_y(shift))
    set_joint(pose, "LowerBack", rotation_y(-shift))
    half = [math.radians(angle) / 2 for angle in (posture.lean_deg, posture.side_deg, posture.twist_deg)]
    for joint in ("Spine", "Spine1"):
        set_joint(pose, joint, rotation_x(half[0]) @ rotation_y(half[1]) @ rotation_z(half[2]))
    set_joint(pose, "Neck", rotation_x(math.radians(posture.nod_deg)) @ rotation_z(math.radians(posture.head_turn_deg)))
    for side, knee in (("Left", posture.left_knee_deg), ("Right", posture.right_knee_deg)):
        bend = math.radians(knee) / 2
        set_joint(pose, f"{side}UpLeg", rotation_y(-shift) @ rotation_x(-bend))
        set_joint(pose, f"{side}Leg", rotation_x(2 * bend))
        set_joint(pose, f"{side}Foot", rotation_x(-bend))
    pose[0:2] += posture.root_offset_m
    return pose


def arms_pose(
    body: BodyMesh, right: tuple[float, float, float], left: tuple[float, float, float], yaw_deg: float = -90.0
) -> np.ndarray:
    """The standing body with each arm at ``(swing, abduction, elbow)`` degrees: swing in the sagittal plane
    (+ in front of the vertical), abduction out from the trunk, elbow flexion (+ brings the forearm forward);
    facing ``yaw_deg`` (world xy angle from +x; -90 faces -y)."""
    pose = body.rest_pose()
    for side, (swing, abduction, elbow), sign in (("Right", right, -1.0), ("Left", left, 1.0)):
        lower = math.radians(90.0 - _T_POSE_DROOP_DEG - abduction)
        set_joint(pose, f"{side}Arm", rotation_x(-math.radians(swing)) @ rotation_y(sign * lower))
        set_joint(pose, f"{side}ForeArm", rotation_z(-sign * math.radians(elbow)))
    set_joint(pose, "Hips", rotation_z(math.radians(yaw_deg + 90.0)))
    return pose


def set_joint(pose: np.ndarray, joint: str, rotation: np.ndarray) -> None:
    """Set ``joint``'s rotation in the pose vector ``pose`` (in place) to the rotation matrix ``rotation``."""
    start = 3 + 3 * JOINT_INDEX[joint]
    pose[start : start + 3] = matrix_to_rotation_vector(rotation)
