"""Camera rigs: the paper-1 three orthogonal views and a single camera.

World frame of the rigs: metres, z up. The orthogonal rig's views are named after where they look from:
``front`` looks along +y, ``left`` along +x, ``top`` along -z; all aim at ``target``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tracker.geometry.cameras import Camera, look_at

Rig = tuple[Camera, ...]

_UP = np.array([0.0, 0.0, 1.0])


def orthogonal3(
    *,
    target: Sequence[float],
    front_distance: float,
    left_distance: float,
    top_distance: float,
    focal_px: float,
    width: int,
    height: int,
) -> Rig:
    """Three orthogonal views (front, left, top) of ``target``, as in paper 1's experiment."""
    target = np.asarray(target, dtype=np.float64)
    intrinsics = dict(width=width, height=height, focal_px=focal_px)
    return (
        look_at("front", target - [0.0, front_distance, 0.0], target, _UP, **intrinsics),
        look_at("left", target - [left_distance, 0.0, 0.0], target, _UP, **intrinsics),
        # Looking down, world +y points up in the image.
        look_at("top", target + [0.0, 0.0, top_distance], target, np.array([0.0, 1.0, 0.0]), **intrinsics),
    )


def mono(
    *,
    position: Sequence[float],
    target: Sequence[float],
    up: Sequence[float] = (0.0, 0.0, 1.0),
    focal_px: float,
    width: int,
    height: int,
    name: str = "main",
) -> Rig:
    """A single camera (paper 2's setting)."""
    return (look_at(name, np.asarray(position), np.asarray(target), np.asarray(up), width=width, height=height,
                    focal_px=focal_px),)
