"""The synthetic camera's settings: the backdrop, the ambient light, and what a real sensor adds to the render."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from tracker.ranges import RGB, Fraction, Positive, Range
from tracker.render.nuisance import SensorNuisance
from tracker.render.offscreen import DEFAULT_BACKGROUND, Lighting, SceneRenderer


@dataclass(frozen=True)
class RenderSettings:
    """The synthetic camera. ``noise_std``, ``gain_*``: sensor noise and illumination change
    (`tracker.render.nuisance`); 0 leaves the rendered image as it is."""

    background_rgb: RGB = DEFAULT_BACKGROUND
    ambient: Fraction = Lighting.ambient
    noise_std: Annotated[float, Range(0.0, 64.0)] = 0.0  # 8-bit levels
    gain_amplitude: Annotated[float, Range(0.0, 0.5)] = 0.0  # relative
    gain_period_frames: Positive = 150.0

    def renderer(self, width: int, height: int) -> SceneRenderer:
        return SceneRenderer(width, height, background_rgb=self.background_rgb, lighting=Lighting(ambient=self.ambient))

    def nuisance(self) -> SensorNuisance | None:
        """The configured sensor noise and illumination change, or None when both are off."""
        if self.noise_std == 0 and self.gain_amplitude == 0:
            return None
        return SensorNuisance(self.noise_std, self.gain_amplitude, self.gain_period_frames)
