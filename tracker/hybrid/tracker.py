"""The hybrid tracker, ``tracker=hybrid``: paper 2 proposes, paper 1's way refines.

Each frame, tree filtering (`tracker.tbf.tracker.TbfTracker`, all its settings) searches its dictionary of pose samples
for the frame's silhouettes: a global search that recovers what a local fit loses. Its estimate and next most probable
samples, ``proposals`` in all, placed where the person stands, and the last frame's refined pose are the candidates,
with that pose turned about the vertical by each of ``turns_deg`` and, with ``extrapolate``, moved on by its last change
(at frame 0, with ``start_from=initial``, the pose the run gives, as AbIS starts; held where it stands); each is refined
for ``screen_iterations`` (with ``screen_best``, only the ``screen_best`` whose silhouettes' cost is lowest as proposed,
and the last refined pose) by the continuous fit of the tracker's own body to every view's silhouette
(`tracker.hybrid.silhouette_fit`: the joints and the root by Levenberg-Marquardt with the skinning's analytic Jacobian,
the root held near where tree filtering placed the person, or, where the views could not place him, where the last
refined pose stood: `root_held`), and the one that then explains the views best (the lowest
`SilhouetteFit.fit_cost`; of those whose root turned at most ``max_turn_deg`` from the last refined pose, or from tree
filtering's estimate: ``turn_from``) is refined on to the estimate. A hard frame, whose estimate costs more than
``rescue_ratio`` times the last frames' median, is searched again: every candidate screened, the ``screen_best``
lowest after their screen refined in full, the lowest kept. ``feed`` of the filter's posterior is moved onto the
sample nearest it, so the next frame's prior starts from it (a worker thread searches the samples for it between the
frames, `tracker.threads`; the next step moves the posterior before its prior). The tracker never sees the truth;
the evaluation judges its estimates, and its dictionary's floor, as tree filtering's.

The fit also follows the skin's features (`tracker.hybrid.feature_pairs`): each frame's features are tied to the
refined body, and the next frame's pairs ask those points to move with them. They guide each candidate's fit; the
silhouettes alone choose between the candidates.

Frame columns: ``hybrid_choice`` (the candidate kept: 0 the filter's estimate, then its next proposals, the previous
refined pose moved on (turned, extrapolated), last the previous refined pose as it was), ``screened`` (the candidates
screened), ``rescued`` (1: the frame was searched again), ``fit_cost`` (the silhouettes' cost of the estimate),
``fit_cost_proposal`` (of the proposal before refining), ``feature_pairs`` (over the views) and ``turned_away`` (the
screened candidates ``max_turn_deg`` kept from the choice); the stage ``refine`` in the timings (the features' tracking
with it).
"""

from __future__ import annotations

import functools
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Annotated, ClassVar, Literal

import numba
import numpy as np
from scipy.spatial.transform import Rotation

from tracker.geometry.cameras import Camera
from tracker.geometry.rotations import rotation_angle_deg, rotation_vectors_to_matrices
from tracker.hybrid.feature_pairs import FeaturePairs
from tracker.hybrid.silhouette_fit import FitSettings, SilhouetteFit
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import turned_about_vertical
from tracker.protocol import Observation
from tracker.ranges import Range
from tracker.registry import TRACKERS, Fit
from tracker.tbf.costs import Cost
from tracker.tbf.motion import RandomWalk
from tracker.tbf.samples import LEVEL_RESOLUTIONS
from tracker.tbf.settings import TbfSettings, check_settings
from tracker.tbf.tracker import TBF_LOOK, TbfResult, TbfTracker, most_probable
from tracker.threads import TwoEndedJobs
from tracker.timing import elapsed_ms


