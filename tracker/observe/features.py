"""Feature points tracked through a view's images: Shi-Tomasi corners and pyramidal Lucas-Kanade (paper 1, step 1).

Each feature keeps an id for as long as it is tracked. Per frame a track survives if LK finds it forwards, finds
its way back (forward-backward error below a threshold) and stays inside the image; otherwise it is lost. New
corners are then detected only away from the surviving tracks, so they fill in where tracks thinned out.
Positions are ``(n, 2)`` float64 ``(u, v)`` in the OpenCV pixel convention of `tracker.geometry.cameras`. The
tracker sees only the images: never the model or the truth.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Annotated

import cv2
import numpy as np

from tracker.ranges import Count, Positive, Range


@dataclass(frozen=True)
class FeatureSettings:
    """Shi-Tomasi corners tracked by pyramidal Lucas-Kanade with a forward-backward check."""

    max_features: Count = 300  # per view
    # Shi-Tomasi: corners weaker than this fraction of the strongest are ignored
    quality_level: Annotated[float, Range(0.0, 1.0, low_open=True)] = 0.01
    min_distance_px: Positive = 5.0  # between corners, and between a new corner and a surviving track
    block_size: Annotated[int, Range(3, 31)] = 5
    window_px: Annotated[int, Range(5, 101)] = 15  # Lucas-Kanade window side
    pyramid_levels: Annotated[int, Range(1, 8)] = 3
    # Tracks on the rendered arm come back within 0.17 px 95% of the time (0.25 px: 96.3%, 0.5 px: 97.6%); at
    # 0.25 px two thirds of the "swaps" to a look-alike corner of an occluder are rejected, which 0.5 px lets pass.
    # The swaps that remain are the false matches AbIS discards by their residual after fitting (paper 1, 4.3).
    max_forward_backward_px: Positive = 0.25


@dataclass(frozen=True, eq=False)
class FeatureFrame:
    """The features of one view at one frame.

    ids ``(n,)`` int64 and points ``(n, 2)``: every live feature (tracked ones first, then new ones);
    new ``(n,)`` bool: detected this frame; lost_ids: ids that were live last frame and are not now;
    gray ``(h, w)`` uint8: the image they were found in.
    """

    ids: np.ndarray
    points: np.ndarray
    new: np.ndarray
    lost_ids: np.ndarray
    gray: np.ndarray

    @property
    def tracked(self) -> np.ndarray:
        return ~self.new


class FeatureTracker:
    """Tracks features through the images of one view. Call `step` with each frame's RGB image in order."""

    def __init__(self, settings: FeatureSettings = FeatureSettings(), first_id: int = 0) -> None:
        self.settings = settings
        self._next_id = first_id
        self._gray: np.ndarray | None = None
        self._ids = np.empty(0, dtype=np.int64)
        self._points = np.empty((0, 2))

    def step(self, rgb: np.ndarray) -> FeatureFrame:
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        previous_ids = self._ids
        if self._gray is None or len(self._ids) == 0:
            kept, points = np.zeros(len(self._ids), bool), np.empty((0, 2))
        else:
            kept, points = self._track(self._gray, gray)
        ids = previous_ids[kept]
        new_points = self._detect(gray, points)
        new_ids = np.arange(self._next_id, self._next_id + len(new_points), dtype=np.int64)
        self._next_id += len(new_points)
        self._gray = gray
        self._ids = np.concatenate([ids, new_ids])
        self._points = np.concatenate([points, new_points])
        return FeatureFrame(
            ids=self._ids,
            points=self._points,
            new=np.concatenate([np.zeros(len(ids), bool), np.ones(len(new_ids), bool)]),
            lost_ids=previous_ids[~kept],  # sorted: ids are handed out in increasing order, tracks keep their order
            gray=gray,
        )

    def _track(self, previous: np.ndarray, current: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which live features are found in ``current`` (a mask), and where they are found (``(kept, 2)``)."""
        s = self.settings
        lk = dict(
            winSize=(s.window_px, s.window_px),
            maxLevel=s.pyramid_levels - 1,
            criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01),
        )
        start = self._points.astype(np.float32).reshape(-1, 1, 2)
        forward, found, _ = cv2.calcOpticalFlowPyrLK(previous, current, start, None, **lk)
        back, found_back, _ = cv2.calcOpticalFlowPyrLK(current, previous, forward, None, **lk)
        forward, back = forward.reshape(-1, 2).astype(np.float64), back.reshape(-1, 2)
        height, width = current.shape
        inside = np.all((forward >= 0) & (forward <= [width - 1, height - 1]), axis=1)
        consistent = np.linalg.norm(back - self._points, axis=1) <= s.max_forward_backward_px
        keep = found.ravel().astype(bool) & found_back.ravel().astype(bool) & inside & consistent
        return keep, forward[keep]

    def _detect(self, gray: np.ndarray, existing: np.ndarray) -> np.ndarray:
        s = self.settings
        wanted = s.max_features - len(existing)
        if wanted <= 0:
            return np.empty((0, 2))
        mask = away_from(gray.shape, np.rint(existing).astype(int), int(np.ceil(s.min_distance_px)))
        box = detection_box(gray, 2 * (s.block_size // 2 + 1))
        if box is None:  # a constant image: no corner anywhere
            return np.empty((0, 2))
        v0, v1, u0, u1 = box
        corners = cv2.goodFeaturesToTrack(
            gray[v0:v1, u0:u1],
            maxCorners=wanted,
            qualityLevel=s.quality_level,
            minDistance=s.min_distance_px,
            mask=mask[v0:v1, u0:u1],
            blockSize=s.block_size,
        )
        if corners is None:
            return np.empty((0, 2))
        return corners.reshape(-1, 2).astype(np.float64) + [u0, v0]


def detection_box(gray: np.ndarray, margin: int) -> tuple[int, int, int, int] | None:
    """``(v0, v1, u0, u1)``: the rectangle of ``gray`` where Shi-Tomasi can find a corner, and on which it finds the
    same ones as on the whole image (None: nowhere, the image is constant). Where the image is locally constant the
    corner response is exactly 0: beyond the box of pixels that differ from a neighbour, the image is one value,
    and a pixel farther from that box than the response's support (``margin`` >= twice it: its gradients' and
    window's) has response 0 whether the rest is drawn or reflected at the rectangle's edge. An image with sensor
    noise differs everywhere: its whole rectangle, found from its edges alone."""
    height, width = gray.shape
    edges = (gray[0], gray[-1], gray[:, 0], gray[:, -1])
    if all(np.any(line[1:] != line[:-1]) for line in edges):  # varying along all four edges: the whole image
        return 0, height, 0, width
    across, down = gray[:, 1:] != gray[:, :-1], gray[1:] != gray[:-1]  # neighbours that differ, both of each pair
    rows = np.flatnonzero(across.any(axis=1) | np.r_[down.any(axis=1), False] | np.r_[False, down.any(axis=1)])
    columns = np.flatnonzero(down.any(axis=0) | np.r_[across.any(axis=0), False] | np.r_[False, across.any(axis=0)])
    if not len(rows):
        return None
    return (
        max(int(rows[0]) - margin, 0),
        min(int(rows[-1]) + 1 + margin, height),
        max(int(columns[0]) - margin, 0),
        min(int(columns[-1]) + 1 + margin, width),
    )


def away_from(shape: tuple[int, int], centres: np.ndarray, radius: int) -> np.ndarray:
    """A ``shape`` uint8 mask, 255 but on a filled disc of ``radius`` around each integer centre ``(n, 2)`` (u, v),
    where it is 0: no new corner next to a live track. The disc is OpenCV's own (`cv2.circle`, filled), stamped at
    every centre at once and cut at the image's edges, the same pixels as drawing each."""
    du, dv = _disc(radius)
    rows, columns = centres[:, 1, None] + dv, centres[:, 0, None] + du
    inside = (rows >= 0) & (rows < shape[0]) & (columns >= 0) & (columns < shape[1])
    mask = np.full(shape, 255, np.uint8)
    mask[rows[inside], columns[inside]] = 0
    return mask


@functools.cache
def _disc(radius: int) -> tuple[np.ndarray, np.ndarray]:
    """The pixel offsets (du, dv) of `cv2.circle`'s filled disc of ``radius``."""
    stamp = np.zeros((2 * radius + 1, 2 * radius + 1), np.uint8)
    cv2.circle(stamp, (radius, radius), radius, 1, thickness=-1)
    dv, du = np.nonzero(stamp)
    return du - radius, dv - radius
