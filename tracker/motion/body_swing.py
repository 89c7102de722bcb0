"""Procedural truth motion of the body (paper 2, experiment A): the right arm swings forward and back.

The body stands in its T-pose with both arms lowered to the sides (``abduction_deg`` away from the trunk); the
right upper arm swings about the body's left-right axis between ``forward_deg`` in front and ``backward_deg``
behind the vertical with a triangle wave, so at constant angular speed, one forward-and-back cycle every
``period_frames`` (frame 0: arm down, moving forward). Seen side-on from the body's left (rig ``body_side``), the
right arm passes behind the torso twice per swing. Pose vectors follow `tracker.models.body_mesh`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.geometry.rotations import matrix_to_rotation_vector, rotation_x, rotation_y, rotation_z
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.ranges import Finite, Positive, Range

# The T-pose's arms hang this far below the horizontal already (frame 0 of the CMU clips).
_T_POSE_DROOP_DEG = 8.0


@dataclass(frozen=True)
class BodySwing:
    """Paper 2's experiment A: the body's right arm swings forward and back at constant angular speed."""

    period_frames: Positive = 40.0
    forward_deg: Annotated[float, Range(0.0, 180.0)] = 60.0  # in front of the vertical
    backward_deg: Annotated[float, Range(0.0, 90.0)] = 40.0  # behind it
    abduction_deg: Annotated[float, Range(0.0, 90.0)] = 8.0  # both arms this far out from the trunk
    yaw_deg: Finite = -90.0  # the direction the body faces, world xy angle from +x (-90: facing -y)

    def swing_angle_deg(self, frame: float) -> float:
        """The right arm's elevation in the sagittal plane: + in front of the vertical, - behind."""
        span = self.forward_deg + self.backward_deg
        # One cycle walks 0 -> forward -> -backward -> 0, a path of 2 * span degrees at constant speed.
        walked = (frame / self.period_frames) % 1.0 * 2 * span
        if walked <= self.forward_deg:
            return walked
        if walked <= self.forward_deg + span:
            return self.forward_deg - (walked - self.forward_deg)
        return -self.backward_deg + (walked - self.forward_deg - span)

    def params(self, body: BodyMesh, frame: int) -> np.ndarray:
        return arms_pose(body, right=(self.swing_angle_deg(frame), self.abduction_deg, 0.0),
                         left=(0.0, self.abduction_deg, 0.0), yaw_deg=self.yaw_deg)  # fmt: skip


def arms_pose(body: BodyMesh, right: tuple[float, float, float], left: tuple[float, float, float],
              yaw_deg: float = -90.0) -> np.ndarray:  # fmt: skip
    """The standing body with each arm at ``(swing, abduction, elbow)`` degrees: swing in the sagittal plane
    (+ in front of the vertical), abduction out from the trunk, elbow flexion (+ brings the forearm forward);
    facing ``yaw_deg`` (world xy angle from +x; -90 faces -y)."""
    pose = body.rest_pose()
    for side, (swing, abduction, elbow), sign in (("Right", right, -1.0), ("Left", left, 1.0)):
        lower = math.radians(90.0 - _T_POSE_DROOP_DEG - abduction)
        _set(pose, f"{side}Arm", rotation_x(-math.radians(swing)) @ rotation_y(sign * lower))
        _set(pose, f"{side}ForeArm", rotation_z(-sign * math.radians(elbow)))
    _set(pose, "Hips", rotation_z(math.radians(yaw_deg + 90.0)))
    return pose


def _set(pose: np.ndarray, joint: str, rotation: np.ndarray) -> None:
    start = 3 + 3 * JOINT_INDEX[joint]
    pose[start : start + 3] = matrix_to_rotation_vector(rotation)
