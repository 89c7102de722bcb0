"""Camera rigs: the paper-1 three orthogonal views and a single camera.

World frame of the rigs: metres, z up. The orthogonal rig's views are named after where they look from:
``front`` looks along +y, ``left`` along +x, ``top`` along -z; all aim at ``target``.
"""

from __future__ import annotations

import numpy as np

from tracker.geometry.cameras import Camera, look_at
from tracker.ranges import ImageSide, Positive, Vector3
from tracker.registry import RIGS

Rig = tuple[Camera, ...]

_UP = np.array([0.0, 0.0, 1.0])


@RIGS.register("orthogonal3", views=(3, 3))
def orthogonal3(
    *,
    target: Vector3 = (0.0, 0.0, 0.0),
    front_distance: Positive = 2.0,
    left_distance: Positive = 2.0,
    top_distance: Positive = 2.0,
    focal_px: Positive = 400.0,
    width: ImageSide = 320,
    height: ImageSide = 240,
) -> Rig:
    """Paper 1's three orthogonal views (front, left, top) of ``target``."""
    target = np.asarray(target, dtype=np.float64)
    intrinsics = dict(width=width, height=height, focal_px=focal_px)
    return (
        look_at("front", target - [0.0, front_distance, 0.0], target, _UP, **intrinsics),
        look_at("left", target - [left_distance, 0.0, 0.0], target, _UP, **intrinsics),
        # Looking down, world +y points up in the image.
        look_at("top", target + [0.0, 0.0, top_distance], target, np.array([0.0, 1.0, 0.0]), **intrinsics),
    )


@RIGS.register("mono", views=(1, 1))
def mono(
    *,
    position: Vector3 = (0.0, -3.0, 1.0),
    target: Vector3 = (0.0, 0.0, 1.0),
    up: Vector3 = (0.0, 0.0, 1.0),
    focal_px: Positive = 400.0,
    width: ImageSide = 320,
    height: ImageSide = 240,
    name: str = "main",
) -> Rig:
    """One camera at ``position`` looking at ``target`` (paper 2's setting)."""
    return (look_at(name, np.asarray(position), np.asarray(target), np.asarray(up), width=width, height=height,
                    focal_px=focal_px),)
