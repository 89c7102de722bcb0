"""Pairs of a model sample and an observed feature, per view, and their life cycle (paper 1, 4.1 and 4.3.2).

A pair links a feature track (its id) to a model sample (part, sample index in the part's grid). Frame 0 pairs
every feature with the nearest visible sample over all parts within a radius; each later frame the pairs whose
feature was tracked carry over, and after fitting the tracker discards pairs whose sample became invisible
(occlusion) or whose residual is too large (false match), then pairs the still-unpaired features again as in
frame 0. A sample takes at most one feature per view: the nearest wins (the paper's "best hypothesis").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Self

import numpy as np
from scipy.spatial import cKDTree

from tracker.abis.visibility import VisibleSamples
from tracker.geometry.cameras import Camera
from tracker.membership import members

COUNT_NAMES = ("tracked", "new", "discarded_occlusion", "discarded_error", "lost")
# Refining a pair's surface coordinates: the central-difference step, Gauss-Newton's damping, and how far eta
# keeps off the poles (where omega is degenerate), all in radians of eta and omega.
DIFFERENCE_STEP_RAD, GAUSS_NEWTON_DAMPING, POLE_MARGIN_RAD = 1e-5, 1e-6, 1e-3
_DAMPING = GAUSS_NEWTON_DAMPING * np.eye(2)


@dataclass(frozen=True, eq=False)
class PairTable:
    """Rows of one view's pairs, ``(k,)`` arrays: feature ids, parts and seed samples (the sample each pair formed
    at); a model's table adds where on the part each pair's own point is (`Pairs`, `tracker.abis.mesh_pairs`)."""

    feature_ids: np.ndarray
    parts: np.ndarray
    samples: np.ndarray

    def __len__(self) -> int:
        return len(self.feature_ids)

    def subset(self, keep: np.ndarray) -> Self:
        return type(self)(**{spec.name: getattr(self, spec.name)[keep] for spec in fields(self)})

    def extend(self, other: Self) -> Self:
        return self.joined([self, other])

    @classmethod
    def joined(cls, tables: Sequence[Self]) -> Self:
        """The rows of ``tables`` (at least one) one after another."""
        columns = {spec.name: [getattr(table, spec.name) for table in tables] for spec in fields(cls)}
        return cls(**{name: np.concatenate(values) for name, values in columns.items()})

    def count_by_part(self, n_parts: int) -> np.ndarray:
        return np.bincount(self.parts, minlength=n_parts)


@dataclass(frozen=True, eq=False)
class Pairs(PairTable):
    """A DSQ part's pairs: the model point's own surface coordinates (eta, omega) ``(k,)``, refined so that it lay
    exactly under its feature when the pair formed."""

    eta: np.ndarray
    omega: np.ndarray

    @classmethod
    def empty(cls) -> Pairs:
        return cls(np.empty(0, np.int64), np.empty(0, int), np.empty(0, int), np.empty(0), np.empty(0))


def pair_features(
    feature_ids: np.ndarray,
    feature_points: np.ndarray,
    visible: VisibleSamples,
    radius_px: float,
    grid_eta: np.ndarray,
    grid_omega: np.ndarray,
    taken: Pairs | None = None,
    feature_parts: np.ndarray | None = None,
) -> Pairs:
    """Pair features with the nearest visible sample within ``radius_px``, each sample at most once.

    Samples already in ``taken`` are not offered again. With ``feature_parts`` ``(n,)``, a feature pairs only with
    a sample of its part (-1: none), and the pairs come part after part, as if each part were paired alone (but for
    which of two samples at exactly the same distance from a feature is taken). The pairs' surface coordinates
    start at their samples' (``grid_eta``, ``grid_omega``); `refine_surface_coordinates` then moves them under the
    features.
    """
    if feature_parts is not None:
        own = feature_parts >= 0
        feature_ids, feature_points, feature_parts = feature_ids[own], feature_points[own], feature_parts[own]
    if len(feature_ids) == 0 or len(visible) == 0:
        return Pairs.empty()
    available = np.ones(len(visible), bool)
    if taken is not None and len(taken):
        available = ~members(sample_keys(visible.part, visible.sample), sample_keys(taken.parts, taken.samples))
    candidates = np.flatnonzero(available)
    if len(candidates) == 0:
        return Pairs.empty()
    samples_at, features_at = visible.uv[candidates], feature_points
    if feature_parts is not None:  # each part on a plane of its own, farther from the others' than the radius:
        apart = 2 * radius_px + 1  # a distance within a part is the same sum, plus 0
        samples_at = np.column_stack([samples_at, visible.part[candidates] * apart])
        features_at = np.column_stack([features_at, feature_parts * apart])
    distance, nearest = cKDTree(samples_at).query(features_at, distance_upper_bound=radius_px)
    within = np.isfinite(distance)
    order = np.argsort(distance[within], kind="stable")  # nearest first: it wins a contested sample
    features = np.flatnonzero(within)[order]
    chosen = candidates[nearest[within][order]]
    _, first = np.unique(chosen, return_index=True)
    winners = np.sort(first)
    if feature_parts is not None:
        winners = winners[np.argsort(visible.part[chosen[winners]], kind="stable")]
    samples = visible.sample[chosen[winners]]
    return Pairs(
        feature_ids[features[winners]],
        visible.part[chosen[winners]],
        samples,
        grid_eta[samples].copy(),
        grid_omega[samples].copy(),
    )


PixelsAt = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``(rows, eta, omega) -> (k, 2)``: the pixels of a batch's points ``rows`` put at surface coordinates (eta,
omega), each ``(k,)``; `surface_pixels` makes one."""


