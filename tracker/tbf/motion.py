"""Paper 2's motion models over pose samples (section 4, eq 3-5) and the prior they give (eq 14).

DM1 (`RandomWalk`, ``motion=dm1``): ``p(x_t | x_{t-1}) = N(x_{t-1}, Sigma)``, ``Sigma = diag(sigma_j^2)``: a random
walk with ``sigma`` (radians) on every joint rotation component and ``sigma_root_m`` on the root position.
DM2 (`OccludedWiderWalk`, ``motion=dm2``): the same with ``sigma_j * m`` for the joints of the parts flagged occluded
(eq 3: area below T_A) in the previous estimate.

The prior of eq 14, ``p(x^n | z_1:t-1) = sum_i N(x^n; x^i, Sigma) p(x^i | z_1:t-1)``, is a dense N x N sum at N
samples. `PosePrior.prior` keeps the terms that matter: from the previous posterior's support (its
``max_support`` largest samples among those with at least ``support_fraction`` of its peak) to every sample
within ``reach`` standard deviations, found in one call of a KD-tree over pose space divided by the frame's
sigmas (one tree per distinct sigma vector, i.e. per DM2 occlusion pattern, built on first use). Terms beyond
``reach`` sigmas weigh less than ``exp(-reach^2 / 2)`` each (reach 4: 3e-4); the posterior mass left out of the
support is reported per frame (`PosePrior.last_mass_used`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from scipy.spatial import cKDTree

from tracker.models.body_skeleton import JOINT_INDEX, PART_BONES, POSE_SIZE
from tracker.ranges import NonNegative, Positive, Range
from tracker.registry import MOTION_MODELS
from tracker.settings import validate


@MOTION_MODELS.register("dm1")
@dataclass(frozen=True)
class RandomWalk:
    """DM1: a Gaussian random walk over joint rotations (paper 2, eq 4)."""

    sigma: Positive = 0.1  # radians per frame, every joint rotation component
    sigma_root_m: Positive = 0.02  # metres per frame, the root position
    occlusion_area_px: NonNegative = 50.0  # T_A (eq 3): a part with fewer pixels (at 320x240) is occluded

    def __post_init__(self) -> None:
        validate(self)

    def base_sigmas(self) -> np.ndarray:
        """``(POSE_SIZE,)`` the DM1 standard deviation of each pose component."""
        sigmas = np.full(POSE_SIZE, self.sigma)
        sigmas[:3] = self.sigma_root_m
        return sigmas

    def sigmas(self, occluded_parts: np.ndarray) -> np.ndarray:
        """``(POSE_SIZE,)`` eq 5's sigma' given the previous estimate's occlusion flags ``(parts,)`` (DM1: none
        widened)."""
        return self.base_sigmas()


@MOTION_MODELS.register("dm2")
@dataclass(frozen=True)
class OccludedWiderWalk(RandomWalk):
    """DM2: DM1 with sigma multiplied by m for the joints of parts occluded in the previous estimate (eq 3-5)."""

    m: Annotated[float, Range(1.0, math.inf)] = 5.0  # the paper's factor

    def sigmas(self, occluded_parts: np.ndarray) -> np.ndarray:
        sigmas = self.base_sigmas()
        for part, bones in enumerate(PART_BONES.values()):
            if occluded_parts[part]:
                for bone in bones:
                    start = 3 + 3 * JOINT_INDEX[bone]
                    sigmas[start : start + 3] *= self.m
        return sigmas


class PosePrior:
    """Eq 14 over a fixed sample set, sparse (see the module docstring)."""

    def __init__(self, poses: np.ndarray, motion: RandomWalk, reach: float = 4.0, support_fraction: float = 1e-4,
                 max_support: int = 256):  # fmt: skip
        self.poses = np.asarray(poses, dtype=np.float64)
        self.motion, self.reach = motion, reach
        self.support_fraction, self.max_support = support_fraction, max_support
        self._trees: dict[bytes, cKDTree] = {}
        self.last_mass_used = 1.0
        self._tree(motion.base_sigmas())  # the no-occlusion tree up front (~0.1 s at 57k samples), not in a frame

    def _tree(self, sigmas: np.ndarray) -> cKDTree:
        key = sigmas.tobytes()
        if key not in self._trees:
            self._trees[key] = cKDTree(self.poses / sigmas)
        return self._trees[key]

    def prior(self, posterior: np.ndarray, occluded_parts: np.ndarray) -> tuple[np.ndarray, int]:
        """``(N,)`` unnormalised eq 14 at every sample (0 where beyond reach) and the number of kernel terms
        evaluated."""
        sigmas = self.motion.sigmas(occluded_parts)
        support = np.flatnonzero(posterior >= self.support_fraction * posterior.max())
        if len(support) > self.max_support:
            support = support[np.argsort(posterior[support])[-self.max_support :]]
        self.last_mass_used = float(posterior[support].sum() / posterior.sum())
        pairs = self._tree(sigmas).sparse_distance_matrix(cKDTree(self.poses[support] / sigmas), self.reach,
                                                        output_type="ndarray")  # fmt: skip
        weights = posterior[support][pairs["j"]] * np.exp(-0.5 * pairs["v"] ** 2)
        return np.bincount(pairs["i"], weights=weights, minlength=len(self.poses)), len(pairs)

    def dense_prior(self, posterior: np.ndarray, occluded_parts: np.ndarray) -> np.ndarray:
        """The same sum over every pair (the naive N x N reference; small sets only)."""
        z = (self.poses[:, None] - self.poses[None]) / self.motion.sigmas(occluded_parts)
        return np.exp(-0.5 * np.einsum("nik,nik->ni", z, z)) @ posterior
