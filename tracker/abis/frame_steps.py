"""What AbIS does the same way on every model, frame by frame: the frame loop (`AbisSequence`) with its steps, pair
bookkeeping over the views' feature tracks, the samples' image motion, and the result of a frame."""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracker.abis.correspondences import COUNT_NAMES, PairTable
from tracker.abis.selection import selection_of
from tracker.abis.settings import AbisSettings
from tracker.abis.visibility import VisibleSamples
from tracker.geometry.cameras import Camera
from tracker.membership import members
from tracker.observe.features import FeatureFrame, FeatureTracker
from tracker.protocol import Observation, Points, StepResult
from tracker.render.offscreen import DepthLabels
from tracker.threads import TwoEndedJobs
from tracker.timing import elapsed_ms

TRACKED, NEW, DISCARDED_OCCLUSION, DISCARDED_ERROR, LOST = range(len(COUNT_NAMES))


@dataclass(frozen=True, eq=False)
class ViewResult:
    """What one view saw and did: its features, the state of each (``FEATURE_STATES``), the estimate's samples."""

    features: FeatureFrame
    feature_states: np.ndarray  # (n,) index into FEATURE_STATES
    visible: VisibleSamples


FEATURE_STATES = ("tracked", "new", "discarded", "unpaired")


@dataclass(frozen=True, eq=False, kw_only=True)
class AbisResult(StepResult):
    """A frame of AbIS: per view the pair counts (`COUNT_NAMES` order), the pairs held after the frame, what each
    view saw and did; per part eq 8's cost at the end of its fit (0 where it had no pairs) and the iterations.
    Build it with `AbisResult.of`, which also fills the columns, series and points every run records."""

    counts: dict[str, np.ndarray]  # view -> (n_parts, 5)
    pairs: dict[str, np.ndarray]  # view -> (n_parts,)
    cost: np.ndarray  # (n_parts,)
    iterations: np.ndarray  # (n_parts,)
    views: dict[str, ViewResult]

    @classmethod
    def of(cls, part_names: Sequence[str], **fields: Any) -> AbisResult:
        counts, pairs, views = fields["counts"], fields["pairs"], fields["views"]
        columns: dict[str, np.ndarray] = {}
        for index, count in enumerate(COUNT_NAMES):
            per_view = {view: view_counts[:, index] for view, view_counts in counts.items()}
            columns[count] = sum(per_view.values())
            columns.update({f"{count}_{view}": values for view, values in per_view.items()})
        columns.update(pairs=sum(pairs.values()), cost=fields["cost"], iterations=fields["iterations"])
        series = {
            f"correspondences/{part}/{count}": float(columns[count][k])
            for k, part in enumerate(part_names)
            for count in COUNT_NAMES
        }
        series.update({f"cost/{part}": float(fields["cost"][k]) for k, part in enumerate(part_names)})
        points = {
            view: {
                "features": Points(seen.features.points, seen.feature_states, FEATURE_STATES),
                "estimate": Points(seen.visible.uv),
            }
            for view, seen in views.items()
        }
        return cls(part_columns=columns, series=series, points=points, **fields)


def feature_rows(features: FeatureFrame, ids: np.ndarray) -> np.ndarray:
    """The feature points of ``ids`` (all live in ``features``)."""
    order = np.argsort(features.ids)
    return features.points[order[np.searchsorted(features.ids[order], ids)]]


def carry_over(
    pairs: Mapping[str, Any], features: Mapping[str, FeatureFrame], counts: Mapping[str, np.ndarray], n_parts: int
) -> dict[str, Any]:
    """Step 1: each view's pairs (``pairs``: view -> its pair table) whose feature was tracked into this frame;
    the tracked and lost ones counted per part into ``counts`` (view -> ``(n_parts, 5)``)."""
    kept = {}
    for name, held in pairs.items():
        live = members(held.feature_ids, features[name].ids)
        counts[name][:, LOST] = held.subset(~live).count_by_part(n_parts)
        kept[name] = held.subset(live)
        counts[name][:, TRACKED] = kept[name].count_by_part(n_parts)
    return kept


def discard(
    pairs: PairTable,
    seen: np.ndarray,
    uv: np.ndarray,
    features: FeatureFrame,
    max_residual_px: float,
    counts: np.ndarray,
) -> tuple[PairTable, np.ndarray]:
    """Step 4's discards in one view: the pairs not ``seen`` (hidden, or about to be: occlusion), then those seen
    whose point projects (``uv``) farther than ``max_residual_px`` from its feature (false matches), each counted
    per part into ``counts``; the pairs kept, and the discarded ones' feature ids."""
    n_parts = len(counts)
    counts[:, DISCARDED_OCCLUSION] = pairs.subset(~seen).count_by_part(n_parts)
    residual = np.linalg.norm(uv - feature_rows(features, pairs.feature_ids), axis=1)
    wrong = seen & (residual > max_residual_px)
    counts[:, DISCARDED_ERROR] = pairs.subset(wrong).count_by_part(n_parts)
    return pairs.subset(seen & ~wrong), pairs.feature_ids[~seen | wrong]


