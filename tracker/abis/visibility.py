"""Which model points a view sees (paper 1, step 1-2): a z-buffer render of the current estimate decides.

A point of part j (a grid sample, or a pair's own surface point) is visible in a view when it projects inside the
image, the label image shows part j at its pixel (nothing else in front: occlusion by other parts) and the
z-buffer depth there is not more than `VISIBILITY_DEPTH_M` in front of the point (not behind its own part's near
side: self-occlusion).

The model's image also predicts occlusion: `region_labels_at` keeps new pairs off the occlusion edges, where two
parts meet in the label image, and `reached_by_other_parts` finds the points another part's edge reaches by the
next frame, moving as in the last one.

Without the model's image (`facing_samples`, the ablation ``tracker.selection=none``), a sample counts as seen when
it projects inside the image and its surface faces the camera: the back-face test alone, blind to other parts.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from tracker.geometry.cameras import Camera
from tracker.render.offscreen import DepthLabels
from tracker.tol import VISIBILITY_DEPTH_M


@dataclass(frozen=True, eq=False)
class VisibleSamples:
    """The samples a view sees: ``part`` and ``sample`` index ``(m,)`` int, projections ``uv`` ``(m, 2)``."""

    part: np.ndarray
    sample: np.ndarray
    uv: np.ndarray

    def __len__(self) -> int:
        return len(self.part)


def visible_mask(
    camera: Camera, zbuffer: DepthLabels, parts: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Which world points ``(n, 3)``, each on its part ``parts`` ``(n,)``, the view sees, and their pixels ``(n, 2)``.

    Part j must have label ``j + 1`` in ``zbuffer`` (the convention of `tracker.models.dsq_arm`).
    """
    uv, z = camera.project(points)
    shown, rows, columns = _shown_pixels(uv, np.ascontiguousarray(parts, dtype=np.int64), zbuffer.labels)
    nearest = z[shown] <= zbuffer.depth_at(rows, columns) + VISIBILITY_DEPTH_M
    seen = np.zeros(len(points), bool)
    seen[shown[nearest]] = True
    return seen, uv


@numba.njit(cache=True, nogil=True)
def _shown_pixels(uv: np.ndarray, parts: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points (indices) whose pixel, ``uv`` ``(n, 2)`` rounded to the nearest (half to even), lies in the image
    and shows their own part (label ``parts + 1``), and that pixel's row and column."""
    height, width = labels.shape
    shown, rows, columns = np.empty(len(uv), np.int64), np.empty(len(uv), np.int64), np.empty(len(uv), np.int64)
    count = 0
    for k in range(len(uv)):
        u, v = np.rint(uv[k, 0]), np.rint(uv[k, 1])
        if not (0 <= u <= width - 1 and 0 <= v <= height - 1):  # NaN too: behind the camera
            continue
        row, column = int(v), int(u)
        if labels[row, column] == parts[k] + 1:
            shown[count], rows[count], columns[count] = k, row, column
            count += 1
    return shown[:count], rows[:count], columns[:count]


def visible_samples(camera: Camera, zbuffer: DepthLabels, samples_world: Sequence[np.ndarray]) -> VisibleSamples:
    """Samples of every part (``samples_world[j]`` is part j's ``(n_j, 3)`` world points) visible in ``camera``,
    part after part (all parts' in one projection)."""
    counts = [len(points) for points in samples_world]
    parts = np.repeat(np.arange(len(counts)), counts)
    seen, uv = visible_mask(camera, zbuffer, parts, np.concatenate(samples_world).reshape(-1, 3))
    chosen = np.flatnonzero(seen)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)  # each part's first row
    return VisibleSamples(parts[chosen], chosen - first[parts[chosen]], uv[chosen])


