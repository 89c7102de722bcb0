"""Procedural truth motion of the body (paper 2, experiment A): the right arm swings forward and back.

The body stands in its T-pose with both arms lowered to the sides (``abduction_deg`` away from the trunk); the
right upper arm swings about the body's left-right axis between ``forward_deg`` in front and ``backward_deg``
behind the vertical with a triangle wave, so at constant angular speed, one forward-and-back cycle every
``period_frames`` (frame 0: arm down, moving forward). Seen side-on from the body's left (rig ``body_side``), the
right arm passes behind the torso twice per swing. Pose vectors follow `tracker.models.body_mesh`.

``variation`` (0: the clean swing above, exactly) makes it a person's (`SwingVariation`, seeded by ``seed``):
each swing's amplitude and speed differ, the elbow and abduction drift, the trunk, head, left arm, knees and weight
sway within `tracker.motion.posture.NATURAL_SPREAD`, the root takes small steps and the body faces a few degrees
off ``yaw_deg``; all scaled by ``variation``. Swings still start at the vertical moving forward, and every
`SWINGS_PER_BLOCK` of them take ``SWINGS_PER_BLOCK * period_frames`` frames together.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Annotated

import numpy as np

from tracker.models.body_mesh import BodyMesh
from tracker.motion.posture import NATURAL_SPREAD, RANGE_SIGMAS, Drifts, Posture, arms_pose, standing_pose
from tracker.ranges import Finite, Fraction, Positive, Range, Seed

SWINGS_PER_BLOCK = 24  # paper 2's experiment A: 24 swings
_SWING_SPREAD = 0.15  # each swing's amplitudes and duration: this fraction (one standard deviation) at variation 1
_ELBOW_DRIFT_DEG = 20.0  # the elbow drifts between straight and this much bent
_ABDUCTION_DRIFT_DEG = 6.0  # the abduction drifts this far either side of abduction_deg
_YAW_OFFSET_DEG = 5.0  # the body faces up to this far off yaw_deg
_STEP_M = 0.03  # one standard deviation of a step of the root on the floor, each axis
_STEP_EVERY_FRAMES = (100, 250)  # a step every so many frames (drawn) ...
_STEP_FRAMES = 12  # ... taking this long
_DRIFT_PERIODS_FRAMES = (80.0, 400.0)  # slow drifts: sums of three sines with periods in this range


@dataclass(frozen=True)
class BodySwing:
    """Paper 2's experiment A: the body's right arm swings forward and back at constant angular speed."""

    period_frames: Positive = 40.0
    forward_deg: Annotated[float, Range(0.0, 180.0)] = 60.0  # in front of the vertical
    backward_deg: Annotated[float, Range(0.0, 90.0)] = 40.0  # behind it
    abduction_deg: Annotated[float, Range(0.0, 90.0)] = 8.0  # both arms this far out from the trunk
    yaw_deg: Finite = -90.0  # the direction the body faces, world xy angle from +x (-90: facing -y)
    variation: Fraction = 0.0  # 0: the clean swing; 1: a person's (see the module docstring)
    seed: Seed = 0  # of the variation

    def swing_angle_deg(self, frame: float) -> float:
        """The right arm's elevation in the sagittal plane: + in front of the vertical, - behind."""
        if self.variation == 0:
            return _triangle((frame / self.period_frames) % 1.0, self.forward_deg, self.backward_deg)
        return self._variation.swing_angle_deg(frame)

    def params(self, body: BodyMesh, frame: int) -> np.ndarray:
        if self.variation == 0:
            return arms_pose(
                body,
                right=(self.swing_angle_deg(frame), self.abduction_deg, 0.0),
                left=(0.0, self.abduction_deg, 0.0),
                yaw_deg=self.yaw_deg,
            )
        return standing_pose(body, self._variation.posture(frame))

    @cached_property
    def _variation(self) -> SwingVariation:
        return SwingVariation.draw(self, np.random.default_rng(self.seed))


