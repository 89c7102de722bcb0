"""Silhouette distances of paper 2 (5.2): XOR (eq 6), core-weighted XOR (wXOR, eq 7-8), normalised wXOR (eq 9).

All three are ``d(P, Q) = (1/N_W) sum_{x in W} d_P(x) XOR(P(x), Q(x))`` for the observed silhouette P and a model
silhouette Q over the window W (a rectangle holding every pose of the sample set; N_W its pixel count), with the
weight map d_P of P alone:
    xor    d_P = 1
    wxor   d_P = D_P + w D_Pbar           D_P: distance of a pixel inside P to the nearest pixel outside it,
                                          D_Pbar: distance of a pixel outside P (within W) to the nearest in it
    nwxor  d_P = D_P / (D_P + D_Pmed) + w' D_Pbar
                                          D_Pmed: distance to P's medial axis (the thinned silhouette); the inner
                                          term is 1 on the axis of a thin limb and of the torso alike; w' makes the
                                          outer term's maximum over W equal the inner one's (1)
Distances are Euclidean, in pixels of the silhouette's resolution. Silhouettes are ``(h, w)`` bool; a window is
``(u0, v0, u1, v1)``, half-open pixel bounds.

Each cost is a function of the observed silhouette (cropped to W) that returns its weights d_P there, registered
by name in `tracker.registry.COSTS` with its settings (wXOR's ``w``) as keyword-only parameters; a new cost is one
such function and its registration. `silhouette_distance` is the definition for one pair; `tracker.tbf.scoring`
scores one observation against many model silhouettes at once.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from skimage.morphology import skeletonize

from tracker.ranges import NonNegative
from tracker.registry import COSTS

Window = tuple[int, int, int, int]


class EmptySilhouette(ValueError):
    """The observed silhouette has no pixel inside the window: the weighted costs are undefined."""


def full_window(shape: tuple[int, int]) -> Window:
    return (0, 0, shape[1], shape[0])


def window_pixels(window: Window) -> int:
    """N_W: the window's pixel count."""
    u0, v0, u1, v1 = window
    return (u1 - u0) * (v1 - v0)


def euclidean_distance(away: np.ndarray) -> np.ndarray:
    """Per pixel where ``away`` is true, the exact Euclidean distance (pixels) to the nearest pixel where it is
    false; 0 where it is false (inf everywhere if no pixel is). The square root of a whole number of squared
    pixels, as SciPy's ``distance_transform_edt`` gives it: the same bits."""
    return _exact_distances(np.ascontiguousarray(away, dtype=bool))


@numba.njit(cache=True, nogil=True)
def _exact_distances(away: np.ndarray) -> np.ndarray:
    """`euclidean_distance` by Meijster, Roerdink and Hesselink's two passes (2000): down the columns, each pixel's
    distance to the nearest pixel off ``away`` in its column; then along each row, the lower envelope of the
    parabolas ``(x - i)^2 + column(i)^2`` over the columns that hold such a pixel. Integer arithmetic throughout
    (exact), then the square root (correctly rounded)."""
    height, width = away.shape
    far = height + width  # farther than any pixel of the image: where a column holds no pixel off `away`
    column = np.empty((height, width), np.int64)
    for x in range(width):
        column[0, x] = far if away[0, x] else 0
    for y in range(1, height):
        for x in range(width):
            column[y, x] = column[y - 1, x] + 1 if away[y, x] else 0
    for y in range(height - 2, -1, -1):
        for x in range(width):
            if column[y + 1, x] + 1 < column[y, x]:
                column[y, x] = column[y + 1, x] + 1
    near = np.flatnonzero(column[0] < far) if height else np.zeros(0, np.int64)  # the columns that hold one
    distance = np.empty((height, width))
    centre = np.empty(width, np.int64)  # the envelope's parabolas, left to right, by their column
    start = np.empty(width, np.int64)  # the first x where each is the lowest
    lift = np.empty(width, np.int64)  # column(i)^2 along the row
    for y in range(height):
        row, out = column[y], distance[y]
        top = -1
        for u in near:
            lift[u] = row[u] * row[u]
            while top >= 0:
                x, i = start[top], centre[top]
                if (x - i) * (x - i) + lift[i] <= (x - u) * (x - u) + lift[u]:
                    break
                top -= 1
            if top < 0:
                top, centre[0], start[0] = 0, u, 0
                continue
            i = centre[top]
            above, apart = u * u - i * i + lift[u] - lift[i], 2 * (u - i)
            if above < (width - 1) * apart:  # u is the lowest from within the row on (divided only then)
                top += 1
                centre[top], start[top] = u, 1 + above // apart
        if top < 0:  # no pixel off `away` anywhere: none is near
            out[:] = np.inf
            continue
        i, first = centre[top], start[top]
        for x in range(width - 1, -1, -1):
            out[x] = math.sqrt((x - i) * (x - i) + lift[i])
            if x == first and top > 0:
                top -= 1
                i, first = centre[top], start[top]
    return distance


def bounding_box(silhouette: np.ndarray) -> tuple[slice, slice]:
    """The rows and columns of the smallest rectangle holding the silhouette (empty slices for none)."""
    rows, columns = np.flatnonzero(silhouette.any(axis=1)), np.flatnonzero(silhouette.any(axis=0))
    if not len(rows):
        return slice(0, 0), slice(0, 0)
    return slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1)


