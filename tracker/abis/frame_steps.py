"""What AbIS does the same way on every model, frame by frame: pair bookkeeping over the views' feature tracks,
the label image's part interiors, the samples' image motion, and the result of a frame."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from tracker.abis.correspondences import COUNT_NAMES
from tracker.abis.visibility import VisibleSamples
from tracker.geometry.cameras import Camera
from tracker.observe.features import FeatureFrame
from tracker.protocol import Points, StepResult

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
        series = {f"correspondences/{part}/{count}": float(columns[count][k])
                  for k, part in enumerate(part_names) for count in COUNT_NAMES}  # fmt: skip
        series.update({f"cost/{part}": float(fields["cost"][k]) for k, part in enumerate(part_names)})
        points = {view: {"features": Points(seen.features.points, seen.feature_states, FEATURE_STATES),
                         "estimate": Points(seen.visible.uv)} for view, seen in views.items()}  # fmt: skip
        return cls(part_columns=columns, series=series, points=points, **fields)


def interior_labels(labels: np.ndarray, margin_px: int) -> np.ndarray:
    """The label image with every pixel within ``margin_px`` of another label (or the background) set to 0."""
    if margin_px <= 0:
        return labels
    kernel = np.ones((2 * margin_px + 1, 2 * margin_px + 1), np.uint8)
    smallest = cv2.erode(labels, kernel)  # a pixel keeps its label only if its whole neighbourhood has it
    largest = cv2.dilate(labels, kernel)
    return np.where((smallest == labels) & (largest == labels), labels, 0)


def feature_rows(features: FeatureFrame, ids: np.ndarray) -> np.ndarray:
    """The feature points of ``ids`` (all live in ``features``)."""
    order = np.argsort(features.ids)
    return features.points[order[np.searchsorted(features.ids[order], ids)]]


def carry_over(pairs: Mapping[str, Any], features: Mapping[str, FeatureFrame], counts: Mapping[str, np.ndarray],
               n_parts: int) -> dict[str, Any]:  # fmt: skip
    """Step 1: each view's pairs (``pairs``: view -> its pair table) whose feature was tracked into this frame;
    the tracked and lost ones counted per part into ``counts`` (view -> ``(n_parts, 5)``)."""
    kept = {}
    for name, held in pairs.items():
        live = np.isin(held.feature_ids, features[name].ids)
        counts[name][:, LOST] = held.subset(~live).count_by_part(n_parts)
        kept[name] = held.subset(live)
        counts[name][:, TRACKED] = kept[name].count_by_part(n_parts)
    return kept


def feature_states(paired_ids: np.ndarray, features: FeatureFrame, discarded: np.ndarray) -> np.ndarray:
    """Each feature's index into FEATURE_STATES after a view's upkeep (``paired_ids``: its pairs' features)."""
    states = np.full(len(features.ids), FEATURE_STATES.index("unpaired"))
    paired = np.isin(features.ids, paired_ids)
    states[paired & features.tracked] = FEATURE_STATES.index("tracked")
    states[paired & features.new] = FEATURE_STATES.index("new")
    states[np.isin(features.ids, discarded)] = FEATURE_STATES.index("discarded")
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
