"""The best chain of likely samples through the frames (`TbfSettings.chain`): the forward pass of Viterbi's algorithm.

One silhouette often fits a few samples far apart nearly as well as the pose it shows: the pose's depth flip
(`tracker.tbf.flips`), a limb forward or back. Paper 2's filter follows whichever of them its motion model reaches;
once its posterior has left the pose, pruning keeps it away. A chain keeps them all. Every frame the tree is searched
by the likelihood alone (`FilterSettings.jump_share` 1), the ``candidates`` most likely samples are kept
(`TreeFilter.most_likely`), and each is scored by the best chain of the frames' candidates that ends in it:

    score_t(c) = log p(z_t | c) + max over the last frame's candidates c' of [score_t-1(c') - d(c', c)^2 / (2 s^2)]

d is the root-mean-square distance between the two samples' joints, each relative to its root (a turn or a flip is
far); s is ``step_m``. The estimate is the best-scoring candidate: the end of the most probable chain so far, known
at once (a smoother would also revise the frames before it; a run does not); or (``estimate=mean``) the mean of the
candidates near it, each weighted by its chain's probability.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.ranges import Positive, Range
from tracker.settings import validate


@dataclass(frozen=True)
class ChainSettings:
    """How many candidates a frame keeps, and the scale of a frame's move between them."""

    candidates: Annotated[int, Range(0, 1000)] = 0  # 0: no chain (the filter's own estimate, the paper's)
    # s: the joints' root-mean-square move between two frames at which a link costs half a nat (metres)
    step_m: Positive = 0.08
    # With ``estimate=mean``: the candidates whose joints lie within this of the best's (root-mean-square, root-aligned,
    # metres) are averaged, each weighted by its chain's probability (`BestChain.around_best`).
    mean_radius_m: Positive = 0.3

    def __post_init__(self) -> None:
        validate(self)


class BestChain:
    """The chains' scores over the samples whose ``joints`` are ``(n, J, 3)`` (joint 0 the root), one frame at a
    time (`step`)."""

    def __init__(self, joints: np.ndarray, step_m: float) -> None:
        aligned = np.asarray(joints, dtype=np.float64) - np.asarray(joints, dtype=np.float64)[:, :1]
        self.joints = aligned.reshape(len(aligned), -1)  # (n, 3J)
        self.joint_count = aligned.shape[1]
        self.step_m = step_m
        self.candidates: np.ndarray | None = None  # the last frame's candidates
        self.scores: np.ndarray | None = None  # their chains' scores, the best 0

    def step(self, candidates: np.ndarray, log_likelihood: np.ndarray) -> int:
        """This frame's ``candidates`` (sample indices) with their ``log_likelihood``: the sample that ends the best
        chain."""
        scores = np.asarray(log_likelihood, dtype=np.float64).copy()
        if self.candidates is not None:
            scores += (
                self.scores[:, None] - self.squared_distances(self.candidates, candidates) / (2 * self.step_m**2)
            ).max(axis=0)
        self.candidates, self.scores = np.asarray(candidates), scores - scores.max()
        return int(self.candidates[np.argmax(self.scores)])

    def around_best(self, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The last frame's candidates within ``radius_m`` of the best (the root-mean-square distance of their
        joints), the best among them, and the probability of each one's chain relative to the best's (1)."""
        best = self.candidates[np.argmax(self.scores)]
        near = self.squared_distances(np.array([best]), self.candidates)[0] <= radius_m**2
        return self.candidates[near], np.exp(self.scores[near])

    def squared_distances(self, these: np.ndarray, those: np.ndarray) -> np.ndarray:
        """``(len(these), len(those))`` the mean over joints of the squared distance between their root-aligned
        joints."""
        a, b = self.joints[these], self.joints[those]
        squared = (a * a).sum(axis=1)[:, None] + (b * b).sum(axis=1)[None] - 2.0 * a @ b.T
        return np.maximum(squared, 0.0) / self.joint_count
