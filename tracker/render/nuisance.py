"""What a real camera adds to the rendered image: sensor noise and a slow illumination change (paper 2's
experiments run under controlled light in front of a blue backdrop; the background model must cope with both).

`SensorNuisance.apply` turns a clean render into the image the tracker sees: ``gain(t) * rgb + noise``, with
``gain(t) = 1 + gain_amplitude * sin(2 pi t / gain_period_frames)`` for the whole image (the light, not the
scene) and independent Gaussian noise of ``noise_std`` 8-bit levels per pixel and channel, clipped to [0, 255].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.ranges import Positive, Range
from tracker.settings import validate


@dataclass(frozen=True)
class SensorNuisance:
    noise_std: Annotated[float, Range(0.0, 64.0)]  # 8-bit levels
    gain_amplitude: Annotated[float, Range(0.0, 0.5)] = 0.0  # relative
    gain_period_frames: Positive = 150.0

    def __post_init__(self) -> None:
        validate(self)

    def gain(self, frame: float) -> float:
        return 1.0 + self.gain_amplitude * math.sin(2 * math.pi * frame / self.gain_period_frames)

    def apply(self, rgb: np.ndarray, frame: float, rng: np.random.Generator) -> np.ndarray:
        """The camera's ``(h, w, 3)`` uint8 image of the clean render ``rgb`` at ``frame``."""
        image = rgb.astype(np.float32) * np.float32(self.gain(frame))
        if self.noise_std > 0:
            image += rng.normal(0.0, self.noise_std, rgb.shape).astype(np.float32)
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)