def region_labels_at(
    labels: np.ndarray, rows: np.ndarray, columns: np.ndarray, occlusion_margin_px: int, boundary_margin_px: int
) -> np.ndarray:
    """The labels at pixels ``(rows, columns)`` ``(n,)``, 0 where the pixel is on an occlusion edge or near the
    silhouette: a part's pixel with another part (not the background) within ``occlusion_margin_px`` (a square
    neighbourhood, cut at the image's edge), where a feature's window straddles two parts' surfaces; or with another
    label, the background among them, within ``boundary_margin_px``. Each neighbourhood is read at the asked pixels
    alone, in one compiled pass (a view's few hundred features, not its whole image)."""
    labels = np.ascontiguousarray(labels)
    height, width = labels.shape
    rows, columns = np.asarray(rows, dtype=np.int64), np.asarray(columns, dtype=np.int64)
    if np.any((rows < -height) | (rows >= height) | (columns < -width) | (columns >= width)):
        raise IndexError(f"a pixel lies outside the {height}x{width} label image")
    rows, columns = np.where(rows < 0, rows + height, rows), np.where(columns < 0, columns + width, columns)
    return _region_labels(labels, rows, columns, max(int(occlusion_margin_px), 0), max(int(boundary_margin_px), 0))


@numba.njit(cache=True, nogil=True)
def _region_labels(labels, rows, columns, occlusion, boundary):
    """`region_labels_at` at pixels within the image, margins of at least 0."""
    height, width = labels.shape
    regions = np.zeros(len(rows), labels.dtype)
    for k in range(len(rows)):
        row, column, at = rows[k], columns[k], labels[rows[k], columns[k]]
        if at == 0:
            continue
        keep = True
        if occlusion > 0:  # another part within the margin: the largest and the smallest part label around differ
            largest, smallest = at, at
            for near_row in range(max(row - occlusion, 0), min(row + occlusion + 1, height)):
                for near_column in range(max(column - occlusion, 0), min(column + occlusion + 1, width)):
                    value = labels[near_row, near_column]
                    if value > 0:
                        largest, smallest = max(largest, value), min(smallest, value)
            keep = smallest == largest
        if keep and boundary > 0:  # any other label within the margin, the background too
            for near_row in range(max(row - boundary, 0), min(row + boundary + 1, height)):
                for near_column in range(max(column - boundary, 0), min(column + boundary + 1, width)):
                    keep = keep and labels[near_row, near_column] == at
        if keep:
            regions[k] = at
    return regions


def reached_by_other_parts(
    uv: np.ndarray,
    parts: np.ndarray,
    motion: np.ndarray,
    visible: VisibleSamples,
    visible_motion: np.ndarray,
    margin_px: float,
    most_px: float,
) -> np.ndarray:
    """``(n,)`` bool: which points, at pixels ``uv`` ``(n, 2)`` on ``parts`` ``(n,)`` and moving ``motion``
    ``(n, 2)`` px per frame, another part's visible sample (``visible``, moving ``visible_motion`` ``(m, 2)``) is
    within ``margin_px`` plus their relative motion (at most ``most_px``) of: another part's edge is at the point's
    feature window, or reaches it by the next frame if both keep moving as in the last one."""
    if len(uv) == 0 or len(visible) == 0:
        return np.zeros(len(uv), bool)
    as_floats = functools.partial(np.ascontiguousarray, dtype=np.float64)
    return _reached(
        as_floats(uv),
        np.ascontiguousarray(parts, dtype=np.int64),
        as_floats(motion),
        as_floats(visible.uv),
        np.ascontiguousarray(visible.part, dtype=np.int64),
        as_floats(visible_motion),
        float(margin_px),
        float(most_px),
    )


