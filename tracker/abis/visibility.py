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

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

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
    pixel = np.rint(uv)
    inside = np.all(np.isfinite(pixel), axis=1)
    inside[inside] &= np.all((pixel[inside] >= 0) & (pixel[inside] <= [camera.width - 1, camera.height - 1]), 1)
    rows, columns = pixel[inside, 1].astype(int), pixel[inside, 0].astype(int)
    own_part = zbuffer.labels[rows, columns] == parts[inside] + 1
    nearest = z[inside] <= zbuffer.depth_at(rows, columns) + VISIBILITY_DEPTH_M
    seen = np.zeros(len(points), bool)
    seen[np.flatnonzero(inside)[own_part & nearest]] = True
    return seen, uv


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
    neighbourhood), where a feature's window straddles two parts' surfaces; or with another label, the background
    among them, within ``boundary_margin_px``. The neighbourhoods' extremes come from morphology over the labelled
    pixels' bounding box widened by the larger margin (beyond it every pixel is background, and so are the
    extremes around it: the same as over the whole image), the comparisons are made at the pixels alone (a view's
    few hundred features, not its whole image)."""
    at = labels[rows, columns]
    left, top, width, height = cv2.boundingRect(labels)  # of the labelled (non-zero) pixels
    if width == 0:
        return np.zeros_like(at)
    reach = max(occlusion_margin_px, boundary_margin_px, 0)
    v0, v1 = max(top - reach, 0), min(top + height + reach, labels.shape[0])
    u0, u1 = max(left - reach, 0), min(left + width + reach, labels.shape[1])
    inside = (rows >= v0) & (rows < v1) & (columns >= u0) & (columns < u1)
    regions = np.zeros_like(at)
    regions[inside] = _region_labels_in(
        labels[v0:v1, u0:u1], rows[inside] - v0, columns[inside] - u0, occlusion_margin_px, boundary_margin_px
    )
    return regions


def _region_labels_in(
    labels: np.ndarray, rows: np.ndarray, columns: np.ndarray, occlusion_margin_px: int, boundary_margin_px: int
) -> np.ndarray:
    """`region_labels_at` by whole-image morphology of ``labels``."""
    at = labels[rows, columns]
    keep = np.ones(len(at), bool)
    if occlusion_margin_px > 0:
        kernel = np.ones((2 * occlusion_margin_px + 1, 2 * occlusion_margin_px + 1), np.uint8)
        largest = cv2.dilate(labels, kernel)[rows, columns]
        # The smallest part label around, less one: the background (0) wraps to the byte's largest value, above
        # every part's; around a labelled pixel there is a part, so adding the one back is exact where it counts.
        smallest = cv2.erode(labels - np.uint8(1), kernel)[rows, columns].astype(int) + 1
        keep &= ~((at > 0) & (smallest < largest))
    if boundary_margin_px > 0:
        kernel = np.ones((2 * boundary_margin_px + 1, 2 * boundary_margin_px + 1), np.uint8)
        keep &= (cv2.erode(labels, kernel)[rows, columns] == at) & (cv2.dilate(labels, kernel)[rows, columns] == at)
    return np.where(keep, at, 0)


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
    # Every (point, sample) pair within the farthest reach, a hair wider so that no pair the test below keeps is
    # lost to the trees' own rounding: the test decides, by the same distances whatever the trees return.
    reach = (margin_px + most_px) * (1 + 1e-9)
    close = cKDTree(uv).sparse_distance_matrix(cKDTree(visible.uv), reach, output_type="ndarray")
    point, near = close["i"], close["j"]  # (k,): which point, and which visible sample near it
    distance = np.linalg.norm(visible.uv[near] - uv[point], axis=1)
    relative = np.minimum(np.linalg.norm(visible_motion[near] - motion[point], axis=1), most_px)
    hit = (visible.part[near] != parts[point]) & (distance <= margin_px + relative)
    return np.bincount(point[hit], minlength=len(uv)) > 0


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