@dataclass(frozen=True)
class HybridSettings(TbfSettings):
    """Tree filtering's settings, the silhouette fit's, and how much of the filter's posterior the refined estimate
    takes for the next frame's prior."""

    fit: FitSettings = field(default_factory=FitSettings)
    proposals: Annotated[int, Range(1, 100)] = 3  # the filter's best samples refined each frame
    # Each candidate's iterations before the best is refined on (on the validation clip martial_09, 1 did as well
    # as 3 at 60 % of the time).
    screen_iterations: Annotated[int, Range(0, 100)] = 1
    feed: Annotated[float, Range(0.0, 1.0)] = 0.5
    # A candidate whose root turned more than this from the last refined pose is not chosen (180: any may be): one
    # silhouette looks much the same from the front and the back, a person seldom turns that far in a frame.
    max_turn_deg: Annotated[float, Range(0.0, 180.0)] = 180.0
    # What that turn is measured from: the last refined pose (``refined``), or tree filtering's estimate of the frame
    # (``proposal``: a candidate is chosen on the side of the camera's depth ambiguity the filter found).
    turn_from: Literal["refined", "proposal"] = "refined"
    # Where frame 0 starts: tree filtering's initial prior alone (upright, facing ``initial_yaw_deg``), or also the
    # frame-0 pose the run gives (paper 1's user-assisted alignment, as AbIS starts): a candidate of frame 0, and
    # ``feed``'s share of the first prior on its nearest sample.
    start_from: Literal["prior", "initial"] = "prior"
    # Of the candidates, only this many are screened: those whose silhouettes' cost is lowest as proposed, the last
    # refined pose always among them (None: every candidate). A screen is most of a candidate's cost.
    screen_best: Annotated[int, Range(1, 100)] | None = None
    # More candidates from the last refined pose, for motion faster than a frame's fit reaches and than the
    # dictionary holds (a dancer's spin turns 30-45 degrees a frame at 15 fps): the pose turned about the vertical
    # by each of ``turns_deg``, and with ``extrapolate`` the pose moved on by its last frame's change (the root's
    # turn composed again, each joint's rotation vector stepped as much again).
    turns_deg: tuple[Annotated[float, Range(-180.0, 180.0)], ...] = ()
    extrapolate: bool = False
    # A frame whose refined estimate costs the silhouettes more than this many times the median of the last
    # `RECENT_FRAMES` estimates' is searched again (None: never): every candidate screened, and the ``screen_best``
    # lowest after their screen refined in full (a limb that moved faster than the fit follows: the screen's few
    # iterations judge a proposal by where it starts, the full refinement by where it ends).
    rescue_ratio: Annotated[float, Range(1.0)] | None = None


class NearestSample:
    """The sample whose joint rotations are nearest a pose's (Euclidean over the rotation vectors: the samples are
    postures in place, their roots' positions not compared; of equally near ones, the first).

    Exact, without reading every sample's 93 numbers: each sample's distance along the samples' first
    `SEARCH_AXES` principal axes is a lower bound of its whole distance (a projection onto orthonormal axes never
    lengthens one). The sample nearest along them gives a first whole distance; only the samples whose bound is
    within it are measured in full (a few hundred of 50,000 on `hybrid_multi_view`'s dictionary)."""

    SEARCH_AXES = 16

    def __init__(self, poses: np.ndarray) -> None:
        rotations = np.asarray(poses, dtype=np.float64)[:, 3:]
        self.rotations = np.ascontiguousarray(rotations)
        self.center = rotations.mean(axis=0)
        centred = rotations - self.center
        _, axes = np.linalg.eigh(centred.T @ centred)
        self.axes = np.ascontiguousarray(axes[:, ::-1][:, : self.SEARCH_AXES])  # the largest spreads first
        self.projected = np.ascontiguousarray(centred @ self.axes)

    def __call__(self, pose: np.ndarray) -> int:
        rotations = np.asarray(pose, dtype=np.float64)[3:]
        return int(_nearest_sample(self.rotations, self.projected, (rotations - self.center) @ self.axes, rotations))


