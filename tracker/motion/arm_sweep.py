"""``scene=arm_sweep``: the DSQ arm's upper arm sweeps in front of the forearm in the ``front`` view.

The forearm holds still in the world, pointing away from the front camera at ``forearm_tilt`` in the horizontal
plane: the front view sees it broadside enough to carry many tracked pairs. The elbow turns about the vertical
between ``elbow_extension`` (bent the other way) and ``elbow_flexion`` with a cosine profile that dwells at both
ends; since the forearm stays put, it is the upper arm (the root) that swings, round the fixed elbow and towards the
camera, until it lies in front of the forearm and hides it in the front view, then back. Meanwhile the ``left`` and
``top`` views see the forearm side-on (the top view all along; the left view loses it behind the end-on upper arm
only at the other end of the swing, bent the other way). The forearm bends (b1) on its own period and the hand rocks
(r1), as in `ArmSwing`.

Occlusion without rotation: the hidden surface keeps facing the camera while it is covered, so its pairs can only
leave by the model's prediction (z-buffer) or by tracking failure, which is what paper 1's Fig 9 is about.
Angles radians, lengths metres, time in frames; world frame of `tracker.geometry.rigs`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.geometry.rotations import matrix_to_euler, rotation_y
from tracker.models.articulated import jointed_translation
from tracker.models.dsq import PARAM_INDEX, pole_point
from tracker.models.dsq_arm import DSQArm
from tracker.motion.arm_swing import N_PARTS, Angle
from tracker.ranges import Finite, Positive, Range, Vector3
from tracker.registry import SCENES

QuarterTurn = Annotated[float, Range(0.0, math.pi / 2)]
# Below a right angle: the flexion is the forearm's r2, and eq 4's Euler angles are singular at r2 = pi/2.
Flexion = Annotated[float, Range(0.0, math.pi / 2, high_open=True)]

_R = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)
_C = slice(PARAM_INDEX["c1"], PARAM_INDEX["c3"] + 1)


@SCENES.register("arm_sweep", models=("dsq_arm",))
@dataclass(frozen=True)
class ArmSweep:
    """The upper arm sweeps round a still forearm and covers it in the front view, then uncovers it."""

    period_frames: Positive = 96.0  # one sweep in and out: the upper arm turns 148 deg each way
    elbow_flexion: Flexion = 1.48  # the elbow's largest flexion (85 deg): the upper arm then covers the forearm
    # and its smallest, negative: bent the other way, the upper arm leaves the forearm whole in the front view
    elbow_extension: Annotated[float, Range(-math.pi / 2, 0.0, low_open=True)] = -1.1  # -63 deg
    forearm_tilt: QuarterTurn = math.pi / 4  # the forearm's angle away from the front camera, in the horizontal
    bend_amplitude: Finite = 0.04  # forearm b1 in [-a, a] m
    bend_period_frames: Positive = 64.0
    wrist_rock: Angle = 0.35  # hand r1 amplitude (20 deg)
    elbow: Vector3 = (0.54, 0.0, -0.2)  # where the elbow (the upper arm's top pole) holds still

    def forearm_rotation(self) -> np.ndarray:
        """The forearm's fixed world rotation: its axis (local z) along ``forearm_tilt`` in the horizontal plane,
        its local y (the elbow's hinge) pointing down, so that a positive flexion swings the upper arm towards
        the front camera (-y)."""
        tilt = self.forearm_tilt
        axis = np.array([math.cos(tilt), math.sin(tilt), 0.0])
        side = np.array([math.sin(tilt), -math.cos(tilt), 0.0])
        return np.column_stack([side, [0.0, 0.0, -1.0], axis])

    def flexion(self, frame: int) -> float:
        """The elbow's flexion (the forearm's r2 relative to the upper arm) at ``frame``."""
        swing = (1.0 - math.cos(2 * math.pi * frame / self.period_frames)) / 2.0
        return self.elbow_extension + (self.elbow_flexion - self.elbow_extension) * swing

    def params(self, arm: DSQArm, frame: int) -> np.ndarray:
        """``(3, 17)`` truth parameters of every part at ``frame``, joints connected."""
        if len(arm.parts) != N_PARTS:
            raise ValueError(f"the arm-sweep motion drives a {N_PARTS}-part arm, the model has {len(arm.parts)}")
        params = arm.rest_params()
        flexion = self.flexion(frame)
        params[1, PARAM_INDEX["r2"]] = flexion
        params[1, PARAM_INDEX["b1"]] = self.bend_amplitude * math.sin(2 * math.pi * frame / self.bend_period_frames)
        phase = 2 * math.pi * frame / self.period_frames
        params[2, PARAM_INDEX["r1"]] = self.wrist_rock * math.sin(phase + math.pi / 3)
        # The root turns so that root @ Ry(flexion) (the forearm's world rotation) stays fixed, and sits with its
        # top pole on the elbow.
        root = self.forearm_rotation() @ rotation_y(flexion).T
        params[0, _R] = matrix_to_euler(root)
        params[0, _C] = jointed_translation(
            root, np.asarray(self.elbow, dtype=np.float64), pole_point(params[0], top=True)
        )
        return arm.connect(params)
