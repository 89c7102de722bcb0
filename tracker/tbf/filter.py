"""Silhouette tree-based filtering (paper 2, sections 5.3 and 6).

Per frame, given the observed silhouette P_o (one per view with several cameras: a node's likelihood is the
product of its views' likelihoods, its log-likelihood the sum of theirs, each view with its own sigma; a view that
lost the person, None, has no say):
    prior     eq 14 at every sample from the previous posterior (`PosePrior`, sparse), occlusion flags of the
              previous estimate widening the occluded parts' sigmas (DM2); made by a worker thread between the
              frames, as soon as that posterior is known;
    levels    from the top: the nodes under the surviving nodes of the level above are scored by their
              representative's silhouette distance at the level's resolution (the observation's weight maps,
              one per level and view, each made when the descent reaches it unless a worker thread, started
              from the finest level's as the step starts, has made it; each representative scored from its runs
              of inside pixels, `tracker.tbf.scoring.ObservationScorer`); a node's posterior
              is ``exp(-d^2 / 2 sigma_l^2)`` (eq 10-11, vol(S) constant) times its members' prior mass; nodes
              below ``prune_fraction`` of the level's best are pruned (with several views, the top level's
              nodes are scored view by view, each next view only where the pruning could still keep them:
              `TreeFilter._top_level`, the same survivors);
    leaves    each member sample of a surviving leaf gets ``p(z | leaf) * prior(sample)`` (eq 12-13); the best
              sample is the estimate, and the normalised values are the next frame's posterior.
Frame 0's prior is a Gaussian around the initial pose (`TreeFilter.start`).

Eq 10's sigma_l is ``likelihood_sigma`` times the cost's typical step between neighbouring samples at level l
(`tracker.tbf.calibration`), so one ``likelihood_sigma`` serves every cost and motion model.
"""

from __future__ import annotations

import functools
import operator
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tracker.observe.silhouettes import resize_silhouette
from tracker.ranges import Positive, Range
from tracker.settings import validate
from tracker.tbf.calibration import neighbour_step
from tracker.tbf.costs import Cost
from tracker.tbf.motion import BODY_SPACE, PosePrior, PoseSpace, RandomWalk
from tracker.tbf.samples import PoseSampleSet, SampleViews
from tracker.tbf.scoring import ObservationScorer, RunBoundaries, ShiftedRunBoundaries
from tracker.tbf.tree import PoseTree
from tracker.threads import TwoEndedJobs
from tracker.timing import elapsed_ms
from tracker.tol import NEGLIGIBLE_PRIOR, TINY

BOUNDING_NODES = 16  # the top level's nodes scored in every view first, for a lower bound of its best (`_top_level`)


@dataclass(frozen=True)
class FilterSettings:
    """Eq 10's sigma, the pruning threshold and beam, frame 0's prior, and the prior's shares moved to the depth flips
    and spread over every sample."""

    likelihood_sigma: Positive = 1.0  # eq 10's sigma, in units of the cost's neighbour step at each level
    # Keep a node whose posterior is at least this fraction of its level's best (per view: with V views, this to
    # the power V, as the views' likelihoods multiply).
    prune_fraction: Annotated[float, Range(0.0, 1.0, high_open=True)] = 0.01
    initial_sigma: Positive = 0.3  # frame 0's prior: N(initial pose, this sigma on every joint component)
    # The share of each frame's prior (after frame 0's) spread evenly over every sample (0: eq 14 alone, the
    # paper's). In a pose space of many joints the motion model's steps reach only the samples next to the last
    # posterior; this share lets the likelihood find the pose anywhere in the tree, as a detector would, when the
    # views can tell. At 1 the tree is searched by the likelihood alone: no motion model, no flips (what a chain of
    # candidates needs, `tracker.tbf.chains`).
    jump_share: Annotated[float, Range(0.0, 1.0)] = 0.0
    # The share of each frame's prior moved from every sample to its depth flip (`tracker.tbf.flips`; one camera
    # only): the samples whose mirror image through the plane facing the camera casts the same silhouette. The
    # motion model never reaches the other side; this share lets a run that started on, or slipped to, the wrong
    # side come back when the silhouettes' perspective says so (0: the paper's).
    flip_share: Annotated[float, Range(0.0, 0.5)] = 0.0
    # At most this many nodes kept a level, those of the highest posterior (None: every node the pruning keeps): a
    # bound on a frame's work where many nodes are nearly as likely, as when the likelihood alone leads the search.
    beam: Annotated[int, Range(1, 1_000_000)] | None = None

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, eq=False)
class FilterResult:
    sample: int  # index of the estimated sample
    pose: np.ndarray  # its pose vector
    occluded: np.ndarray  # (parts,) eq 3's flags of the estimate
    nodes_evaluated: list[int]  # per level
    nodes_kept: list[int]  # per level, after pruning
    prior_terms: int  # kernel evaluations of eq 14
    entropy: float  # of the posterior over samples (nats)
    timings_ms: dict[str, float]