def inside_distance(silhouette: np.ndarray) -> np.ndarray:
    """D_P: per pixel of the silhouette, the Euclidean distance to the nearest pixel outside it (0 outside).
    The image border counts as outside."""
    distance = np.zeros(silhouette.shape)
    box, framed = _framed_box(silhouette)
    distance[box] = _inside_distance_in_frame(framed)
    return distance


def _framed_box(silhouette: np.ndarray) -> tuple[tuple[slice, slice], np.ndarray]:
    """The silhouette's `bounding_box`, and its crop framed by one pixel outside (as ``np.pad(crop, 1)``, without
    its cost on small images): the inner terms are measured on it, as a pixel's nearest outside pixel lies in that
    frame or nearer and thinning sees only a pixel's neighbours."""
    box = bounding_box(silhouette)
    crop = silhouette[box]
    framed = np.zeros((crop.shape[0] + 2, crop.shape[1] + 2), bool)
    framed[1:-1, 1:-1] = crop
    return box, framed


def _inside_distance_in_frame(framed: np.ndarray) -> np.ndarray:
    """`inside_distance` on a `_framed_box` crop, the frame left out."""
    return euclidean_distance(framed)[1:-1, 1:-1]


def outside_distance(silhouette: np.ndarray) -> np.ndarray:
    """D_Pbar: per pixel outside the silhouette, the Euclidean distance to the nearest silhouette pixel."""
    if not silhouette.any():
        raise EmptySilhouette("the silhouette is empty: no distance to it")
    return euclidean_distance(~silhouette)


def medial_axis_distance(silhouette: np.ndarray) -> np.ndarray:
    """D_Pmed: per pixel of the silhouette, the Euclidean distance to its thinned centre line (skeleton); 0
    outside it."""
    distance = np.zeros(silhouette.shape)
    box, framed = _framed_box(silhouette)
    distance[box] = _medial_axis_distance_in_frame(framed)
    return distance


def _medial_axis_distance_in_frame(framed: np.ndarray) -> np.ndarray:
    """`medial_axis_distance` on a `_framed_box` crop, the frame left out."""
    axis = skeletonize(framed)
    if not axis.any():
        raise EmptySilhouette("the silhouette is empty: it has no medial axis")
    distance = euclidean_distance(~axis)[1:-1, 1:-1]
    distance[~framed[1:-1, 1:-1]] = 0.0
    return distance


@COSTS.register("xor")
def xor(inside: np.ndarray) -> np.ndarray:
    """Eq 6: every pixel where the silhouettes differ counts 1 (the fraction of the window that differs)."""
    return np.ones(inside.shape)


# wXOR and nwXOR compute their inner terms on the silhouette's bounding box (0 outside it) and add them onto the
# outer term, which spans the window.


@COSTS.register("wxor")
def wxor(inside: np.ndarray, *, w: NonNegative = 1.0) -> np.ndarray:
    """Eq 7-8: XOR weighted by the distance to the observed silhouette's contour, inside + w outside."""
    box, framed = _framed_box(inside)
    core = _inside_distance_in_frame(framed)
    outer = outside_distance(inside)
    weights = np.multiply(outer, w, out=outer)
    weights[box] += core
    return weights


@COSTS.register("nwxor")
def nwxor(inside: np.ndarray) -> np.ndarray:
    """Eq 9: XOR weighted by the inside distance normalised by the local thickness, outside scaled to the same
    maximum (w' makes the two terms' maxima equal)."""
    box, framed = _framed_box(inside)
    core, to_axis = _inside_distance_in_frame(framed), _medial_axis_distance_in_frame(framed)
    outer = outside_distance(inside)
    inner = np.divide(core, core + to_axis, out=np.zeros_like(core), where=framed[1:-1, 1:-1])
    farthest = outer.max()
    weights = np.multiply(outer, inner.max() / farthest if farthest > 0 else 0.0, out=outer)
    weights[box] += inner
    return weights


Cost = Callable[[np.ndarray], np.ndarray]  # the observed silhouette, cropped to the window -> its weights there


def weight_map(cost: str | Cost, observed: np.ndarray, window: Window | None = None, **settings: Any) -> np.ndarray:
    """``(h, w)`` float64 d_P of ``cost`` (a registered name, with ``settings``, or a configured cost) for the
    observed silhouette, 0 outside the window. A cost that needs a silhouette to measure from (wXOR, nwXOR) raises
    `EmptySilhouette` when the window holds none of it."""
    u0, v0, u1, v1 = window or full_window(observed.shape)
    weights = np.zeros(observed.shape)
    weights[v0:v1, u0:u1] = window_weights(cost, observed, (u0, v0, u1, v1), **settings)
    return weights


def window_weights(cost: str | Cost, observed: np.ndarray, window: Window, **settings: Any) -> np.ndarray:
    """`weight_map` over the window only: ``(v1 - v0, u1 - u0)``."""
    weights_of = COSTS.build(cost, settings) if isinstance(cost, str) else cost
    u0, v0, u1, v1 = window
    return weights_of(np.asarray(observed, bool)[v0:v1, u0:u1])


def silhouette_distance(
    cost: str | Cost, observed: np.ndarray, model: np.ndarray, window: Window | None = None, **settings: Any
) -> float:
    """d(P, Q) for one pair, straight from the definition (the reference for `ObservationScorer`)."""
    u0, v0, u1, v1 = window or full_window(observed.shape)
    weights = weight_map(cost, observed, window, **settings)
    differs = np.logical_xor(observed, model)[v0:v1, u0:u1]
    return float((weights[v0:v1, u0:u1] * differs).sum() / window_pixels((u0, v0, u1, v1)))
