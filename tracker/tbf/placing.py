"""Where the observed person stands, frame by frame: the tracker's alignment modes (`TbfSettings.align`) as one
interface, each built on `tracker.tbf.alignment`.

A mode `place`s the frame's observed silhouettes (one per view, in the rig's order) into the samples' frame, as the
filter scores them, and gives back where the person stood (`Placed`); `estimate` then puts the filter's sample
there; `columns` are the frame's columns of it in the run's table.
    `AsSeen`        ``none``: the silhouettes as they are, the sample as it is.
    `FeetAligned`   ``feet``: each view's silhouette moved by whole pixels onto the samples' feet; the estimate's
                    root moved back by as much (the mean over views).
    `GroundPlaced`  ``ground``, one view: placed on the floor (`tracker.tbf.alignment.GroundPlacement`); with
                    anchors, on a reference sample's, the filter scoring each sample from its own.
    `ViewsPlaced`   ``ground``, several views: placed on a reference sample's spot, where the views' centroid
                    rays cross (`tracker.tbf.alignment.ViewsPlacement`); the filter scores each sample from it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.tbf.alignment import (
    GroundPlacement,
    Placement,
    ViewsPlacement,
    feet_anchor,
    samples_anchor,
    shifted,
    world_offset,
)
from tracker.tbf.samples import SampleViews

Resize = Callable[[np.ndarray], np.ndarray]  # a silhouette at the finest level's resolution


@dataclass(frozen=True, eq=False)
class Placed:
    """One frame's placing: the silhouettes the filter sees (finest level where placed; None for a view that lost
    the person while another sees him), the sample whose spot they were placed on (several views; None otherwise),
    and how (the mode's own record, for `estimate` and `columns`)."""

    silhouettes: tuple[np.ndarray | None, ...]
    reference: int | None = None
    how: Any = None


class AsSeen:
    def place(self, observed: Sequence[np.ndarray]) -> Placed:
        return Placed(tuple(observed))

    def estimate(self, sample: int, pose: np.ndarray, placed: Placed) -> np.ndarray:
        return pose.copy()

    def columns(self, placed: Placed) -> dict[str, float]:
        return {}


class FeetAligned(AsSeen):
    def __init__(self, cameras: Sequence[Camera], samples: SampleViews) -> None:
        self.cameras = tuple(cameras)
        self.anchors = [samples_anchor(view) for view in samples.sets]

    def place(self, observed: Sequence[np.ndarray]) -> Placed:
        shifts = [self._shift(anchor, silhouette) for anchor, silhouette in zip(self.anchors, observed, strict=True)]
        moved = tuple(
            shifted(silhouette, *shift) if any(shift) else silhouette
            for silhouette, shift in zip(observed, shifts, strict=True)
        )
        return Placed(moved, how=shifts)

    @staticmethod
    def _shift(anchor: tuple[float, float], observed: np.ndarray) -> tuple[int, int]:
        """Whole pixels ``(du, dv)`` that move the observed feet onto the samples' (none without feet)."""
        found = feet_anchor(observed)
        if found is None:
            return 0, 0
        return int(round(anchor[0] - found[0])), int(round(anchor[1] - found[1]))

    def estimate(self, sample: int, pose: np.ndarray, placed: Placed) -> np.ndarray:
        """The sample's pose with its root moved back by the views' shifts (their mean): the subject stands away
        from the samples' spot, and so does the estimate."""
        estimate = pose.copy()
        if any(any(shift) for shift in placed.how):
            estimate[:3] += np.mean(
                [
                    world_offset(camera, estimate[:3], -du, -dv) if du or dv else np.zeros(3)
                    for camera, (du, dv) in zip(self.cameras, placed.how, strict=True)
                ],
                axis=0,
            )
        return estimate

    def columns(self, placed: Placed) -> dict[str, float]:
        du, dv = placed.how[0]
        return {"align_du_px": du, "align_dv_px": dv}


class GroundPlaced(AsSeen):
    def __init__(self, placement: GroundPlacement, finest: Resize) -> None:
        self.placement, self.finest = placement, finest

    def place(self, observed: Sequence[np.ndarray]) -> Placed:
        silhouette = self.finest(observed[0])
        # with anchors, the filter scores each sample from its own, the reference's being where it was placed
        reference = None if self.placement.anchors is None else self.placement.reference
        placement: Placement | None = self.placement.place(silhouette)  # None: no feet below the horizon
        return Placed((placement.silhouette if placement else silhouette,), reference, how=placement)

    def estimate(self, sample: int, pose: np.ndarray, placed: Placed) -> np.ndarray:
        return pose.copy() if placed.how is None else self.placement.pose(sample, placed.how)

    def columns(self, placed: Placed) -> dict[str, float]:
        return {"placement_scale": placed.how.scale if placed.how else float("nan")}


class ViewsPlaced(AsSeen):
    def __init__(self, placement: ViewsPlacement, finest: Resize) -> None:
        self.placement, self.finest = placement, finest

    def place(self, observed: Sequence[np.ndarray]) -> Placed:
        silhouettes = [self.finest(silhouette) for silhouette in observed]
        reference = self.placement.reference
        placed = self.placement.place(silhouettes)  # None: someone is out of a view
        if placed is None:
            return Placed(tuple(silhouettes), reference)
        moved, offset = placed
        return Placed(tuple(moved), reference, offset)

    def estimate(self, sample: int, pose: np.ndarray, placed: Placed) -> np.ndarray:
        """The sample moved across the floor until its spot is the person's; it becomes the next reference."""
        return pose.copy() if placed.how is None else self.placement.pose(sample, placed.how)

    def columns(self, placed: Placed) -> dict[str, float]:
        dx, dy = placed.how[:2] if placed.how is not None else (float("nan"), float("nan"))
        return {"placement_dx_m": float(dx), "placement_dy_m": float(dy)}


Placing = AsSeen | FeetAligned | GroundPlaced | ViewsPlaced