def surface_points(
    surfaces: Sequence[Callable[[np.ndarray, np.ndarray], np.ndarray]],
    parts: np.ndarray,
    eta: np.ndarray,
    omega: np.ndarray,
) -> np.ndarray:
    """World points ``(n, 3)`` at surface coordinates (eta, omega) ``(n,)``, each on its part's surface
    (``surfaces[parts[k]]``: (eta, omega) -> world points), every part's evaluated once."""
    points = np.empty((len(parts), 3))
    for part in np.unique(parts):
        mine = parts == part
        points[mine] = surfaces[part](eta[mine], omega[mine])
    return points


def surface_pixels(
    surfaces: Sequence[Callable[[np.ndarray, np.ndarray], np.ndarray]],
    cameras: Sequence[Camera],
    parts: np.ndarray | None = None,
    views: np.ndarray | None = None,
) -> PixelsAt:
    """A batch of points on ``surfaces`` (each (eta, omega) -> world points ``(n, 3)``) seen by ``cameras``:
    ``parts`` and ``views`` ``(n,)`` say on which surface each point lies and which camera sees it (None: the
    first). Each surface and each camera is evaluated once a call, over all its points."""

    def pixels_at(rows: np.ndarray, eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
        points = surface_points(surfaces, np.zeros(len(rows), int) if parts is None else parts[rows], eta, omega)
        if views is None:
            return cameras[0].project(points)[0]
        pixels, seen_by = np.empty((len(rows), 2)), views[rows]
        for view in np.unique(seen_by):
            mine = seen_by == view
            pixels[mine] = cameras[view].project(points[mine])[0]
        return pixels

    return pixels_at


def refine_surface_coordinates(
    pixels_at: PixelsAt,
    eta: np.ndarray,
    omega: np.ndarray,
    targets: np.ndarray,
    iterations: int = 5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move surface coordinates so that each point (``pixels_at``, `surface_pixels`) projects onto its ``targets``
    pixel.

    Gauss-Newton on each pair's (eta, omega), derivatives by central differences, steps damped and capped at
    0.2 rad, eta kept off the poles (where omega is degenerate). Returns eta, omega and the final pixel distances.
    """
    eta, omega = eta.astype(np.float64).copy(), omega.astype(np.float64).copy()
    rows = np.arange(len(eta))
    for _ in range(iterations):
        pixels, jacobian = _pixels_and_jacobian(pixels_at, rows, eta, omega)
        residual = pixels - targets
        normal = np.einsum("kji,kjl->kil", jacobian, jacobian) + _DAMPING
        delta = -np.linalg.solve(normal, np.einsum("kji,kj->ki", jacobian, residual)[..., None])[..., 0]
        delta = np.clip(delta, -0.2, 0.2)
        eta = np.clip(eta + delta[:, 0], -np.pi / 2 + POLE_MARGIN_RAD, np.pi / 2 - POLE_MARGIN_RAD)
        omega = (omega + delta[:, 1] + np.pi) % (2 * np.pi) - np.pi
    return eta, omega, np.linalg.norm(pixels_at(rows, eta, omega) - targets, axis=1)


def pixel_jacobian(pixels_at: PixelsAt, eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``(k, 2, 2)``: how the pixels of the points (``pixels_at``) move with (eta, omega), by central differences;
    rows (u, v), columns (d/d eta, d/d omega)."""
    return _pixels_and_jacobian(pixels_at, np.arange(len(eta)), eta, omega)[1]


def _pixels_and_jacobian(
    pixels_at: PixelsAt, rows: np.ndarray, eta: np.ndarray, omega: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The points' pixels ``(k, 2)`` and `pixel_jacobian`: the points and their four displaced copies in one
    evaluation."""
    step = DIFFERENCE_STEP_RAD
    eta_all = np.concatenate([eta, eta + step, eta - step, eta, eta])
    omega_all = np.concatenate([omega, omega, omega, omega + step, omega - step])
    at, eta_plus, eta_minus, omega_plus, omega_minus = pixels_at(np.tile(rows, 5), eta_all, omega_all).reshape(5, -1, 2)
    return at, np.stack([(eta_plus - eta_minus) / (2 * step), (omega_plus - omega_minus) / (2 * step)], axis=2)


def sample_keys(parts: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """One integer per (part, sample), for set operations."""
    return parts.astype(np.int64) * (1 << 32) + samples.astype(np.int64)