def feature_states(paired_ids: np.ndarray, features: FeatureFrame, discarded: np.ndarray) -> np.ndarray:
    """Each feature's index into FEATURE_STATES after a view's upkeep (``paired_ids``: its pairs' features)."""
    states = np.full(len(features.ids), FEATURE_STATES.index("unpaired"))
    paired = members(features.ids, paired_ids)
    states[paired & features.tracked] = FEATURE_STATES.index("tracked")
    states[paired & features.new] = FEATURE_STATES.index("new")
    states[members(features.ids, discarded)] = FEATURE_STATES.index("discarded")
    return states


class ImageMotion:
    """Every sample's image motion per view between the last two estimates, for the model's prediction of
    occlusion (`tracker.abis.visibility.reached_by_other_parts`)."""

    def __init__(self) -> None:
        self._pixels: dict[str, np.ndarray] = {}  # view -> the last estimate's samples' pixels

    def step(self, camera: Camera, points: np.ndarray) -> np.ndarray:
        """``(n, 2)`` pixels per frame of the samples at world ``points`` ``(n, 3)`` in ``camera`` since the last
        call (zero at the first and where a sample does not project); keeps this call's pixels for the next."""
        pixels = camera.project(points)[0]
        before = self._pixels.get(camera.name, pixels)
        self._pixels[camera.name] = pixels
        return np.nan_to_num(pixels - before, nan=0.0, posinf=0.0, neginf=0.0)


