"""A dictionary-searching tracker judged against the truth after the run: what its samples allow and where its own
cost could not tell (`tracker.protocol.SampleDictionary`).

The floor: at every frame the sample nearest the truth (by the model's evaluation: in 3-D for the body, in the
samples' space for the arm), scored as if it had been the estimate; no search over these samples can do better.
A frame is ambiguous when the tracker's own cost finds the observation at least as likely under the estimate's
sample as under the floor's: there the cost itself prefers a pose no nearer the truth, and no filter would have
done better. A frame whose estimate is the floor's sample, or that failed, is not ambiguous.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tracker.evaluation import Evaluation
from tracker.protocol import Model, SampleDictionary


def judge_dictionary(
    evaluation: Evaluation, model: Model, dictionary: SampleDictionary, table: Mapping[str, np.ndarray]
) -> dict[str, Any]:
    """The floor's figures (`Evaluation.floor`), ``ambiguous_frames`` and ``ambiguous_per_frame``, from the run's
    table (one row per frame and part, frame-major, with the tracker's ``est_sample``)."""
    figures, nearest = evaluation.floor(model, dictionary, table)
    frame = table["part"] == model.part_names[0]  # one row per frame
    flags = [
        bool(
            np.isfinite(estimate)
            and int(estimate) != int(floor)
            and dictionary.prefers(int(f), int(estimate), int(floor))
        )
        for f, estimate, floor in zip(table["frame"][frame], table["est_sample"][frame], nearest, strict=True)
    ]
    return {**figures, "ambiguous_frames": int(sum(flags)), "ambiguous_per_frame": flags}
