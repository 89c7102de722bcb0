"""A DSQ part's fit problem (paper 1, eq 1-8): its pairs as pixels over its free parameters (`PartProblem`, on
`tracker.abis.fitting`'s optimisers), its gauge, its parameters' ranges and its rotations' increments.

Gauge: eq 1-2 depend on a, a1, a2, a3 only through a*a1, a*a2, a*a3 (the bending and tapering terms divide by
a*a3 too), so one of the four is redundant. After every step the fit rescales them to ``max(a1, a2, a3) = 1``,
which leaves the surface unchanged and the paper's reading intact (a is the scale, a1..a3 aspects in (0, 1]).

Rotations are stepped as increments ``R(r) Exp(w)`` in the part's frame and converted back to eq 4's Euler angles
after every step (`tracker.abis.part_model`): the Euler angles themselves are singular at r2 = +-pi/2.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tracker.abis.fitting import PixelProblem, Prior
from tracker.abis.part_model import free_parameter_indices, part_world_points, posed_coordinates
from tracker.geometry.cameras import Camera
from tracker.geometry.rotations import (
    euler_to_matrix,
    matrix_to_euler,
    matrix_to_rotation_vector,
    rotation_vector_to_matrix,
)
from tracker.models.dsq import PARAM_INDEX, PARAM_NAMES, PARAM_RANGES

_ASPECTS = [PARAM_INDEX[name] for name in ("a1", "a2", "a3")]
_ROTATION = np.array([PARAM_INDEX[name] for name in ("r1", "r2", "r3")])
OPEN_BOUND_INSET = 1e-6  # a parameter with an open bound (a > 0, a1 in (0, 1]) stays this far inside it


@dataclass(frozen=True, eq=False)
class ViewPairs:
    """One view's pairs for the part: the model points' surface coordinates and the observed feature pixels."""

    camera: Camera
    eta: np.ndarray  # (m,)
    omega: np.ndarray  # (m,)
    observed: np.ndarray  # (m, 2)


class PartProblem(PixelProblem):
    """A DSQ part's pairs (and prior) as functions of its free parameters (`tracker.abis.part_model`)."""

    def __init__(
        self,
        views: Sequence[ViewPairs],
        parent_world: np.ndarray | None = None,
        joint_in_parent: np.ndarray | None = None,
        prior: Prior | None = None,
    ) -> None:
        self.views = [view for view in views if len(view.eta)]
        super().__init__(
            [view.camera for view in self.views],
            [view.observed for view in self.views],
            free_parameter_indices(parent_world is None),
            prior,
        )
        eta = np.concatenate([view.eta for view in self.views]) if self.views else np.empty(0)
        omega = np.concatenate([view.omega for view in self.views]) if self.views else np.empty(0)
        self._coordinates = posed_coordinates(eta, omega, parent_world is None)  # every evaluation poses them
        self._is_rotation = np.isin(self.free, _ROTATION)
        self._reference_rotation = None if prior is None else euler_to_matrix(prior.reference[_ROTATION])
        self.parent_world, self.joint_in_parent = parent_world, joint_in_parent

    def points(self, q: np.ndarray) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        return part_world_points(q, self._coordinates, self.parent_world, self.joint_in_parent, local_rotation=True)

    def start(self, q: np.ndarray) -> np.ndarray:
        """``q`` (a copy) in the gauge ``max(a1, a2, a3) = 1``."""
        return _normalise_gauge(np.array(q, dtype=np.float64))

    def moved(self, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """``q`` moved by ``delta`` over the free parameters (rotation entries: a local increment w)."""
        return _apply(q, self.free, self._is_rotation, delta)

    def pressed(self, q: np.ndarray, gradient: np.ndarray) -> np.ndarray:
        return _pressed_against_bounds(q, self.free, self._is_rotation, gradient)

    def prior_difference(self, q: np.ndarray) -> np.ndarray:
        """Rotations: the rotation vector of R(ref)^T R(q)."""
        return _parameter_difference(q, self.prior.reference, self._reference_rotation, self.free, self._is_rotation)


def _parameter_difference(
    q: np.ndarray, reference: np.ndarray, reference_rotation: np.ndarray, free: np.ndarray, is_rotation: np.ndarray
) -> np.ndarray:
    """q - reference over the free parameters (``is_rotation``: which are r); for the rotation, the rotation vector
    of R(ref)^T R(q) (``reference_rotation``: R(ref))."""
    difference = q[free] - reference[free]
    relative = reference_rotation.T @ euler_to_matrix(q[_ROTATION])
    difference[is_rotation] = matrix_to_rotation_vector(relative)
    return difference


def _pressed_against_bounds(
    q: np.ndarray, free: np.ndarray, is_rotation: np.ndarray, gradient: np.ndarray
) -> np.ndarray:
    """Free parameters (``is_rotation``: which are r, never pressed) at a bound of their range whose descent direction
    (-gradient) points out of it."""
    at_low = (q[free] <= _LOW[free]) & (gradient > 0)
    at_high = (q[free] >= _HIGH[free]) & (gradient < 0)
    return ~is_rotation & (at_low | at_high)


def _bounds(index: int) -> tuple[float, float]:
    allowed = PARAM_RANGES[PARAM_NAMES[index]]
    inset = OPEN_BOUND_INSET
    return allowed.low + (inset if allowed.low_open else 0.0), allowed.high - (inset if allowed.high_open else 0.0)


_LOW, _HIGH = np.array([_bounds(index) for index in range(len(PARAM_NAMES))]).T  # every parameter's, q's order


def _apply(q: np.ndarray, free: np.ndarray, is_rotation: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """q moved by ``delta`` over the free parameters (``is_rotation``: which are r); the rotation entries of delta
    are a local increment w."""
    candidate = q.copy()
    candidate[free[~is_rotation]] += delta[~is_rotation]
    turned = euler_to_matrix(q[_ROTATION]) @ rotation_vector_to_matrix(delta[is_rotation])
    candidate[_ROTATION] = matrix_to_euler(turned, near=q[_ROTATION])
    stepped = free[~is_rotation]  # stay inside eq 1-2's ranges
    candidate[stepped] = np.clip(candidate[stepped], _LOW[stepped], _HIGH[stepped])
    return _normalise_gauge(candidate)


def _normalise_gauge(q: np.ndarray) -> np.ndarray:
    """Rescale (a, a1, a2, a3) to max(a1, a2, a3) = 1 without changing the surface."""
    largest = q[_ASPECTS].max()
    q[PARAM_INDEX["a"]] *= largest
    q[_ASPECTS] /= largest
    return q