@numba.njit(cache=True, nogil=True)
def _nearest_sample(rotations: np.ndarray, projected: np.ndarray, query: np.ndarray, pose: np.ndarray) -> int:
    """`NearestSample`'s search: ``projected`` the samples along the axes, ``query`` the pose along them."""
    bounds = np.empty(len(projected))
    for s in range(len(projected)):
        total = 0.0
        for a in range(projected.shape[1]):
            total += (projected[s, a] - query[a]) ** 2
        bounds[s] = total
    first = np.argmin(bounds)
    best, found = 0.0, first
    for a in range(rotations.shape[1]):
        best += (rotations[first, a] - pose[a]) ** 2
    reach = best * (1 + 1e-9) + 1e-12  # the bounds' own rounding
    for s in range(len(rotations)):
        if bounds[s] > reach:
            continue
        total = 0.0
        for a in range(rotations.shape[1]):
            total += (rotations[s, a] - pose[a]) ** 2
        if total < best or (total == best and s < found):
            best, found = total, s
    return found


@TRACKERS.register(
    "hybrid",
    settings=HybridSettings,
    needs={"cost": "nwxor", "motion": "learned"},
    models={"body_mesh": Fit((1, 4))},
    observes=("silhouettes",),
    presentation=TBF_LOOK,
    min_image=LEVEL_RESOLUTIONS[0],  # the tree's coarsest level
    check=check_settings,
)
class HybridTracker(TbfTracker):
    name: ClassVar[str] = "hybrid"
    RECENT_FRAMES: ClassVar[int] = 10  # the estimates whose cost a frame's is compared with (``rescue_ratio``)

    def __init__(self, settings: HybridSettings, cost: Cost, motion: RandomWalk) -> None:
        super().__init__(settings, cost, motion)
        self.refined: np.ndarray | None = None
        self._turn_reference: np.ndarray | None = None  # what a candidate's turn is measured from (`turned_away`)
        self._before_refined: np.ndarray | None = None  # the refined pose of the frame before (`extrapolate`)
        self._feeding: TwoEndedJobs[int] | None = None  # the sample nearest the last refined pose, to come
        self._recent_costs: deque[float] = deque(maxlen=self.RECENT_FRAMES)  # the last estimates' `fit_cost`

    def start(self, model: BodyMesh, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator) -> None:
        super().start(model, cameras, initial, rng)
        self.fit = SilhouetteFit(self.body, self.cameras, self.settings.fit)
        pairing = self.settings.fit.features
        self.features = FeaturePairs(self.body, self.cameras, pairing) if pairing.weight > 0 else None
        self.nearest = NearestSample(self.samples.poses)
        self.refined, self._feeding, self._given_root, self._before_refined = None, None, None, None
        self._recent_costs.clear()
        if self.settings.start_from == "initial":
            given = np.asarray(initial, dtype=np.float64).copy()
            self.refined, self._feeding = given, TwoEndedJobs([lambda: self.nearest(given)])
            self._given_root = given[:3]  # the first frame fitted holds the root where the given pose puts it

    def proposals(self, found: TbfResult, placed: np.ndarray) -> list[np.ndarray]:
        """The filter's best ``proposals`` samples by their posterior, each with its root at ``placed``."""
        posterior = self.filter.posterior
        ranked = most_probable(posterior, self.settings.proposals)
        best = found.estimate.copy()
        best[:3] = placed
        poses = [best]
        for sample in ranked[ranked != found.filter.sample][: self.settings.proposals - 1]:
            pose = np.asarray(self.samples.poses[sample], dtype=np.float64).copy()
            pose[:3] = placed
            poses.append(pose)
        return poses

    def step(self, observation: Observation) -> TbfResult:
        """Tree filtering's step, then its proposals and the previous refined pose screened, the best refined on."""
        start = time.perf_counter()
        pairs = (
            None if self.features is None else self.features.pairs([observation.images[c.name] for c in self.cameras])
        )
        pairing_ms = elapsed_ms(start)
        self._feed()
        found = super().step(observation)
        if found.failure is not None:
            if self.features is not None:
                self.features.forget()
            self._before_refined = None  # the last change spans the failed frame
            return found
        start = time.perf_counter()
        self.fit.observe([observation.silhouettes[camera.name] for camera in self.cameras], pairs)
        placed = self.root_held(found.estimate)
        self._given_root = None
        self._turn_reference = self.refined if self.settings.turn_from == "refined" else found.estimate
        candidates = self.proposals(found, placed) + self.moved_on()
        candidates += [self.refined] if self.refined is not None else []
        kept = self.screened(candidates)
        screened = self._screen(candidates, kept, placed)
        turned_away = self.turned_away([pose for pose, _ in screened], self._turn_reference)
        best = int(np.argmin(np.where(turned_away, np.inf, [cost for _, cost in screened])))
        choice = int(kept[best])
        self._before_refined = self.refined
        refined, cost = self.fit.refine(screened[best][0], root=placed)
        rescued = self._hard(cost)
        if rescued:
            (refined, cost, choice), kept, turned_away = self.rescue(
                candidates, kept, screened, (refined, cost, choice), placed
            )
        self._recent_costs.append(cost)
        self.refined = self._estimate = refined
        if self.features is not None:
            self.features.anchor(self.refined, [view.inside_px for view in self.fit.fields])
        if self.settings.feed > 0:
            self._feeding = TwoEndedJobs([lambda: self.nearest(refined)])
        found.frame_columns.update(
            hybrid_choice=choice,
            screened=len(kept),
            rescued=int(rescued),
            fit_cost=cost,
            fit_cost_proposal=self.fit.fit_cost(found.estimate),
            feature_pairs=sum(len(view) for view in self.fit.pairs),
            turned_away=int(turned_away.sum()),
        )
        return replace(
            found,
            estimate=self.refined.copy(),
            timings_ms={**found.timings_ms, "refine": elapsed_ms(start) + pairing_ms},
            series={**found.series, "hybrid/fit_cost": cost, "hybrid/choice": float(choice)},
        )

    def root_held(self, estimate: np.ndarray) -> np.ndarray:
        """Where this frame's candidates are put and their fit holds the root near: where tree filtering's
        ``estimate`` placed the person (`person_placed`); where it could not (someone out of a view), where the last
        refined pose stands, not the sample's own root (the samples are posed in place, metres from the person); the
        first frame, started from the given pose, where that stands."""
        if self._given_root is not None:
            return self._given_root
        if self.person_placed or self.refined is None:
            return estimate[:3]
        return self.refined[:3].copy()

    def _screen(
        self, candidates: Sequence[np.ndarray], indices: np.ndarray, placed: np.ndarray
    ) -> list[tuple[np.ndarray, float]]:
        """The ``indices`` of ``candidates`` each fitted for ``screen_iterations``, the root held near ``placed``:
        each one's refined pose and `SilhouetteFit.fit_cost` (shared with the worker threads: the fits' compiled
        passes free the GIL)."""
        return self._refined([candidates[k] for k in indices], self.settings.screen_iterations, placed)

    def _refined(
        self, starts: Sequence[np.ndarray], iterations: int | None, placed: np.ndarray
    ) -> list[tuple[np.ndarray, float]]:
        """`SilhouetteFit.refine` of each of ``starts``, independent fits shared with the worker threads."""
        return TwoEndedJobs(
            [functools.partial(self.fit.refine, start, iterations, placed) for start in starts]
        ).results()

    def _hard(self, cost: float) -> bool:
        """Whether a frame's refined estimate, of silhouettes' ``cost``, is searched again (``rescue_ratio``)."""
        ratio = self.settings.rescue_ratio
        return ratio is not None and len(self._recent_costs) > 0 and cost > ratio * np.median(self._recent_costs)

    def rescue(
        self,
        candidates: Sequence[np.ndarray],
        kept: np.ndarray,
        screened: Sequence[tuple[np.ndarray, float]],
        chosen: tuple[np.ndarray, float, int],
        placed: np.ndarray,
    ) -> tuple[tuple[np.ndarray, float, int], np.ndarray, np.ndarray]:
        """A hard frame searched again (``rescue_ratio``). The ``candidates`` not among ``kept`` (those screened, to
        ``screened``) are screened too; of all, the ``screen_best`` (None: every one) lowest after their screen are
        refined in full, but ``chosen``'s candidate, refined already (``chosen``: its refined pose, cost and index).
        Returns the lowest of those and ``chosen``, in ``chosen``'s form, the indices of the candidates screened (all
        of them, ascending), and which screened candidates turned away (`turned_away`; ``kept``'s, then the others')."""
        more = np.setdiff1d(np.arange(len(candidates)), kept)
        indices = np.r_[kept, more].astype(np.int64)
        screened = [*screened, *self._screen(candidates, more, placed)]
        turned_away = self.turned_away([pose for pose, _ in screened], self._turn_reference)
        costs = np.where(turned_away, np.inf, [cost for _, cost in screened])
        best = chosen
        picked = [
            j
            for j in np.argsort(costs, kind="stable")[: self.settings.screen_best or len(candidates)]
            if indices[j] != chosen[2] and np.isfinite(costs[j])
        ]
        for j, (pose, cost) in zip(picked, self._refined([screened[j][0] for j in picked], None, placed), strict=True):
            if cost < best[1]:
                best = (pose, cost, int(indices[j]))
        return best, np.sort(indices), turned_away

    def moved_on(self) -> list[np.ndarray]:
        """The last refined pose turned about the vertical by each of ``turns_deg``, then with ``extrapolate`` moved
        on by its last change (none before a pose was refined; extrapolated once two were)."""
        if self.refined is None:
            return []
        last = self.refined
        moved = [turned_about_vertical(last, np.radians(turn)) for turn in self.settings.turns_deg]
        if self.settings.extrapolate and self._before_refined is not None:
            before = self._before_refined
            onward = 2 * last - before
            onward[:3] = last[:3]
            root, root_before = Rotation.from_rotvec(last[3:6]), Rotation.from_rotvec(before[3:6])
            onward[3:6] = (root * root_before.inv() * root).as_rotvec()
            moved.append(onward)
        return moved

    def screened(self, candidates: Sequence[np.ndarray]) -> np.ndarray:
        """The indices (ascending) of the candidates to screen (``screen_best``): the last refined pose, last in
        ``candidates`` when there is one, and those of lowest `SilhouetteFit.fit_cost` as they are."""
        keep = self.settings.screen_best
        if keep is None or len(candidates) <= keep:
            return np.arange(len(candidates))
        costs = self.fit.fit_costs(candidates)
        if self.refined is not None:
            costs[-1] = -np.inf
        return np.sort(np.argsort(costs, kind="stable")[:keep])

    def turned_away(self, poses: Sequence[np.ndarray], reference: np.ndarray | None) -> np.ndarray:
        """``(len(poses),)`` bool: the poses whose root turned more than ``max_turn_deg`` from ``reference``, the
        frame's (``turn_from``: the last refined pose, none at the first frame and never itself, screened; or tree
        filtering's estimate)."""
        if reference is None or self.settings.max_turn_deg >= 180.0:
            return np.zeros(len(poses), bool)
        last = rotation_vectors_to_matrices(reference[3:6])[0]
        roots = rotation_vectors_to_matrices(np.array([pose[3:6] for pose in poses]))
        return np.array([rotation_angle_deg(last, root) for root in roots]) > self.settings.max_turn_deg

    def _feed(self) -> None:
        """The last refined pose's share of the posterior onto its nearest sample, before the prior is made."""
        if self._feeding is not None:
            self.filter.feed(self._feeding.result(0), self.settings.feed)
            self._feeding = None
