"""Silhouettes by background subtraction (paper 2, 5.1), from the camera's RGB image, never the render mask.

`BackgroundModel.learn` takes background-only frames and keeps, per pixel, the mean and variance of the
brightness-normalised colour ``c = (R, G, B) / (R + G + B)`` (a diagonal Gaussian: the paper's likelihood) and the
mean raw colour. A pixel is silhouette when its normalised colour is unlikely under that Gaussian (squared
Mahalanobis distance above ``chroma_threshold**2``) or when its raw colour differs from the background's mean by
more than ``color_threshold`` 8-bit levels (objects that differ from the backdrop in brightness only). A 3x3
opening then closing removes isolated noise pixels and pinholes. Images are ``(h, w, 3)`` uint8; silhouettes
``(h, w)`` bool.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Annotated

import cv2
import numpy as np

from tracker.ranges import Positive, Range
from tracker.settings import validate


@dataclass(frozen=True)
class SilhouetteSettings:
    """Background subtraction: the thresholds, the clean-up, and how many empty frames the background is learnt
    from."""

    chroma_threshold: Positive = 5.0  # sigmas of the background's normalised colour
    color_threshold: Positive = 60.0  # 8-bit levels, Euclidean over RGB
    min_chroma_std: Positive = 0.004  # floor of the learnt per-pixel sigma (a perfectly still pixel has none)
    cleanup_px: Annotated[int, Range(0, 15)] = 3  # side of the opening/closing kernel; 0 or 1: none
    background_frames: Annotated[int, Range(2, 1000)] = 20  # of the empty scene, before the subject walks in

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, eq=False)
class BackgroundModel:
    chroma_mean: np.ndarray  # (h, w, 3) float32
    chroma_inverse_std: np.ndarray  # (h, w, 3) float32
    color_mean: np.ndarray  # (h, w, 3) float32
    settings: SilhouetteSettings

    @classmethod
    def learn(cls, frames: np.ndarray, settings: SilhouetteSettings = SilhouetteSettings()) -> BackgroundModel:
        """From ``(n, h, w, 3)`` uint8 background-only frames (n >= 2)."""
        frames = np.asarray(frames)
        if frames.ndim != 4 or frames.shape[-1] != 3 or len(frames) < 2:
            raise ValueError(f"learning a background needs (n >= 2, h, w, 3) frames, got shape {frames.shape}")
        chroma = normalised_colour(frames)
        std = np.maximum(chroma.std(axis=0), settings.min_chroma_std)
        return cls(chroma.mean(axis=0), (1.0 / std).astype(np.float32), frames.mean(axis=0, dtype=np.float32), settings)

    def silhouette(self, rgb: np.ndarray) -> np.ndarray:
        """``(h, w)`` bool: the pixels of ``rgb`` that are not background."""
        if rgb.shape != self.color_mean.shape:
            raise ValueError(f"image of shape {rgb.shape}, the background model is {self.color_mean.shape}")
        s = self.settings
        colour = rgb.astype(np.float32)
        z = (_normalise(colour) - self.chroma_mean) * self.chroma_inverse_std
        unlikely = _channel_sum(z * z) > s.chroma_threshold**2
        difference = colour - self.color_mean
        different = _channel_sum(difference * difference) > s.color_threshold**2
        mask = (unlikely | different).astype(np.uint8)
        if s.cleanup_px > 1:
            kernel = np.ones((s.cleanup_px, s.cleanup_px), np.uint8)
            mask = cv2.morphologyEx(cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel), cv2.MORPH_CLOSE, kernel)
        return mask.astype(bool)


def normalised_colour(rgb: np.ndarray) -> np.ndarray:
    """``(..., 3)`` float32 colour divided by its sum R + G + B (black stays 0)."""
    colour = np.asarray(rgb, dtype=np.float32)
    return _normalise(colour.reshape(-1, *colour.shape[-2:]) if colour.ndim > 3 else colour).reshape(colour.shape)


def _normalise(colour: np.ndarray) -> np.ndarray:
    """``(h, w, 3)`` float32 colour over its channel sum (at least 1: 8-bit levels)."""
    return colour * (1.0 / np.maximum(_channel_sum(colour), 1.0))[..., None]


def _channel_sum(image: np.ndarray) -> np.ndarray:
    """``(h, w, 3)`` float32 -> ``(h, w)``: the sum over channels (OpenCV: numpy's reduction over the last axis
    of an interleaved image is several times slower)."""
    return cv2.transform(image, np.ones((1, 3), np.float32))


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1.0 when both are empty)."""
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


@dataclass(frozen=True, eq=False)
class CapturedFrame:
    """One frame's extracted silhouettes per view, their IoU against the render's mask, and the time taken."""

    silhouettes: dict[str, np.ndarray]
    iou: dict[str, float]
    ms: float


class SilhouetteCapture:
    """Background subtraction per view: `learn` from empty-scene frames, then `step` on each frame's images."""

    def __init__(self, backgrounds: dict[str, BackgroundModel]) -> None:
        self.backgrounds = backgrounds

    @classmethod
    def learn(cls, frames: dict[str, np.ndarray], settings: SilhouetteSettings = SilhouetteSettings()):
        return cls({name: BackgroundModel.learn(images, settings) for name, images in frames.items()})

    def step(self, rgb: dict[str, np.ndarray], masks: dict[str, np.ndarray] | None = None) -> CapturedFrame:
        """Silhouettes of the views' ``rgb``; with the render's ``masks`` (truth, for evaluation only) their IoU."""
        start = time.perf_counter()
        silhouettes = {name: self.backgrounds[name].silhouette(image) for name, image in rgb.items()}
        ms = 1e3 * (time.perf_counter() - start)
        scores = {name: iou(silhouettes[name], mask) for name, mask in (masks or {}).items()}
        return CapturedFrame(silhouettes, scores, ms)


def resize_silhouette(silhouette: np.ndarray, width: int, height: int) -> np.ndarray:
    """The silhouette at ``width`` x ``height``: a pixel is in when at least half of the area it covers is."""
    coverage = cv2.resize(silhouette.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)
    return coverage >= 0.5
