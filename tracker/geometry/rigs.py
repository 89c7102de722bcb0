"""Camera rigs: the paper-1 three orthogonal views, a single camera, and any number of named cameras.

World frame of the rigs: metres, z up. The orthogonal rig's views are named after where they look from:
``front`` looks along +y, ``left`` along +x, ``top`` along -z; all aim at ``target``. A rig's cameras are in the
order they are given; a tracker that uses one view uses the first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.geometry.cameras import Camera, look_at
from tracker.ranges import ImageSide, Positive, Vector3
from tracker.registry import RIGS

Rig = tuple[Camera, ...]

_UP = np.array([0.0, 0.0, 1.0])


@RIGS.register("orthogonal3")
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


@RIGS.register("mono")
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
    return (
        look_at(
            name,
            np.asarray(position),
            np.asarray(target),
            np.asarray(up),
            width=width,
            height=height,
            focal_px=focal_px,
        ),
    )


@dataclass(frozen=True)
class View:
    """One camera of a `cameras` rig: its name and where it stands (it looks at the rig's target)."""

    name: str
    position: Vector3


def check_views(rig, frames: int, key: str, model: str) -> None:
    """Before a run: a `cameras` rig has at least one camera, each with its own name, none at the target."""
    names = [view.name for view in rig.views]
    if not names:
        raise ValueError(f"{key}.views=[]: allowed one camera or more")
    if len(set(names)) < len(names):
        raise ValueError(f"{key}.views: names {names} repeat; allowed distinct names")
    for k, view in enumerate(rig.views):
        if np.allclose(view.position, rig.target):
            raise ValueError(f"{key}.views[{k}].position={list(view.position)}: it is the target; allowed elsewhere")


@RIGS.register("cameras", check=check_views)
def cameras(
    *,
    views: tuple[View, ...] = (View("front", (0.0, -4.5, 0.9)),),
    target: Vector3 = (0.0, 0.0, 0.9),
    up: Vector3 = (0.0, 0.0, 1.0),
    focal_px: Positive = 420.0,
    width: ImageSide = 320,
    height: ImageSide = 240,
) -> Rig:
    """Named cameras, each at its position looking at ``target``, alike inside (e.g. several views of a body)."""
    return tuple(
        look_at(
            view.name,
            np.asarray(view.position, dtype=np.float64),
            np.asarray(target, dtype=np.float64),
            np.asarray(up, dtype=np.float64),
            width=width,
            height=height,
            focal_px=focal_px,
        )
        for view in views
    )