class TreeFilter:
    """Paper 2's filter over ``samples`` (one view's set, or several views') and their ``tree`` (``transitions``:
    for `LearnedTransitions`; ``space``: what the pose vectors hold, the body's or the arm's).

    ``spot_pixels`` (several views placing the person on the floor, `tracker.tbf.alignment.ViewsPlacement`): per
    level, ``(samples, views, 2)``: where each view sees each sample's spot, in the level's pixels. The observation
    is placed on one sample's spot (the reference's, given to `step`); each sample is scored moved by whole pixels,
    the reference's spot pixel minus its own, as if the observation had been placed on its own spot. Scored where
    they stand, the samples whose limbs put their spot where the reference's is would win (the cost would prefer
    poses farther from the truth than the dictionary's nearest). The top level moves a sample by the difference of
    the two pixels each rounded, which makes its sums one product with its run boundaries (`ShiftedRunBoundaries`);
    the levels below by the difference rounded."""

    def __init__(
        self,
        samples: PoseSampleSet | SampleViews,
        tree: PoseTree,
        cost: Cost,
        motion: RandomWalk,
        settings: FilterSettings = FilterSettings(),
        transitions: np.ndarray | None = None,
        space: PoseSpace = BODY_SPACE,
        spot_pixels: list[np.ndarray] | None = None,
        flips: np.ndarray | None = None,
    ) -> None:
        samples = SampleViews.of(samples)
        self.samples, self.tree, self.cost, self.motion, self.settings = samples, tree.prepare(), cost, motion, settings
        self.space, self.spot_pixels = space, spot_pixels
        if settings.flip_share > 0 and flips is None:
            raise ValueError("a flip share moves the prior to each sample's depth flip: the filter needs the flips")
        self.flips = flips
        self._prior = PosePrior(samples.poses, motion, transitions=transitions, space=space)
        self._stacks = [samples.silhouettes(level.resolution) for level in tree.levels]
        # The top level, scored whole at frame 0 and, with a jump share, at every frame: its representatives as run
        # boundaries per view (the coarsest resolution: the matrix is small), each moved back by its spot pixel if
        # any. The levels below score a few children of the survivors each frame, from the set's own runs.
        top = tree.levels[0].representatives
        self.top_boundaries = tuple(
            RunBoundaries(stack.masks(top))
            if spot_pixels is None
            else ShiftedRunBoundaries(stack.masks(top), np.rint(spot_pixels[0][top, view]))
            for view, stack in enumerate(self._stacks[0])
        )
        if spot_pixels is not None:  # the levels below score their runs moved: each silhouette's extent made here
            for stacks in self._stacks[1:]:  # (`SilhouetteRuns.extents`), not at frame 0
                for stack in stacks:
                    stack.runs.extents(stack.shape[1])
        self._occluded = samples.occluded(motion.occlusion_area_px)
        # Per level, each view's sigma (eq 10): its own neighbour step.
        self.level_sigmas = [
            tuple(settings.likelihood_sigma * neighbour_step(view, cost, level.resolution) for view in samples.sets)
            for level in tree.levels
        ]
        # Pruning keeps nodes within this of the level's best log-posterior per view that sees the person:
        # prune_fraction per view, as each view adds its own log-likelihood (one view: the paper's).
        self.prune_log = np.log(max(settings.prune_fraction, TINY))
        self._posterior: np.ndarray | None = None
        self._likely: tuple[np.ndarray, np.ndarray] | None = None  # the last step's leaves' members, log-likelihoods
        self._reference: int | None = None  # with spot pixels: the sample whose spot this frame's observation is on
        self._previous_flags: np.ndarray | None = None
        # The next frame's prior, made by a worker thread from the last posterior between the frames (`_next_prior`)
        self._coming_prior: TwoEndedJobs[tuple[np.ndarray, int]] | None = None
        self.last_evaluated: list[np.ndarray] = []  # per level, the nodes the last step scored
        self.observed: tuple[np.ndarray | None, ...] = ()  # the last step's observations as it took them (`_seeing`)

    def start(self, initial_pose: np.ndarray) -> None:
        """Frame 0's prior: a Gaussian around ``initial_pose`` (the paper: upright, facing the camera)."""
        self._settle_prior()
        sigmas = self.motion.base_sigmas(self.space) / self.motion.sigma * self.settings.initial_sigma
        z = (np.asarray(self.samples.poses) - initial_pose) / sigmas
        log_prior = -0.5 * np.einsum("nk,nk->n", z, z)
        posterior = np.exp(log_prior - log_prior.max())
        posterior[posterior < NEGLIGIBLE_PRIOR] = 0.0
        self._posterior = posterior / posterior.sum()
        self.initial_sample = int(np.argmax(posterior))  # the prior's most likely sample
        self._previous_flags = self._occluded[self.initial_sample]
        self._first = True

    def step(self, observed: np.ndarray | tuple[np.ndarray | None, ...], reference: int | None = None) -> FilterResult:
        """One frame: ``observed`` is the ``(h, w)`` bool silhouette at the finest level's resolution, or one per
        view in the views' order (with ``spot_pixels``: placed on sample ``reference``'s spot); None for a view
        that lost the person (at least one must see him; a view whose silhouette is too small to show at the top
        level is one, while another's shows)."""
        observed = (observed,) if isinstance(observed, np.ndarray) else tuple(observed)
        if all(view is None for view in observed):
            raise ValueError("no view sees the person")
        observed, top = self._seeing(observed)
        self.observed = observed
        if (self.spot_pixels is None) != (reference is None):
            raise ValueError("a filter with spot pixels scores from a reference sample's spot, and only such a filter")
        self._reference = reference
        timings: dict[str, float] = {}
        scorers = self._scorers(observed, top)  # the worker threads start on them (after the prior, if under way)
        start = time.perf_counter()
        first, self._first = self._first, False
        if first:  # frame 0's prior is the initial Gaussian itself
            prior, terms = self._posterior.copy(), 0
        elif self.searches_alone:
            prior, terms = np.full(len(self._posterior), 1.0 / len(self._posterior)), 0
        else:
            prior, terms = self._next_prior()
        if self.settings.flip_share > 0 and (first or not self.searches_alone):
            prior = self.flipped(prior)
        if not first and 0 < self.settings.jump_share < 1:
            prior = (1 - self.settings.jump_share) * prior / prior.sum() + self.settings.jump_share / len(prior)
        timings["prior"] = elapsed_ms(start)
        leaves, leaf_likelihood, evaluated, kept = self._descend(prior, scorers, timings)
        start = time.perf_counter()
        members = self.tree.leaf_members(leaves)
        likelihood_of_leaf = np.empty(len(self.tree.levels[-1]))
        likelihood_of_leaf[leaves] = leaf_likelihood
        leaf_of = self.tree.levels[-1].node_of_sample[members]
        log_posterior = likelihood_of_leaf[leaf_of] + np.log(np.maximum(prior[members], TINY))
        weights = np.exp(log_posterior - log_posterior.max())
        weights[prior[members] <= 0] = 0.0
        posterior = np.zeros(len(prior))
        posterior[members] = weights / weights.sum()
        best = int(members[np.argmax(weights)])
        self._posterior = posterior
        self._likely = members, likelihood_of_leaf[leaf_of]
        self._previous_flags = self._occluded[best]
        if not self.searches_alone:
            self._coming_prior = TwoEndedJobs([functools.partial(self._prior.prior, posterior, self._previous_flags)])
        nonzero = posterior[posterior > 0]
        timings["leaves"] = elapsed_ms(start)
        return FilterResult(
            sample=best,
            pose=np.asarray(self.samples.poses[best]).copy(),
            occluded=self._occluded[best].copy(),
            nodes_evaluated=evaluated,
            nodes_kept=kept,
            prior_terms=terms,
            entropy=float(-(nonzero * np.log(nonzero)).sum()),
            timings_ms=timings,
        )

    @property
    def searches_alone(self) -> bool:
        """Whether the frames after the first are searched by the likelihood alone (``jump_share`` 1)."""
        return self.settings.jump_share == 1

    def most_likely(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """The ``count`` samples of the last step's surviving leaves that the observation makes most likely (of equal
        ones the lower index first; a leaf's members share its likelihood), and their log-likelihoods."""
        members, log_likelihood = self._likely
        order = np.lexsort((members, -log_likelihood))[:count]
        return members[order], log_likelihood[order]

    def occluded_of(self, sample: int) -> np.ndarray:
        """``(parts,)`` eq 3's occlusion flags of ``sample``."""
        return self._occluded[sample].copy()

    def flipped(self, prior: np.ndarray) -> np.ndarray:
        """``prior`` normalised, ``flip_share`` of each sample's mass moved to its depth flip."""
        share, total = self.settings.flip_share, prior.sum()
        carried = np.flatnonzero(prior)  # a prior is zero beyond its kernels' reach
        flipped = (1 - share) / total * prior
        np.add.at(flipped, self.flips[carried], share / total * prior[carried])
        return flipped

    def _seeing(
        self, observed: tuple[np.ndarray | None, ...]
    ) -> tuple[tuple[np.ndarray | None, ...], tuple[np.ndarray | None, ...]]:
        """The views' observations as the filter takes them, and each one's at the top level (the views' as given
        with one view): with several views, one whose silhouette vanishes at the top level (a few pixels at the
        image's edge) has lost the person too (None), unless none would see him."""
        if len(observed) == 1:
            return observed, observed
        top = tuple(None if view is None else self.observation_at(0, view) for view in observed)
        seeing = tuple(
            None if view is None or not small.any() else view for view, small in zip(observed, top, strict=True)
        )
        if all(view is None for view in seeing):
            return observed, top
        return seeing, tuple(None if view is None else small for view, small in zip(seeing, top, strict=True))

    @property
    def posterior(self) -> np.ndarray:
        """``(N,)`` the last step's posterior over the samples (the next frame's prior is made from it)."""
        return self._posterior

    def feed(self, sample: int, share: float) -> None:
        """Move ``share`` of the posterior onto ``sample`` (an estimate made outside the filter, e.g. refined, that
        the next frame's prior should start from)."""
        self._settle_prior()  # made from the posterior before this
        self._posterior = (1 - share) * self._posterior
        self._posterior[sample] += share
        self._previous_flags = self._occluded[sample]

    def _next_prior(self) -> tuple[np.ndarray, int]:
        """Eq 14 from the last posterior (`PosePrior.prior`): made by a worker thread since the last step ended, or
        here. Made between the frames, a frame that meets a new occlusion pattern waits less for its KD-tree."""
        coming, self._coming_prior = self._coming_prior, None
        if coming is None:
            return self._prior.prior(self._posterior, self._previous_flags)
        return coming.result(0)

    def _settle_prior(self) -> None:
        """The prior under way dropped (the posterior it came from has changed), once no worker uses the prior's
        caches."""
        if self._coming_prior is not None:
            self._coming_prior.settle()
            self._coming_prior = None

    def _descend(
        self, prior: np.ndarray, scorers: list[list[Callable[[], ObservationScorer]]], timings: dict[str, float]
    ) -> tuple[np.ndarray, np.ndarray, list[int], list[int]]:
        """Level by level from the top, the nodes under the survivors scored (``scorers``: per level, each view's
        `ObservationScorer` to come) and pruned: the surviving leaves, their log-likelihoods, and per level the nodes
        evaluated and kept."""
        survivors, node_likelihood = np.array([0]), np.zeros(0)
        evaluated, kept = [], []
        self.last_evaluated = []
        for k, level in enumerate(self.tree.levels):
            start = time.perf_counter()
            nodes = level.children_of(survivors) if k > 0 else np.arange(len(level))
            mass = level.masses(prior, nodes if k > 0 else None)
            nodes, mass = nodes[mass > 0], mass[mass > 0]
            if len(nodes) == 0:
                raise RuntimeError("the prior gives no sample any weight")
            level_scorers = [None if scorer is None else scorer() for scorer in scorers[k]]  # a failure raises here
            self.last_evaluated.append(nodes)
            evaluated.append(len(nodes))
            seeing = sum(scorer is not None for scorer in level_scorers)
            if k == 0 and seeing > 1:
                nodes, mass, log_likelihood = self._top_level(nodes, mass, level_scorers)
            else:
                distances = self._level_distances(k, level_scorers, None if len(nodes) == len(level) else nodes)
                log_likelihood = self.log_likelihood(k, distances)
            log_posterior = log_likelihood + np.log(mass)
            keep = np.flatnonzero(log_posterior >= log_posterior.max() + seeing * self.prune_log)
            if self.settings.beam is not None and len(keep) > self.settings.beam:
                keep = np.sort(keep[np.argsort(-log_posterior[keep], kind="stable")[: self.settings.beam]])
            kept.append(len(keep))
            survivors, node_likelihood = nodes[keep], log_likelihood[keep]
            timings[f"level{k + 1}"] = elapsed_ms(start)
        return survivors, node_likelihood, evaluated, kept

    def _top_level(
        self, nodes: np.ndarray, mass: np.ndarray, scorers: list[ObservationScorer | None]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The top level's ``nodes`` (with their prior ``mass``) that its pruning could keep, that mass and their
        log-likelihoods (`log_likelihood`'s, to the bit), scored view by view: every node in the first view that sees
        the person, then in each next view only the nodes whose log-posterior so far reaches the pruning's threshold
        for a lower bound of the level's best (the best log-posterior, all views scored, of the `BOUNDING_NODES`
        highest after the first view). Each view adds a term of at most 0, and rounding keeps the order of sums, so
        a log-posterior so far bounds the node's from above: a node dropped could not have been kept, and the best
        node is never dropped. With several views most of the level is dropped after the first."""
        seeing = [view for view, scorer in enumerate(scorers) if scorer is not None]
        sigmas, log_mass = self.level_sigmas[0], np.log(mass)
        scoring = {view: self.top_scoring(scorers[view], view) for view in seeing}

        def term(view: int, rows: np.ndarray | None) -> np.ndarray:  # as `log_likelihood` makes each view's
            return -0.5 * (scoring[view](rows) / sigmas[view]) ** 2

        first = term(seeing[0], None if len(nodes) == len(self.tree.levels[0]) else nodes)
        so_far = first + log_mass
        highest = np.argpartition(so_far, -min(BOUNDING_NODES, len(nodes)))[-BOUNDING_NODES:]
        bound = functools.reduce(operator.add, [first[highest]] + [term(v, nodes[highest]) for v in seeing[1:]])
        threshold = (bound + log_mass[highest]).max() + len(seeing) * self.prune_log
        alive = np.flatnonzero(so_far >= threshold)
        log_likelihood = first[alive]
        for view in seeing[1:]:
            log_likelihood = log_likelihood + term(view, nodes[alive])  # in the views' order
            reach = log_likelihood + log_mass[alive] >= threshold
            alive, log_likelihood = alive[reach], log_likelihood[reach]
        return nodes[alive], mass[alive], log_likelihood

    def _level_distances(
        self, level: int, scorers: list[ObservationScorer | None], nodes: np.ndarray | None
    ) -> list[np.ndarray | None]:
        """Each view's distances to ``nodes`` of ``level`` (None for a view that lost the person). Below the top
        level several views' are shared with the worker threads (their sums are compiled loops that free the GIL);
        at the top the workers are still making the levels below's scorers."""
        jobs = [
            (lambda: None) if scorer is None else functools.partial(self.scores_from, scorer, level, view, nodes)
            for view, scorer in enumerate(scorers)
        ]
        if len(jobs) == 1 or level == 0:
            return [job() for job in jobs]
        return TwoEndedJobs(jobs).results()

    @property
    def reference(self) -> int | None:
        """The sample on whose spot the last step's observation was placed (with spot pixels)."""
        return self._reference

    def observation_at(self, level: int, observed: np.ndarray) -> np.ndarray:
        """The observed silhouette at ``level``'s resolution."""
        resolution = tuple(self.tree.levels[level].resolution)
        return observed if observed.shape[::-1] == resolution else resize_silhouette(observed, *resolution)

    def _scorers(
        self, observed: tuple[np.ndarray | None, ...], top: tuple[np.ndarray | None, ...]
    ) -> list[list[Callable[[], ObservationScorer] | None]]:
        """Per level, each view's `ObservationScorer` of the observation at the level's resolution (None for a view
        that lost the person; ``top``: the observations at the top level's, or at any), to ask for when the descent
        reaches it: made then, unless a worker thread, starting from the finest level's, has made it already
        (`tracker.threads.TwoEndedJobs`)."""
        levels, views = range(len(self.tree.levels)), range(len(observed))
        pairs = [(k, v) for k in levels for v in views if observed[v] is not None]
        jobs = TwoEndedJobs(
            [functools.partial(self._scorer, k, v, top[v] if k == 0 else observed[v]) for k, v in pairs]
        )
        job = {pair: n for n, pair in enumerate(pairs)}
        return [[functools.partial(jobs.result, job[k, v]) if (k, v) in job else None for v in views] for k in levels]

    def _scorer(self, level: int, view: int, observed: np.ndarray) -> ObservationScorer:
        """View ``view``'s observation's scorer at ``level`` (``observed`` at any level's resolution)."""
        return ObservationScorer(self.cost, self.observation_at(level, observed), self._stacks[level][view].window)

    def scores_from(
        self, scorer: ObservationScorer, level: int, view: int, nodes: np.ndarray | None = None
    ) -> np.ndarray:
        """View ``view``'s distances of ``scorer``'s observation to the representatives of ``nodes`` of ``level``
        (all of them for None); with spot pixels, each moved from its spot to the reference's (`shifts`)."""
        if level == 0:
            return self.top_scoring(scorer, view)(nodes)
        representatives = self.tree.levels[level].representatives
        samples = representatives if nodes is None else representatives[nodes]
        runs = self._stacks[level][view].runs
        if self.spot_pixels is None:
            return scorer.scores_of_runs(runs, samples)
        return scorer.scores_of_shifted(runs, samples, self.shifts(level, view, samples, self._reference))

    def top_scoring(self, scorer: ObservationScorer, view: int) -> Callable[[np.ndarray | None], np.ndarray]:
        """`scores_from` at the top level, for any nodes asked (all for None) in turns: the sums of the nodes'
        run boundaries (`RunBoundaries`), moved with spot pixels (`ShiftedRunBoundaries`), the observation's prefix
        sums made once."""
        if self.spot_pixels is None:
            return scorer.scoring(self.top_boundaries[view])
        return scorer.scoring(self.top_boundaries[view], np.rint(self.spot_pixels[0][self._reference, view]))

    def shifts(self, level: int, view: int, samples: np.ndarray, reference: int) -> np.ndarray:
        """``(len(samples), 2)`` the whole pixels ``(du, dv)`` by which ``samples`` are moved at ``level`` in view
        ``view`` when the observation is on sample ``reference``'s spot: the difference of the two spot pixels
        rounded; at the top level, the difference of the two each rounded (what makes it one product)."""
        pixels = self.spot_pixels[level][:, view]
        if level == 0:
            return (np.rint(pixels[reference]) - np.rint(pixels[samples])).astype(np.int64)
        return np.rint(pixels[reference] - pixels[samples]).astype(np.int64)

    def score_samples(
        self,
        level: int,
        observations: tuple[np.ndarray | None, ...],
        samples: np.ndarray,
        reference: int | None = None,
    ) -> list[np.ndarray | None]:
        """Per view, the distances of its observation (at ``level``'s resolution) to ``samples`` (None for a view
        that lost the person); with spot pixels, each moved from its spot to that of sample ``reference`` (the
        observation's)."""
        scores = []
        for view, (observation, stack) in enumerate(zip(observations, self._stacks[level], strict=True)):
            if observation is None:
                scores.append(None)
                continue
            scorer = self._scorer(level, view, observation)
            scores.append(
                scorer.scores_of_runs(stack.runs, samples)
                if self.spot_pixels is None
                else scorer.scores_of_shifted(stack.runs, samples, self.shifts(level, view, samples, reference))
            )
        return scores

    def log_likelihood(self, level: int, distances: list[np.ndarray | None]) -> np.ndarray:
        """Eq 10 at ``level`` from each view's distances: the sum over views of ``-d^2 / 2 sigma^2``, the log of the
        product of the views' likelihoods (a view that lost the person, None, left out)."""
        terms = (
            -0.5 * (d / sigma) ** 2
            for d, sigma in zip(distances, self.level_sigmas[level], strict=True)
            if d is not None
        )
        return functools.reduce(operator.add, terms)  # in the views' order
