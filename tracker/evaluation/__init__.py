"""How estimates are judged against the truth, per model: columns of a frame's row (truth, estimate, errors), a
run's figures, and, for a tracker that searches a dictionary of samples, what its samples allow.

An evaluation registers itself for a model's registered name, beside its code (`register_evaluation`; the
models know nothing of it). It has ``columns(model, truth, estimate)`` -> ``(per_part, per_frame)`` column
dictionaries for one frame (``estimate`` None when nothing was estimated); ``summarize(model, table)`` -> a run's
accuracy figures from the frames table (``table``: column name -> ``(rows,)`` array, one row per frame and part,
frame-major); ``floor(model, dictionary, table)`` -> the figures had the sample nearest the truth been the estimate
at every frame, and those samples (`tracker.evaluation.dictionary`); and ``series``, the numeric columns worth a
time series in the recording (per part where they are per part).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

from tracker.protocol import Model, SampleDictionary


class Evaluation(Protocol):
    series: tuple[str, ...]

    def columns(self, model: Model, truth: np.ndarray, estimate: np.ndarray | None) -> tuple[dict, dict]: ...

    def summarize(self, model: Model, table: Mapping[str, np.ndarray]) -> dict[str, Any]: ...

    def floor(
        self, model: Model, dictionary: SampleDictionary, table: Mapping[str, np.ndarray]
    ) -> tuple[dict[str, Any], np.ndarray]: ...


EVALUATIONS: dict[str, Evaluation] = {}


def register_evaluation(model: str, evaluation: Evaluation) -> None:
    """Judge the estimates of the model registered as ``model`` by ``evaluation``."""
    EVALUATIONS[model] = evaluation


def evaluation_of(model: str) -> Evaluation | None:
    """How the estimates of the model registered as ``model`` are judged (None: they are not)."""
    return EVALUATIONS.get(model)
