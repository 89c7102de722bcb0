"""The hybrid tracker, ``tracker=hybrid``: paper 2 proposes, paper 1's way refines.

Each frame, tree filtering (`tracker.tbf.tracker.TbfTracker`, all its settings) searches its dictionary of pose
samples for the frame's silhouettes: a global search that recovers what a local fit loses. Its best sample, placed
where the person stands, and the last frame's refined pose are the candidates; each is refined by the continuous
fit of the tracker's own body to every view's silhouette (`tracker.hybrid.silhouette_fit`: the joints and the
root by Levenberg-Marquardt with the skinning's analytic Jacobian). The candidate whose refined pose explains the
views best (the lowest `SilhouetteFit.fit_cost`) is the estimate, and ``feed`` of the filter's posterior is moved
onto the sample nearest it, so the next frame's prior starts from it. The tracker never sees the truth; the
evaluation judges its estimates, and its dictionary's floor, as tree filtering's.

Frame columns: ``hybrid_choice`` (0: the dictionary's proposal, 1: the previous refined pose), ``fit_cost`` (of the
chosen pose) and ``fit_cost_proposal`` (of the proposal before refining); the stage ``refine`` in the timings.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, ClassVar

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.hybrid.silhouette_fit import FitSettings, SilhouetteFit
from tracker.models.body_mesh import BodyMesh
from tracker.protocol import Observation
from tracker.ranges import Range
from tracker.registry import TRACKERS, Fit
from tracker.tbf.costs import Cost
from tracker.tbf.motion import RandomWalk
from tracker.tbf.settings import TbfSettings, check_settings
from tracker.tbf.tracker import TBF_LOOK, TbfResult, TbfTracker
from tracker.timing import elapsed_ms

CHOICES = ("proposal", "previous")  # hybrid_choice's values, in order


@dataclass(frozen=True)
class HybridSettings(TbfSettings):
    """Tree filtering's settings, the silhouette fit's, and how much of the filter's posterior the refined estimate
    takes for the next frame's prior."""

    fit: FitSettings = field(default_factory=FitSettings)
    feed: Annotated[float, Range(0.0, 1.0)] = 0.5


class NearestSample:
    """The sample whose joint rotations are nearest a pose's (Euclidean over the rotation vectors: the samples are
    postures in place, their roots' positions not compared)."""

    def __init__(self, poses: np.ndarray) -> None:
        self.rotations = np.asarray(poses, dtype=np.float64)[:, 3:]
        self.norms = np.einsum("nk,nk->n", self.rotations, self.rotations)

    def __call__(self, pose: np.ndarray) -> int:
        rotations = np.asarray(pose, dtype=np.float64)[3:]
        return int(np.argmin(self.norms - 2 * self.rotations @ rotations))


@TRACKERS.register(
    "hybrid",
    settings=HybridSettings,
    needs={"cost": "nwxor", "motion": "learned"},
    models={"body_mesh": Fit((1, 4))},
    observes=("silhouettes",),
    presentation=TBF_LOOK,
    check=check_settings,
)
class HybridTracker(TbfTracker):
    name: ClassVar[str] = "hybrid"

    def __init__(self, settings: HybridSettings, cost: Cost, motion: RandomWalk) -> None:
        super().__init__(settings, cost, motion)
        self.refined: np.ndarray | None = None

    def start(self, model: BodyMesh, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator) -> None:
        super().start(model, cameras, initial, rng)
        self.fit = SilhouetteFit(self.body, self.cameras, self.settings.fit)
        self.nearest = NearestSample(self.samples.poses)
        self.refined = None

    def step(self, observation: Observation) -> TbfResult:
        """Tree filtering's step, then its proposal and the previous refined pose refined and the better kept."""
        found = super().step(observation)
        if found.failure is not None:
            return found
        start = time.perf_counter()
        self.fit.observe([observation.silhouettes[camera.name] for camera in self.cameras])
        candidates = [found.estimate] + ([self.refined] if self.refined is not None else [])
        refined = [self.fit.refine(candidate) for candidate in candidates]
        costs = [self.fit.fit_cost(pose) for pose in refined]
        choice = int(np.argmin(costs))
        self.refined = self._estimate = refined[choice]
        if self.settings.feed > 0:
            self.filter.feed(self.nearest(self.refined), self.settings.feed)
        found.frame_columns.update(
            hybrid_choice=choice, fit_cost=costs[choice], fit_cost_proposal=self.fit.fit_cost(found.estimate)
        )
        timings = {**found.timings_ms, "refine": elapsed_ms(start)}
        return TbfResult(
            filter=found.filter,
            frame=found.frame,
            estimate=self.refined.copy(),
            timings_ms=timings,
            part_columns=found.part_columns,
            frame_columns=found.frame_columns,
            series={**found.series, "hybrid/fit_cost": costs[choice], "hybrid/choice": float(choice)},
        )