class AbisSequence:
    """One sequence of AbIS on a model, frame by frame: features tracked in every view, pairs carried over (1), the
    parts fitted (2), the new estimate's visibility (3), each view's pairs kept, discarded and made (4), and the
    frame's counts and result. The selection (`tracker.abis.selection`) decides what is seen; a model's sequence
    says how it fits (`_fit`), sees (`_visibility`), where its pairs' points are and how its samples move
    (`_pair_points`, `_sample_motion`), and how new pairs form and are kept (`_new_pairs` in each view; `_settled`,
    `_held` for all views at once: at a few pairs a view, a step's fixed cost outweighs its work). It is built at
    `AbisTracker.start` with frame 0's estimate and its empty pair table."""

    def __init__(
        self,
        settings: AbisSettings,
        part_names: Sequence[str],
        cameras: Sequence[Camera],
        estimate: np.ndarray,
        no_pairs: PairTable,
    ) -> None:
        self.settings, self.part_names, self.cameras = settings, tuple(part_names), list(cameras)
        self.selection = selection_of(settings)
        self._estimate = estimate
        self._trackers = {  # feature ids are unique across views
            camera.name: FeatureTracker(settings.features, first_id=k << 40) for k, camera in enumerate(cameras)
        }
        self._pairs = {camera.name: no_pairs for camera in cameras}
        self._motion = ImageMotion()  # the samples' image motion, for the model image's prediction of occlusion
        self._frame = 0

    def step(self, observation: Observation) -> AbisResult:
        n_parts = len(self.part_names)
        names = [camera.name for camera in self.cameras]
        counts = {name: np.zeros((n_parts, len(COUNT_NAMES)), int) for name in names}
        timings: dict[str, float] = {}
        failure = None
        cost, iterations = np.zeros(n_parts), np.zeros(n_parts, int)

        start = time.perf_counter()  # the views' features tracked here and on a worker thread (OpenCV frees the GIL)
        tracking = TwoEndedJobs(
            [functools.partial(self._trackers[name].step, observation.images[name]) for name in names]
        )
        features = dict(zip(names, tracking.results(), strict=True))
        timings["features"] = elapsed_ms(start)
        if self._frame > 0:
            self._pairs = carry_over(self._pairs, features, counts, n_parts)  # 1. pairs whose feature was tracked
            start = time.perf_counter()  # 2. fit top-down
            estimate, cost, iterations, failure = self._fit(features)
            timings["fit"] = elapsed_ms(start)
            if failure is None:
                self._estimate = estimate

        start = time.perf_counter()  # 3. visibility of the new estimate
        zbuffers, visible, points, posed = self._visibility()
        timings["visibility"] = elapsed_ms(start)
        start = time.perf_counter()  # 4. pair upkeep: each view's pairs kept and new ones matched, then all views'
        kept, discarded, matched = {}, {}, {}  # new pairs made ready and held at once (one batch, not one a view)
        before = [self._pairs[name] for name in names]  # the pairs carried into step 4, their points posed at once
        ends = np.cumsum([len(pairs) for pairs in before])[:-1]
        on_estimate = np.split(self._pair_points(before[0].joined(before), posed), ends)
        for camera, pair_points in zip(self.cameras, on_estimate, strict=True):
            name = camera.name
            motion = self._motion.step(camera, points) if self.selection.uses_model_image else None
            kept[name], discarded[name], matched[name] = self._upkeep(
                camera, features[name], zbuffers[name], visible[name], motion, posed, pair_points, counts[name]
            )
        new = self._settled(matched, features, posed)
        for name in names:
            counts[name][:, NEW] = new[name].count_by_part(n_parts)
        self._pairs = self._held(features, kept, new, posed)
        views = {}
        for name in names:
            states = feature_states(self._pairs[name].feature_ids, features[name], discarded[name])
            views[name] = ViewResult(features[name], states, visible[name])
        timings["pairing"] = elapsed_ms(start)
        if failure is None and all(len(pairs) == 0 for pairs in self._pairs.values()):
            failure = "all pairs lost"
        self._frame += 1
        return AbisResult.of(
            self.part_names,
            frame=observation.frame,
            estimate=self._estimate.copy(),
            counts=counts,
            pairs={name: self._pairs[name].count_by_part(n_parts) for name in names},
            cost=cost,
            iterations=iterations,
            views=views,
            timings_ms=timings,
            failure=failure,
        )

    def _upkeep(
        self,
        camera: Camera,
        features: FeatureFrame,
        zbuffer: DepthLabels | None,
        visible: VisibleSamples,
        motion: np.ndarray | None,
        posed: Any,
        pair_points: np.ndarray,
        counts: np.ndarray,
    ) -> tuple[PairTable, np.ndarray, PairTable]:
        """Step 4 in one view: the pairs the selection no longer sees are discarded for occlusion, those off their
        feature as false (counted into ``counts`` ``(parts, 5)``); the unpaired features are matched with visible
        samples. ``motion``: every sample's image motion over the last frame (with the model image); ``posed``:
        what `_visibility` posed; ``pair_points``: the view's pairs' world points on it (`_pair_points`, all views'
        at once). Returns the pairs kept, the discarded features' ids and the new pairs matched (`_settled` makes
        them ready)."""
        pairs = self._pairs[camera.name]
        moving = self.selection.uses_model_image
        seen, uv = self.selection.seen(
            camera,
            zbuffer,
            pairs.parts,
            pair_points,
            self._sample_motion(pairs.parts, pairs.samples, motion) if moving else None,
            visible,
            self._sample_motion(visible.part, visible.sample, motion) if moving else None,
        )
        pairs, discarded = discard(pairs, seen, uv, features, self.settings.max_residual_px, counts)
        unpaired = ~members(features.ids, pairs.feature_ids) & ~members(features.ids, discarded)
        regions = self.selection.regions(zbuffer, features.points)
        return pairs, discarded, self._new_pairs(camera, features, unpaired, regions, visible, pairs, posed)

    def _fit(self, features: Mapping[str, FeatureFrame]) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
        """Step 2: every part fitted top-down against the current pairs: the estimate, per part eq 8's cost and
        the iterations, and a failure (None, or why the previous estimate stands)."""
        raise NotImplementedError

    def _visibility(self) -> tuple[dict[str, DepthLabels | None], dict[str, VisibleSamples], np.ndarray, Any]:
        """Step 3, for the estimate: per view its z-buffer (None without the model image) and the samples it sees;
        every sample's world point (parts one after another: their image motion is followed); and the posed model
        that upkeep reads pairs' points from (the arm's part transforms, the body's vertices)."""
        raise NotImplementedError

    def _pair_points(self, pairs: PairTable, posed: Any) -> np.ndarray:
        """``(n, 3)`` world points of ``pairs`` on the posed estimate."""
        raise NotImplementedError

    def _sample_motion(self, parts: np.ndarray, samples: np.ndarray, motion: np.ndarray) -> np.ndarray:
        """``(n, 2)`` image motion of the samples ``samples`` of ``parts``, from every sample's ``motion``."""
        raise NotImplementedError

    def _new_pairs(
        self,
        camera: Camera,
        features: FeatureFrame,
        unpaired: np.ndarray,
        regions: np.ndarray | None,
        visible: VisibleSamples,
        pairs: PairTable,
        posed: Any,
    ) -> PairTable:
        """New pairs of the ``unpaired`` features (a mask) with samples of the part whose region holds each
        (``regions``, -1 none; None: any part), none taken by ``pairs`` already (`_settled` then sees them)."""
        raise NotImplementedError

    def _settled(
        self, matched: Mapping[str, PairTable], features: Mapping[str, FeatureFrame], posed: Any
    ) -> dict[str, PairTable]:
        """Every view's new pairs (``matched``: view -> `_new_pairs`'), ready to be held: as matched, unless a model
        refines them (all views at once)."""
        return dict(matched)

    def _held(
        self,
        features: Mapping[str, FeatureFrame],
        kept: Mapping[str, PairTable],
        new: Mapping[str, PairTable],
        posed: Any,
    ) -> dict[str, PairTable]:
        """Every view's pairs after the frame (view -> table): those kept and the new ones."""
        return {name: pairs.extend(new[name]) for name, pairs in kept.items()}
