"""Paper 2's motion models over pose samples (section 4, eq 3-5) and the prior they give (eq 14).

DM1 (`RandomWalk`, ``motion=dm1``): ``p(x_t | x_{t-1}) = N(x_{t-1}, Sigma)``, ``Sigma = diag(sigma_j^2)``: a random
walk with ``sigma`` (radians) on every angle of the pose vector and ``sigma_root_m`` on every length (the root's
position; a DSQ part's bend). What a pose vector holds is its model's `PoseSpace` (the body's: `BODY_SPACE`).
DM2 (`OccludedWiderWalk`, ``motion=dm2``): the same with ``sigma_j * m`` for the joints of the parts flagged occluded
(eq 3: area below T_A) in the previous estimate.
Learned (`LearnedTransitions`, ``motion=learned``; paper 2's reference [19], Thayananthan, Stenger, Torr and
Cipolla, BMVC 2003): the transitions are learned from the training motion instead of assumed. The clips the samples
come from say, for each sample, which samples followed it one frame later (`tracker.tbf.pose_sets
.learned_transitions`, counted over every clip and variation); the prior from sample i is the mixture
``(1 - w) N(x_i, Sigma) + w sum_b c_ib / c_i N(x_b, Sigma_l)``: DM2's walk, and a narrower Gaussian
(``learned_sigma``, widened by m for occluded parts as DM2's) about each learned successor b weighted by how often
the clips made that move. Each kernel is normalised over the sample set, so the mixture's weights are its shares
of the prior mass. A sample no clip frame stands for (from a grid) keeps the walk alone.

The prior of eq 14, ``p(x^n | z_1:t-1) = sum_i N(x^n; x^i, Sigma) p(x^i | z_1:t-1)``, is a dense N x N sum at N
samples. `PosePrior.prior` keeps the terms that matter: from the previous posterior's support (its
``max_support`` largest samples among those with at least ``support_fraction`` of its peak) to every sample
within ``reach`` standard deviations, found by a KD-tree over pose space divided by the frame's sigmas (one tree
per distinct sigma vector, i.e. per DM2 occlusion pattern, built on first use) and kept per sample
(`KernelNeighbours`): the support moves little from frame to frame, and in a pose space of ~100 components a sample
has few neighbours (a few dozen terms a frame at ~52,000 samples). The tree searches the scaled samples' first
`SEARCH_AXES` principal axes for candidates, whose distances are then taken in full. A tree holds those projections
(2.4 MB at 37,000 samples; two trees a pattern with the learned motion's kernels) and a clip meets a new occlusion
pattern every ~30 frames (indian_14: 12 in 374): only the `KERNEL_TREES_KEPT` last used keep their trees; the
others keep the neighbours they found, and build their tree again only for a sample not asked before.
Terms beyond ``reach`` sigmas weigh less than ``exp(-reach^2 / 2)`` each (reach 4: 3e-4); the posterior mass left
out of the support is reported per frame (`PosePrior.last_mass_used`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from scipy.spatial import cKDTree

from tracker.models.body_skeleton import JOINT_INDEX, PART_BONES, POSE_SIZE
from tracker.ranges import Fraction, NonNegative, Positive, Range
from tracker.registry import MOTION_MODELS
from tracker.settings import validate


@dataclass(frozen=True)
class PoseSpace:
    """What a model's pose vector holds, as the motion models need it: its size, which components are lengths
    (metres; the others are angles, radians) and which components move each part (DM2 widens those of an
    occluded part)."""

    size: int
    lengths: tuple[int, ...]
    part_components: tuple[tuple[int, ...], ...] = ()


# The body's pose vector (`tracker.models.body_skeleton`): the root's position, then each joint's rotation vector.
BODY_SPACE = PoseSpace(
    POSE_SIZE,
    (0, 1, 2),
    tuple(
        tuple(3 + 3 * JOINT_INDEX[bone] + axis for bone in bones for axis in range(3)) for bones in PART_BONES.values()
    ),
)


@MOTION_MODELS.register("dm1")
@dataclass(frozen=True)
class RandomWalk:
    """DM1: a Gaussian random walk over joint rotations (paper 2, eq 4)."""

    sigma: Positive = 0.1  # radians per frame, every joint rotation component
    sigma_root_m: Positive = 0.02  # metres per frame, the root position
    occlusion_area_px: NonNegative = 50.0  # T_A (eq 3): a part with fewer pixels (at 320x240) is occluded

    def __post_init__(self) -> None:
        validate(self)

    def base_sigmas(self, space: PoseSpace = BODY_SPACE) -> np.ndarray:
        """``(space.size,)`` the DM1 standard deviation of each pose component."""
        sigmas = np.full(space.size, self.sigma)
        sigmas[list(space.lengths)] = self.sigma_root_m
        return sigmas

    def sigmas(self, occluded_parts: np.ndarray, space: PoseSpace = BODY_SPACE) -> np.ndarray:
        """``(space.size,)`` eq 5's sigma' given the previous estimate's occlusion flags ``(parts,)`` (DM1: none
        widened)."""
        return self.base_sigmas(space)


@MOTION_MODELS.register("dm2")
@dataclass(frozen=True)
class OccludedWiderWalk(RandomWalk):
    """DM2: DM1 with sigma multiplied by m for the joints of parts occluded in the previous estimate (eq 3-5)."""

    m: Annotated[float, Range(1.0, math.inf)] = 5.0  # the paper's factor

    def sigmas(self, occluded_parts: np.ndarray, space: PoseSpace = BODY_SPACE) -> np.ndarray:
        sigmas = self.base_sigmas(space)
        for part, components in enumerate(space.part_components):
            if occluded_parts[part]:
                sigmas[list(components)] *= self.m
        return sigmas


@MOTION_MODELS.register("learned")
@dataclass(frozen=True)
class LearnedTransitions(OccludedWiderWalk):
    """Transitions learned from the training clips' consecutive frames, over DM2's walk (see the module docstring).
    The clips are taken at ``tracker.samples.clip_fps``: set it to the tracking rate."""

    learned_share: Fraction = 0.7  # w: the share of each sample's prior that follows its learned successors
    learned_sigma: Positive = 0.05  # radians: the spread about a learned successor (metres: sigma_root_m's share)

    def learned_sigmas(self, walk_sigmas: np.ndarray) -> np.ndarray:
        """``(size,)`` the learned kernel's standard deviations: DM2's (``walk_sigmas``, `sigmas`), scaled by
        learned_sigma / sigma."""
        return walk_sigmas * (self.learned_sigma / self.sigma)


KERNEL_TREES_KEPT = 12  # `PosePrior`'s KD-trees kept, the last used: 6 occlusion patterns' walk and learned kernels
SEARCH_AXES = 8  # the principal axes of the scaled samples a `KernelNeighbours` tree searches along


class KernelNeighbours:
    """For one sigma vector, each asked sample's samples within ``reach`` sigmas and their distances in sigmas,
    found on first ask (one KD-tree query for all of a call's new samples) and kept. `release` lets the tree go
    (the neighbours found stay); a sample asked after it builds it again, the same.

    The tree holds the scaled samples (divided by the sigmas) projected onto their `SEARCH_AXES` principal axes
    (of ``covariance``, the unscaled samples' covariance). A projection onto orthonormal axes lengthens no distance,
    so every sample within reach is among the tree's candidates (searched a hair beyond reach, for rounding); each
    candidate's distance is then taken over every component, as scipy's cKDTree takes it (`squared_distances`).
    The pairs and their distances are the same bytes as a tree over every component finds, sooner: in ~100
    components such a tree spends its time proving that a sample has no neighbour but itself. The tree splits each
    node at the midpoint of its points' spread (scipy's ``balanced_tree=False``; its default, the median, takes
    longer to build and to query). A tree ``made_up_front`` (the kernels of no occlusion, before the first frame)
    shrinks each node's box to its points; a tree built while tracking (an occlusion pattern met) keeps the boxes
    unshrunk, quicker to build."""

    def __init__(
        self, poses: np.ndarray, sigmas: np.ndarray, reach: float, covariance: np.ndarray, made_up_front: bool = False
    ) -> None:
        self.poses, self.sigmas, self.reach = poses, np.array(sigmas, dtype=np.float64), reach  # its own sigmas
        self.covariance, self.made_up_front = covariance, made_up_front
        self.projected: np.ndarray | None = None
        self.tree: cKDTree | None = None
        self._build()
        self._first = np.full(len(poses), -1)  # per sample: where its neighbours start in the kept arrays, -1: unasked
        self._count = np.zeros(len(poses), np.int64)
        self._neighbours, self._distances = np.zeros(0, np.int64), np.zeros(0)

    def pairs(self, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every (centre, sample within reach) pair: the centre's position in ``centres``, the sample and their
        distance in sigmas; centre by centre, each centre's samples in index order."""
        new = np.unique(centres[self._first[centres] < 0])
        if len(new):
            if self.tree is None:
                self._build()
            found = self.tree.sparse_distance_matrix(
                cKDTree(self.projected[new]), self.reach * (1 + 1e-9), output_type="ndarray"
            )
            sample, centre = found["i"], found["j"]
            squared = squared_distances(self.poses[sample] / self.sigmas, self.poses[new[centre]] / self.sigmas)
            within = squared <= self.reach**2
            sample, centre, distance = sample[within], centre[within], np.sqrt(squared[within])
            order = np.lexsort((sample, centre))  # by centre, then by sample
            counts = np.bincount(centre, minlength=len(new))  # >= 1: a centre is its own neighbour
            self._first[new] = len(self._neighbours) + np.cumsum(counts) - counts
            self._count[new] = counts
            self._neighbours = np.concatenate([self._neighbours, sample[order]])
            self._distances = np.concatenate([self._distances, distance[order]])
        counts = self._count[centres]
        rows = np.repeat(np.arange(len(centres)), counts)
        index = np.repeat(self._first[centres] - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        return rows, self._neighbours[index], self._distances[index]

    def release(self) -> None:
        """Let the tree and the projected samples go; the neighbours found stay."""
        self.projected, self.tree = None, None

    def _build(self) -> None:
        _, axes = np.linalg.eigh(self.covariance / np.outer(self.sigmas, self.sigmas))  # the scaled samples' axes
        self.projected = self.poses @ (axes[:, ::-1][:, :SEARCH_AXES] / self.sigmas[:, None])  # scaled, projected
        self.tree = cKDTree(self.projected, balanced_tree=False, compact_nodes=self.made_up_front)


def squared_distances(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """``|first - second|^2`` row by row (``(n, d)`` each), summed as scipy's cKDTree sums a distance's squares
    (so that its bytes are the tree's): four running sums over the components 4b, 4b + 1, 4b + 2 and 4b + 3,
    added ((s0 + s1) + s2) + s3, then the remaining components' squares one by one."""
    differences = first - second
    squares = differences * differences
    blocks = squares.shape[1] // 4
    sums = np.zeros((len(squares), 4))
    for block in range(blocks):
        sums += squares[:, 4 * block : 4 * block + 4]
    total = ((sums[:, 0] + sums[:, 1]) + sums[:, 2]) + sums[:, 3]
    for component in range(4 * blocks, squares.shape[1]):
        total += squares[:, component]
    return total


class PosePrior:
    """Eq 14 over a fixed sample set, sparse (see the module docstring); with `LearnedTransitions`, its mixture
    over the learned ``transitions`` (``(m, 3)`` rows ``from, to, count``). ``space``: what the poses hold."""

    def __init__(
        self,
        poses: np.ndarray,
        motion: RandomWalk,
        reach: float = 4.0,
        support_fraction: float = 1e-4,
        max_support: int = 256,
        transitions: np.ndarray | None = None,
        space: PoseSpace = BODY_SPACE,
    ):
        self.poses = np.asarray(poses, dtype=np.float64)
        self.motion, self.reach, self.space = motion, reach, space
        self.support_fraction, self.max_support = support_fraction, max_support
        self._neighbours: dict[bytes, KernelNeighbours] = {}
        # each sigma vector's trees search its principal axes (a set of one sample has none: any axes do)
        self._covariance = (
            np.atleast_2d(np.cov(self.poses, rowvar=False)) if len(self.poses) > 1 else np.eye(self.poses.shape[1])
        )
        self.last_mass_used = 1.0
        self._within_reach(motion.base_sigmas(space), made_up_front=True)  # the no-occlusion tree
        self.learned = isinstance(motion, LearnedTransitions)
        if self.learned:
            if transitions is None or not len(transitions):
                raise ValueError(
                    "motion=learned learns from the clips the samples come from: tracker.samples.clips names none"
                )
            order = np.argsort(transitions[:, 0], kind="stable")
            self._to, self._count = transitions[order, 1], transitions[order, 2].astype(np.float64)
            self._rows = np.searchsorted(transitions[order, 0], np.arange(len(self.poses) + 1))
            self._within_reach(motion.learned_sigmas(motion.base_sigmas(space)), made_up_front=True)

    def _within_reach(self, sigmas: np.ndarray, made_up_front: bool = False) -> KernelNeighbours:
        """The neighbours for ``sigmas``, kept or found anew (`KernelNeighbours`: ``made_up_front``); the trees but
        the `KERNEL_TREES_KEPT` last used let go."""
        key = sigmas.tobytes()
        neighbours = self._neighbours.pop(key, None)
        if neighbours is None:
            neighbours = KernelNeighbours(self.poses, sigmas, self.reach, self._covariance, made_up_front)
        self._neighbours[key] = neighbours  # the most recent last
        for older in list(self._neighbours.values())[:-KERNEL_TREES_KEPT]:
            older.release()
        return neighbours

    def prior(self, posterior: np.ndarray, occluded_parts: np.ndarray) -> tuple[np.ndarray, int]:
        """``(N,)`` unnormalised eq 14 at every sample (0 where beyond reach) and the number of kernel terms
        evaluated."""
        sigmas = self.motion.sigmas(occluded_parts, self.space)
        support = np.flatnonzero(posterior >= self.support_fraction * posterior.max())
        if len(support) > self.max_support:
            support = support[np.argsort(posterior[support])[-self.max_support :]]
        self.last_mass_used = float(posterior[support].sum() / posterior.sum())
        if self.learned:
            return self._learned_prior(support, posterior[support], sigmas)
        centre, sample, distance = self._within_reach(sigmas).pairs(support)
        weights = posterior[support][centre] * np.exp(-0.5 * distance**2)
        return np.bincount(sample, weights=weights, minlength=len(self.poses)), len(sample)

    def _learned_prior(self, support: np.ndarray, mass: np.ndarray, sigmas: np.ndarray) -> tuple[np.ndarray, int]:
        """`LearnedTransitions`' mixture from the ``support`` samples holding ``mass``; ``sigmas``: the frame's walk."""
        starts, counts = self._rows[support], self._rows[support + 1] - self._rows[support]
        share = np.where(counts > 0, self.motion.learned_share, 0.0)
        rows = np.repeat(np.arange(len(support)), counts)  # each learned move's support sample, and its index:
        moves = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        totals = np.bincount(rows, weights=self._count[moves], minlength=len(support))
        move_mass = (mass * share)[rows] * self._count[moves] / totals[rows]
        walk, walk_terms = self._kernels(support, mass * (1 - share), sigmas)
        learned, learned_terms = self._kernels(self._to[moves], move_mass, self.motion.learned_sigmas(sigmas))
        return walk + learned, walk_terms + learned_terms

    def _kernels(self, centres: np.ndarray, mass: np.ndarray, sigmas: np.ndarray) -> tuple[np.ndarray, int]:
        """``sum_c mass_c N(x; x_c, diag(sigmas^2))`` at every sample, each kernel normalised over the set (terms
        within ``reach``), and the number of terms."""
        if not len(centres):
            return np.zeros(len(self.poses)), 0
        centre, sample, distance = self._within_reach(sigmas).pairs(centres)
        kernel = np.exp(-0.5 * distance**2)
        totals = np.bincount(centre, weights=kernel, minlength=len(centres))  # >= 1: a centre is a sample
        return np.bincount(sample, weights=mass[centre] * kernel / totals[centre], minlength=len(self.poses)), len(
            sample
        )

    def dense_prior(self, posterior: np.ndarray, occluded_parts: np.ndarray) -> np.ndarray:
        """The same sum over every pair (the naive N x N reference; small sets only)."""
        z = (self.poses[:, None] - self.poses[None]) / self.motion.sigmas(occluded_parts, self.space)
        return np.exp(-0.5 * np.einsum("nik,nik->ni", z, z)) @ posterior
