"""A synthetic capture session like paper 2's sample captures: a person side-on, moving the right arm in various
ways while standing naturally (section 3.1: "mainly side-on, the right arm moved in various ways").

The session is continuous, as a capture is: the right arm goes from move to move — reaching to a posture drawn
uniformly over the ranges at a drawn speed (minimum-jerk), or swinging about a drawn centre for one to three cycles
of a drawn amplitude and period — while the trunk, head, left arm, knees, weight and facing drift slowly
(`tracker.motion.posture.Drifts`, `NATURAL_SPREAD` times ``amplitude``). Every frame becomes a pose
(`tracker.motion.posture.standing_poses`); the sample set then drops near-duplicates, as the paper did.
Times in seconds, angles in degrees. Everything is drawn from the generator given: a session shares nothing with
another seed's, nor with any test sequence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.models.body_mesh import BodyMesh
from tracker.motion.posture import NATURAL_SPREAD, Drifts, Posture, standing_poses, with_offsets

REACH_SPEED_DEG_S = (60.0, 200.0)  # a reach's speed along its largest joint change
SWING_AMPLITUDE_DEG = (10.0, 80.0)
SWING_PERIOD_S = (0.8, 2.5)
SWING_CYCLES = (1, 3)
DRIFT_PERIODS_S = (3.0, 15.0)


@dataclass(frozen=True)
class ArmRanges:
    swing_deg: tuple[float, float]
    abduction_deg: tuple[float, float]
    elbow_deg: tuple[float, float]

    def uniform(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.uniform(*span) for span in (self.swing_deg, self.abduction_deg, self.elbow_deg)])

    def clip(self, arm: np.ndarray) -> np.ndarray:
        spans = np.array([self.swing_deg, self.abduction_deg, self.elbow_deg])
        return np.clip(arm, spans[:, 0], spans[:, 1])


def right_arm_track(ranges: ArmRanges, frames: int, fps: float, rng: np.random.Generator) -> np.ndarray:
    """``(frames, 3)`` swing, abduction, elbow of the right arm over the session (see the module docstring)."""
    track = [ranges.uniform(rng)[None]]
    length = 1
    while length < frames:
        start = track[-1][-1]
        if rng.random() < 0.5:  # reach
            target = ranges.uniform(rng)
            seconds = np.abs(target - start).max() / rng.uniform(*REACH_SPEED_DEG_S)
            s = np.linspace(0.0, 1.0, max(int(round(seconds * fps)), 1) + 1)[1:]
            move = start + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, target - start)
        else:  # swing about the present posture
            amplitude, period = rng.uniform(*SWING_AMPLITUDE_DEG), rng.uniform(*SWING_PERIOD_S)
            cycles = rng.integers(SWING_CYCLES[0], SWING_CYCLES[1] + 1)
            t = np.arange(1, int(round(cycles * period * fps)) + 1) / fps
            move = np.repeat(start[None], len(t), axis=0)
            move[:, 0] += amplitude * np.sin(2 * np.pi * t / period)
            move = ranges.clip(move)
        track.append(move)
        length += len(move)
    return np.concatenate(track)[:frames]


def capture_poses(
    body: BodyMesh,
    ranges: ArmRanges,
    seconds: float,
    fps: float,
    yaw_deg: float,
    amplitude: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """``(frames, POSE_SIZE)``: every frame of a session of ``seconds`` at ``fps``, facing ``yaw_deg``."""
    frames = int(round(seconds * fps))
    arm = right_arm_track(ranges, frames, fps, rng)
    drifts = Drifts.draw(rng, NATURAL_SPREAD, DRIFT_PERIODS_S).natural(np.arange(frames) / fps, amplitude)
    return standing_poses(
        body,
        (
            with_offsets(
                Posture(right=tuple(arm[k]), yaw_deg=yaw_deg),
                {name: float(values[k]) for name, values in drifts.items()},
            )
            for k in range(frames)
        ),
    )