def _triangle(phase: float, forward: float, backward: float) -> float:
    """One swing at constant angular speed, ``phase`` in [0, 1): 0 -> forward -> -backward -> 0."""
    span = forward + backward
    walked = phase * 2 * span
    if walked <= forward:
        return walked
    if walked <= forward + span:
        return forward - (walked - forward)
    return -backward + (walked - forward - span)


@dataclass(frozen=True, eq=False)
class SwingVariation:
    """A drawn person's swing (`BodySwing` with ``variation`` > 0): per swing its start frame and amplitudes, and
    the slow drifts of everything else."""

    swing: BodySwing
    starts: np.ndarray  # (swings + 1,) frame each swing starts (the last: where the last one ends)
    forward: np.ndarray  # (swings,) degrees
    backward: np.ndarray
    drifts: Drifts  # of NATURAL_SPREAD's variations, the elbow and the abduction
    yaw_offset_deg: float
    steps: np.ndarray  # (k, 3): frame a step starts, its x and y (m)

    @classmethod
    def draw(cls, swing: BodySwing, rng: np.random.Generator, swings: int = 10 * SWINGS_PER_BLOCK) -> SwingVariation:
        v = swing.variation

        def spread(n: int) -> np.ndarray:
            return 1.0 + v * _SWING_SPREAD * np.clip(rng.normal(0.0, 1.0, n), -RANGE_SIGMAS, RANGE_SIGMAS)

        durations = spread(swings).reshape(-1, SWINGS_PER_BLOCK)
        durations *= SWINGS_PER_BLOCK * swing.period_frames / durations.sum(axis=1, keepdims=True)
        drifts = Drifts.draw(rng, [*NATURAL_SPREAD, "elbow", "abduction"], _DRIFT_PERIODS_FRAMES)
        step_frames = np.cumsum(rng.uniform(*_STEP_EVERY_FRAMES, 64))
        steps = np.column_stack([step_frames, rng.normal(0.0, v * _STEP_M, (64, 2))])
        return cls(
            swing=swing,
            starts=np.r_[0.0, np.cumsum(durations)],
            forward=swing.forward_deg * spread(swings),
            backward=swing.backward_deg * spread(swings),
            drifts=drifts,
            yaw_offset_deg=float(v * rng.uniform(-_YAW_OFFSET_DEG, _YAW_OFFSET_DEG)),
            steps=steps,
        )

    def swing_angle_deg(self, frame: float) -> float:
        k = int(np.searchsorted(self.starts, frame, side="right")) - 1
        if k >= len(self.forward):
            raise ValueError(f"frame {frame} is past the {len(self.forward)} swings drawn")
        phase = (frame - self.starts[k]) / (self.starts[k + 1] - self.starts[k])
        return _triangle(phase, self.forward[k], self.backward[k])

    def root_offset_m(self, frame: float) -> tuple[float, float]:
        """Where the steps taken by ``frame`` have moved the root (each step eased over `_STEP_FRAMES`)."""
        progress = np.clip((frame - self.steps[:, 0]) / _STEP_FRAMES, 0.0, 1.0)
        eased = progress * progress * (3 - 2 * progress)
        offset = eased @ self.steps[:, 1:]
        return float(offset[0]), float(offset[1])

    def posture(self, frame: float) -> Posture:
        v, swing = self.swing.variation, self.swing
        natural = {name: float(value) for name, value in self.drifts.natural(frame, v).items()}
        elbow = v * _ELBOW_DRIFT_DEG * (float(self.drifts.value("elbow", frame)) + 1) / 2
        abduction = swing.abduction_deg + v * _ABDUCTION_DRIFT_DEG * float(self.drifts.value("abduction", frame))
        left = (
            natural.pop("left_swing_deg"),
            swing.abduction_deg + natural.pop("left_abduction_deg"),
            natural.pop("left_elbow_deg"),
        )
        yaw = swing.yaw_deg + self.yaw_offset_deg + natural.pop("yaw_deg")
        return Posture(
            right=(self.swing_angle_deg(frame), abduction, elbow),
            left=left,
            yaw_deg=yaw,
            root_offset_m=self.root_offset_m(frame),
            **natural,
        )
