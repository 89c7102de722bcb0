"""A user's plugin, as a user would write it: a tracker and a silhouette cost of their own, registered here and
nowhere else, the tracker with the models it tracks from how many views and how it looks in the recording
(`test_plugboard` runs them through the real command line with ``plugins=[this module]``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from tracker.presentation import Panel, Presentation
from tracker.protocol import Observation, Points, StepResult, Tracker
from tracker.ranges import Positive
from tracker.registry import COSTS, TRACKERS, Fit


@dataclass(frozen=True)
class HoldSettings:
    """A baseline: the estimate never moves from frame 0's (the initial pose, as the papers' aligned start)."""

    marker_px: Positive = 5.0  # where the overlay's points sit, from each image corner


HOLD_LOOK = Presentation(
    panels=lambda parts: [Panel("frames held", "metrics/hold")],
    state_colors={"near": (10, 20, 30), "far": (40, 50, 60)},
)


@TRACKERS.register("hold_still", settings=HoldSettings, models={"dsq_arm": Fit((2, 3))}, presentation=HOLD_LOOK)
class HoldStill(Tracker):
    name: ClassVar[str] = "hold_still"

    def __init__(self, settings: HoldSettings) -> None:
        self.settings = settings

    def start(self, model, cameras, initial, rng) -> None:
        self.estimate, self.cameras, self.parts = np.array(initial), cameras, len(model.part_names)

    def step(self, frame: Observation) -> StepResult:
        d = self.settings.marker_px
        corners = {
            c.name: Points(np.array([[d, d], [c.width - d, c.height - d]]), np.array([0, 1]), ("near", "far"))
            for c in self.cameras
        }
        return StepResult(
            frame=frame.frame,
            estimate=self.estimate,
            part_columns={"held": np.ones(self.parts, bool)},
            frame_columns={"frames_held": frame.frame, "given": ",".join(sorted(vars(frame)))},
            series={"hold/frames": frame.frame},
            points={view: {"corners": points} for view, points in corners.items()},
        )

    def summarize(self, table) -> dict:
        return {"frames_held_max": int(np.max(table["frames_held"])), "summarized_from": sorted(table)}


@COSTS.register("uniform")
def uniform(inside: np.ndarray, *, weight: Positive = 2.0) -> np.ndarray:
    """Every pixel of the window weighs ``weight``: XOR scaled."""
    return np.full(inside.shape, weight)
