"""Fitting one part to its correspondences: paper 1, eq 7-9, by steepest descent (`sd`) or Levenberg-Marquardt (`lm`),
on any model's pixel problem (`PixelProblem`: the DSQ part's, `tracker.abis.part_problem`; a body part's,
`tracker.abis.body_fitting`).

The cost of part i is eq 8, ``E_i = sum_v sum_j (U_mj - U_j)^2 + (V_mj - V_j)^2`` over its pairs (model sample j
seen in view v, paired with a tracked feature), optionally with eq 7's robust rho (Huber) through iteratively
reweighted least squares. Both optimisers work in coordinates scaled by the Jacobian's column norms, since a
part's parameters have unrelated units (metres, radians, exponents).

Prior: a frame's pairs cannot pin every parameter (the DSQ's b1 cos(theta) has a shear-like limit b1 -> inf,
theta -> pi/2; a part seen in one view has unobservable depth). A `Prior` adds residual rows
``(q_k - q_ref_k) / sigma_k`` to the cost (a MAP fit around the previous frame's estimate): a parameter the pairs
say nothing about stays, and one pixel of image error weighs as much as one sigma of change. ``sigma = inf``
leaves a parameter free; without a prior the cost is eq 8 itself.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from tracker.geometry.cameras import Camera, ViewsPoints
from tracker.ranges import Count, Positive
from tracker.settings import validate
from tracker.tol import ZERO_LENGTH

LM_INITIAL_DAMPING, LM_SMALLEST_DAMPING = 1e-3, 1e-9  # Marquardt's lambda, relative to the Hessian's diagonal
ARMIJO = 1e-4  # steepest descent: a step must lower the cost by this fraction of its first-order prediction


@dataclass(frozen=True)
class FitSettings:
    """Per-part fitting: the optimiser (``sd``: the paper's steepest descent, eq 9; ``lm``: Levenberg-Marquardt),
    its iterations and stopping rule, and eq 7's robust rho."""

    optimizer: Literal["sd", "lm"] = "lm"
    max_iterations: Count = 20  # lm; sd gets `sd_iterations_factor` times as many (each is cheaper)
    sd_iterations_factor: Count = 10
    relative_tolerance: Positive = 1e-6  # stop when the cost falls by less than this fraction
    huber_px: Positive | None = None  # eq 7's rho: Huber with this threshold (pixels), or plain squares (None)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, eq=False)
class Prior:
    """Residual rows ``(q - reference) / sigmas`` over the free parameters (rotations: the increment's angle)."""

    reference: np.ndarray  # (17,)
    sigmas: np.ndarray  # (17,), inf for none


@dataclass(frozen=True, eq=False)
class FitResult:
    params: np.ndarray  # (17,)
    cost_start: float  # the cost at the start (eq 8, robust and with the prior where set)
    cost: float  # and at the end
    iterations: int
    residuals: list[np.ndarray]  # per view, (m, 2) model minus observed pixels at the end


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The part's residuals at q: per view (pixels), and stacked with the prior rows for least squares; their
    Jacobian made when first asked (a trial step the optimiser rejects, or its last, never asks)."""

    view_residuals: list[np.ndarray]
    vector: np.ndarray  # (2M + n_prior,)
    weights: np.ndarray  # (2M + n_prior,) IRLS weights (Huber on pixel pairs, 1 for the prior)
    cost: float
    jacobian_of: Callable[[], np.ndarray] = dataclasses.field(repr=False)

    @functools.cached_property
    def jacobian(self) -> np.ndarray:
        """``(2M + n_prior, n_free)``."""
        return self.jacobian_of()


class PixelProblem:
    """A part's pairs as pixels: per view the residuals (model minus observed) and their Jacobian over the free
    parameters, stacked with the prior's rows, robust as eq 7 says. A model's problem says how its pairs' world
    points follow the parameters (`points`) and, where they are not plain numbers, how the parameters move and
    differ (`start`, `moved`, `pressed`, `prior_difference`)."""

    def __init__(
        self, cameras: Sequence[Camera], observed: Sequence[np.ndarray], free: np.ndarray, prior: Prior | None
    ) -> None:
        self._views = ViewsPoints.of(cameras, [len(pixels) for pixels in observed])
        self._observed_rows = np.concatenate(observed) if len(observed) else np.empty((0, 2))  # views one after another
        self.free = free
        self.prior = prior
        if prior is not None:
            inverse = 1.0 / prior.sigmas[self.free]
            self._prior_rows = np.flatnonzero(inverse > 0)
            self._prior_scale = inverse[self._prior_rows]
            self._prior_jacobian = np.zeros((len(self._prior_rows), len(self.free)))
            self._prior_jacobian[np.arange(len(self._prior_rows)), self._prior_rows] = self._prior_scale

    @property
    def empty(self) -> bool:
        return not self._views.cameras

    def points(self, q: np.ndarray) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        """Every view's pairs' world points ``(M, 3)``, views one after another, and what makes their Jacobian
        ``(M, 3, n_free)`` when asked."""
        raise NotImplementedError

    def start(self, q: np.ndarray) -> np.ndarray:
        """The parameters the fit starts from (a copy of ``q``)."""
        return np.array(q, dtype=np.float64)

    def moved(self, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """``q`` moved by ``delta`` over the free parameters."""
        candidate = q.copy()
        candidate[self.free] += delta
        return candidate

    def pressed(self, q: np.ndarray, gradient: np.ndarray) -> np.ndarray:
        """Free parameters at a bound of their range that the descent direction (-gradient) points out of."""
        return np.zeros(len(self.free), bool)

    def prior_difference(self, q: np.ndarray) -> np.ndarray:
        """q - the prior's reference, over the free parameters."""
        return q[self.free] - self.prior.reference[self.free]

    def pixel_terms(
        self, q: np.ndarray, huber_px: float | None
    ) -> tuple[np.ndarray, float, np.ndarray, Callable[[], np.ndarray]]:
        """The pairs' residuals at ``q`` (model minus observed pixels ``(M, 2)``, views one after another), their
        cost (eq 8, or eq 7's with ``huber_px``) and IRLS weights ``(M,)``, and what makes the residuals' Jacobian
        rows ``(2M, n_free)`` (u then v of each pair) when asked."""
        # All views' points in one batch: the per-call overhead dominates at a few dozen pairs per view.
        points, points_jacobian = self.points(q)
        in_cameras = self._views.to_camera(points)
        residual = self._views.pixels(in_cameras)[0] - self._observed_rows
        cost, weights = robust_cost(np.linalg.norm(residual, axis=1), huber_px)

        def rows() -> np.ndarray:
            pixels = np.einsum("nij,njk->nik", self._views.projection_jacobian(in_cameras), points_jacobian())
            return pixels.reshape(-1, len(self.free))

        return residual, cost, weights, rows

    def evaluate(self, q: np.ndarray, settings: FitSettings) -> Evaluation:
        residual, pixel_cost, pixel_weights, pixel_rows = self.pixel_terms(q, settings.huber_px)
        residuals = [residual[rows] for rows in self._views.rows]
        vector = [residual.ravel()]
        weights = [np.repeat(pixel_weights, 2)]
        prior_cost = 0.0
        with_prior = self.prior is not None and len(self._prior_rows) > 0
        if with_prior:
            difference = self.prior_difference(q)[self._prior_rows]
            prior_residual = difference * self._prior_scale
            prior_cost = float(prior_residual @ prior_residual)
            vector.append(prior_residual)
            weights.append(np.ones(len(prior_residual)))

        def jacobian() -> np.ndarray:
            rows = pixel_rows()
            return np.concatenate([rows, self._prior_jacobian]) if with_prior else rows

        return Evaluation(
            view_residuals=residuals,
            vector=np.concatenate(vector),
            weights=np.concatenate(weights),
            cost=pixel_cost + prior_cost,
            jacobian_of=jacobian,
        )


def fit_part(q0: np.ndarray, problem: PixelProblem, settings: FitSettings = FitSettings()) -> FitResult:
    """Minimise the part's cost from ``q0`` over its free parameters; parameters stay in their ranges.

    ``problem``: a DSQ part's `PartProblem`, a body part's (`tracker.abis.body_fitting`), any `PixelProblem`."""
    q = problem.start(q0)
    if problem.empty:
        return FitResult(q, 0.0, 0.0, 0, [])
    current = problem.evaluate(q, settings)
    cost_start = current.cost
    step = _lm_step if settings.optimizer == "lm" else _sd_step
    budget = settings.max_iterations * (1 if settings.optimizer == "lm" else settings.sd_iterations_factor)
    state = {"damping": LM_INITIAL_DAMPING}
    accepted = 0
    while accepted < budget:
        candidate, evaluation = step(q, problem, current, settings, state)
        if candidate is None:  # no step lowers the cost: converged (or stuck)
            break
        accepted += 1
        improvement = current.cost - evaluation.cost
        q, current = candidate, evaluation  # its Jacobian is made only if another step asks for it
        if improvement <= settings.relative_tolerance * max(current.cost, ZERO_LENGTH):
            break
    return FitResult(q, cost_start, current.cost, accepted, current.view_residuals)


def _lm_step(q, problem, current, settings, state):
    """Marquardt: solve (J^T W J + lambda diag) delta = -J^T W r; raise lambda until the cost falls."""
    scale = _column_scale(current.jacobian)
    js = current.jacobian / scale
    hessian = js.T @ (current.weights[:, None] * js)
    gradient = js.T @ (current.weights * current.vector)
    for _ in range(12):
        damped = hessian + state["damping"] * np.diag(np.diag(hessian) + ZERO_LENGTH)
        try:
            delta = -np.linalg.solve(damped, gradient) / scale
        except np.linalg.LinAlgError:
            state["damping"] *= 10
            continue
        candidate = problem.moved(q, delta)
        evaluation = problem.evaluate(candidate, settings)
        if evaluation.cost < current.cost:
            state["damping"] = max(state["damping"] / 3, LM_SMALLEST_DAMPING)
            return candidate, evaluation
        state["damping"] *= 4
    return None, current


def _sd_step(q, problem, current, settings, state):
    """Eq 9, alpha <- alpha - beta dE/dalpha in scaled coordinates.

    beta starts at the Cauchy step (the minimum along the gradient of the Gauss-Newton model of E) and is halved
    until Armijo's sufficient decrease holds, which makes the descent converge. Parameters held at a bound of
    their range by the gradient drop out of the step (projected gradient).
    """
    scale = _column_scale(current.jacobian)
    js = current.jacobian / scale
    gradient = js.T @ (current.weights * current.vector)  # half the gradient of E in scaled coordinates
    gradient[problem.pressed(q, gradient)] = 0.0
    slope = gradient @ gradient
    curvature = np.sum(current.weights * (js @ gradient) ** 2)
    if slope <= 0 or curvature <= 0:
        return None, current
    beta = slope / curvature
    for _ in range(30):
        candidate = problem.moved(q, -beta * gradient / scale)
        evaluation = problem.evaluate(candidate, settings)
        if evaluation.cost <= current.cost - ARMIJO * beta * 2 * slope:  # sufficient decrease
            return candidate, evaluation
        beta /= 2
    return None, current


def robust_cost(distances: np.ndarray, huber_px: float | None) -> tuple[float, np.ndarray]:
    """Eq 8's squares, or eq 7 with Huber's rho; and the IRLS weight of each pair."""
    if huber_px is None:
        return float(np.sum(distances**2)), np.ones_like(distances)
    k = huber_px
    cost = float(np.sum(np.where(distances <= k, distances**2, 2 * k * distances - k**2)))
    return cost, np.minimum(1.0, k / np.maximum(distances, ZERO_LENGTH))


def _column_scale(jacobian: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(jacobian, axis=0)
    return np.where(norms > ZERO_LENGTH, norms, 1.0)
