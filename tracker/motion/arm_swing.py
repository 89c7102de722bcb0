"""Procedural truth motion of the 3-part DSQ arm (paper 1's experiment).

The arm points along world +x from a shoulder at ``shoulder``. The elbow (part 2's r2) swings the forearm down
between straight and ``elbow_swing`` with a cosine profile that dwells near straight: while the forearm is nearly
straight it hides behind the thicker upper arm in the ``left`` view, which looks along +x (the paper's "serious
occlusion of part 2"). The forearm bends (b1) on its own period, the hand rocks sideways (r1) and the shoulder
sways about the vertical (root r3). Angles radians, lengths metres, time in frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.geometry.rotations import euler_to_matrix
from tracker.models.articulated import jointed_translation
from tracker.models.dsq import PARAM_INDEX, pole_point
from tracker.models.dsq_arm import DSQArm
from tracker.ranges import Finite, Positive, Range, Vector3

N_PARTS = 3
Angle = Annotated[float, Range(-math.pi, math.pi)]


@dataclass(frozen=True)
class ArmSwing:
    """Paper 1's elbow swing of the DSQ arm, with dwell near straight, forearm bending and a rocking wrist."""

    period_frames: Positive = 48.0
    elbow_swing: Angle = 1.2  # forearm r2 between 0 and this (69 deg)
    bend_amplitude: Finite = 0.04  # forearm b1 in [-a, a] m
    bend_period_frames: Positive = 64.0
    wrist_rock: Angle = 0.35  # hand r1 amplitude (20 deg)
    shoulder_sway: Angle = 0.06  # upper-arm r3 amplitude (3.4 deg)
    shoulder: Vector3 = (0.0, 0.0, 0.0)  # where the upper arm's bottom pole sits

    def params(self, arm: DSQArm, frame: int) -> np.ndarray:
        """``(3, 17)`` truth parameters of every part at ``frame``, joints connected."""
        if len(arm.parts) != N_PARTS:
            raise ValueError(f"the arm-swing motion drives a {N_PARTS}-part arm, the model has {len(arm.parts)}")
        phase = 2 * math.pi * frame / self.period_frames
        params = arm.rest_params()
        r1, r2, r3 = PARAM_INDEX["r1"], PARAM_INDEX["r2"], PARAM_INDEX["r3"]
        # Root: local z (the part's axis) turned onto world +x, swaying about world z.
        params[0, r2] = math.pi / 2
        params[0, r3] = self.shoulder_sway * math.sin(0.5 * phase)
        # Forearm: swing down and back (dwelling at straight), and bend.
        params[1, r2] = self.elbow_swing * (1.0 - math.cos(phase)) / 2.0
        params[1, PARAM_INDEX["b1"]] = self.bend_amplitude * math.sin(2 * math.pi * frame / self.bend_period_frames)
        # Hand: rock sideways.
        params[2, r1] = self.wrist_rock * math.sin(phase + math.pi / 3)
        # The root's bottom pole (the shoulder joint) sits at `shoulder`; children follow from the joints.
        root_rotation = euler_to_matrix(params[0, r1 : r3 + 1])
        params[0, PARAM_INDEX["c1"] : PARAM_INDEX["c3"] + 1] = jointed_translation(
            root_rotation, np.asarray(self.shoulder, dtype=np.float64), pole_point(params[0], top=False)
        )
        return arm.connect(params)