@numba.njit(cache=True, nogil=True)
def _reached(uv, parts, motion, sample_uv, sample_parts, sample_motion, margin_px, most_px):
    """`reached_by_other_parts`' test of every (point, sample) pair that can meet it: the samples sorted into square
    cells a hair wider than the farthest reach (``margin_px + most_px``; at least a 64th of their spread, so that
    the cells stay few), each point tried against the samples of its cell and the eight around it, which hold
    every sample within that reach of it."""
    low_u, low_v = sample_uv[:, 0].min(), sample_uv[:, 1].min()
    span_u, span_v = sample_uv[:, 0].max() - low_u, sample_uv[:, 1].max() - low_v
    cell = max((margin_px + most_px) * (1 + 1e-6), max(span_u, span_v) / 64, 1e-9)
    columns, rows = int(span_u / cell) + 1, int(span_v / cell) + 1
    cell_of = np.empty(len(sample_uv), np.int64)
    starts = np.zeros(rows * columns + 1, np.int64)
    for j in range(len(sample_uv)):
        cell_of[j] = int((sample_uv[j, 1] - low_v) / cell) * columns + int((sample_uv[j, 0] - low_u) / cell)
        starts[cell_of[j] + 1] += 1
    for k in range(rows * columns):
        starts[k + 1] += starts[k]
    order, filled = np.empty(len(sample_uv), np.int64), starts[:-1].copy()
    for j in range(len(sample_uv)):
        order[filled[cell_of[j]]] = j
        filled[cell_of[j]] += 1
    reached = np.zeros(len(uv), np.bool_)
    for i in range(len(uv)):
        column, row = math.floor((uv[i, 0] - low_u) / cell), math.floor((uv[i, 1] - low_v) / cell)
        for near_row in range(max(row - 1, 0), min(row + 2, rows)):
            for near_column in range(max(column - 1, 0), min(column + 2, columns)):
                k = near_row * columns + near_column
                if not reached[i]:
                    reached[i] = _reaches(
                        order[starts[k] : starts[k + 1]],
                        i,
                        uv,
                        parts,
                        motion,
                        sample_uv,
                        sample_parts,
                        sample_motion,
                        margin_px,
                        most_px,
                    )
    return reached


@numba.njit(cache=True, nogil=True)
def _reaches(near, i, uv, parts, motion, sample_uv, sample_parts, sample_motion, margin_px, most_px) -> bool:
    """Whether one of the samples ``near`` of another part than point ``i``'s is within ``margin_px`` plus their
    relative motion (at most ``most_px``) of it."""
    for j in near:
        if sample_parts[j] == parts[i]:
            continue
        du, dv = sample_uv[j, 0] - uv[i, 0], sample_uv[j, 1] - uv[i, 1]
        mu, mv = sample_motion[j, 0] - motion[i, 0], sample_motion[j, 1] - motion[i, 1]
        if math.sqrt(du * du + dv * dv) <= margin_px + min(math.sqrt(mu * mu + mv * mv), most_px):
            return True
    return False


def in_image(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which world points ``(n, 3)`` project inside ``camera``'s image, and their pixels ``(n, 2)``."""
    uv, _ = camera.project(points)
    pixel = np.rint(uv)
    inside = np.all(np.isfinite(pixel), axis=1)
    inside[inside] &= np.all((pixel[inside] >= 0) & (pixel[inside] <= [camera.width - 1, camera.height - 1]), 1)
    return inside, uv


def facing_samples(
    camera: Camera, samples_world: Sequence[np.ndarray], normals_world: Sequence[np.ndarray]
) -> VisibleSamples:
    """Samples of every part that project inside the image with their outward normal toward the camera."""
    parts, indices, uvs = [], [], []
    for part, (points, normals) in enumerate(zip(samples_world, normals_world, strict=True)):
        inside, uv = in_image(camera, points)
        facing = np.einsum("ij,ij->i", normals, camera.position - points) > 0
        chosen = np.flatnonzero(inside & facing)
        parts.append(np.full(len(chosen), part))
        indices.append(chosen)
        uvs.append(uv[chosen])
    return VisibleSamples(np.concatenate(parts), np.concatenate(indices), np.concatenate(uvs).reshape(-1, 2))


NORMAL_STEP_RAD = 1e-4  # central differences in eta and omega for a sample's normal


def outward_normals(surface, eta: np.ndarray, omega: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """``(n, 3)`` unit normals of ``surface(eta, omega)`` (world points) at its samples, turned away from
    ``centre`` (the part's own origin: its surface is star-shaped about it)."""
    h = NORMAL_STEP_RAD
    d_eta = surface(eta + h, omega) - surface(eta - h, omega)
    d_omega = surface(eta, omega + h) - surface(eta, omega - h)
    normals = np.cross(d_eta, d_omega)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    outward = np.einsum("ij,ij->i", normals, surface(eta, omega) - centre) >= 0
    return np.where(outward[:, None], normals, -normals)
