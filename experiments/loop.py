"""The frame loop of a run: render, capture, estimate, record and tabulate each frame, until done or stopped."""

from __future__ import annotations

import dataclasses
import sys
import time
from typing import Any

import numpy as np
from tqdm import tqdm

from experiments.components import Components
from experiments.outputs import frame_rows
from experiments.recording import RunRecording
from tracker.observe.silhouettes import CapturedFrame, SilhouetteCapture
from tracker.protocol import FrameInput, StepResult
from tracker.sequence import background_frames, simulate
from tracker.timing import elapsed_ms


def run_frames(
    components: Components,
    recording: RunRecording,
    stop: Any,
    rows: list[dict[str, Any]],
    timings: list[dict[str, float]],
) -> None:
    """Start the tracker, then run every frame, appending its table rows and stage timings (``stop.requested``
    ends the loop after the current frame)."""
    settings, model, cameras, tracker = components.settings, components.model, components.cameras, components.tracker
    nuisance = settings.render.nuisance()
    nuisance_rng = np.random.default_rng([settings.seed, 2])  # the camera's own stream (1: the tracker's)
    renderer = settings.render.renderer(cameras[0].width, cameras[0].height)
    # The tracker's own random stream (stream 1 of the run's seed; the model's textures use others).
    tracker.start(model, cameras, components.scene.params(model, 0), np.random.default_rng([settings.seed, 1]))
    with renderer:
        capture = None
        if "silhouettes" in components.observes:  # paper 2's observation: background subtraction
            empty = background_frames(cameras, renderer, settings.silhouette.background_frames, nuisance, nuisance_rng)
            capture = SilhouetteCapture.learn(empty, settings.silhouette)
        frames = simulate(model, components.scene, cameras, renderer, settings.frames, nuisance, nuisance_rng)
        for frame in tqdm(frames, total=settings.frames, desc="frames", disable=not sys.stderr.isatty()):
            frame, captured = capture_frame(capture, frame)
            result = estimate(tracker, frame)
            evaluated = evaluate(components, frame, result)
            record_frame(recording, frame, captured, result, evaluated)
            rows.extend(frame_rows(frame, components, result, captured, evaluated))
            timings.append(frame.timings_ms)
            if stop.requested:
                break


def capture_frame(capture: SilhouetteCapture | None, frame: FrameInput) -> tuple[FrameInput, CapturedFrame | None]:
    """The frame with its silhouettes extracted from the RGB (their IoU against the render's masks kept apart)."""
    if capture is None:
        return frame, None
    captured = capture.step(
        {name: view.rgb for name, view in frame.views.items()},
        {name: view.labels > 0 for name, view in frame.views.items()},
    )
    frame.timings_ms["capture"] = captured.ms
    return dataclasses.replace(frame, silhouettes=captured.silhouettes), captured


def estimate(tracker: Any, frame: FrameInput) -> StepResult | None:
    """The tracker's step, timed (``estimate`` and its own stages as ``estimate_<stage>``)."""
    start = time.perf_counter()
    result = tracker.step(frame)
    if result is not None:
        frame.timings_ms["estimate"] = elapsed_ms(start)
        frame.timings_ms.update({f"estimate_{k}": v for k, v in result.timings_ms.items()})
    return result


def evaluate(components: Components, frame: FrameInput, result: StepResult | None) -> tuple[dict, dict]:
    """The model's evaluation columns of the frame (`tracker.evaluation`): per part, per frame."""
    if components.evaluation is None:
        return {}, {}
    return components.evaluation.columns(components.model, frame.truth, None if result is None else result.estimate)


def record_frame(
    recording: RunRecording,
    frame: FrameInput,
    captured: CapturedFrame | None,
    result: StepResult | None,
    evaluated: tuple[dict, dict],
) -> None:
    """Everything of the frame into the recording, timed as ``record``."""
    start = time.perf_counter()
    recording.log_frame(frame)
    if captured is not None:
        recording.log_capture(captured)
    if result is not None:
        recording.log_result(result, evaluated)
    frame.timings_ms["record"] = elapsed_ms(start)
    recording.log_timings(frame.frame, frame.timings_ms)
