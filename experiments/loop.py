"""The frame loop of a run: render, capture, estimate, record and tabulate each frame, until done or stopped."""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from experiments.components import Components
from experiments.outputs import RunLog, frame_rows
from experiments.recording import RunRecording
from tracker.observe.silhouettes import CapturedFrame, SilhouetteCapture
from tracker.protocol import Observation, RenderedFrame, StepResult, Tracker
from tracker.sequence import background_frames, simulate
from tracker.timing import elapsed_ms


def run_frames(
    components: Components,
    recording: RunRecording,
    stop: Any,
    log: RunLog,
) -> None:
    """Start the tracker, then run every frame, appending its table rows and stage timings to ``log``
    (``stop.requested`` ends the loop after the current frame; while the tracker starts, a stop is at once). The
    tracker sees each frame's observation only."""
    settings, model, cameras, tracker = components.settings, components.model, components.cameras, components.tracker
    nuisance = settings.render.nuisance()
    nuisance_rng = np.random.default_rng([settings.seed, 2])  # the camera's own stream (1: the tracker's)
    renderer = settings.render.renderer(cameras[0].width, cameras[0].height)
    # The tracker's own random stream (stream 1 of the run's seed; the model's textures use others).
    with stop.at_once():  # a stop while the tracker starts (a sample build) need not wait for it
        tracker.start(model, cameras, components.scene.params(model, 0), np.random.default_rng([settings.seed, 1]))
    with renderer:
        capture = None
        if "silhouettes" in components.observes:  # paper 2's observation: background subtraction
            empty = background_frames(cameras, renderer, settings.silhouette.background_frames, nuisance, nuisance_rng)
            capture = SilhouetteCapture.learn(empty, settings.silhouette)
        frames = simulate(model, components.scene, cameras, renderer, settings.frames, nuisance, nuisance_rng)
        with frame_threads():
            for frame in tqdm(frames, total=settings.frames, desc="frames", disable=not sys.stderr.isatty()):
                captured = capture_frame(capture, frame)
                result = estimate(tracker, frame, frame.observation(captured.silhouettes if captured else None))
                evaluated = evaluate(components, frame, result)
                record_frame(recording, frame, captured, result, evaluated)
                log.add(frame_rows(frame, components, result, captured, evaluated), frame.timings_ms, result)
                if stop.requested:
                    break


def frame_threads() -> threadpool_limits:
    """The thread limits a run steps its tracker under, and benchmarks time it under (`experiments.bench`): BLAS on
    one thread. A frame's linear algebra is small (the hybrid's fit: systems of 72 unknowns): BLAS threads waiting
    for each other cost more than they share, most on a busy machine (the hybrid's refinement took 4x as long with
    two threads as with one while the machine ran other work), and they spin on the cores the tracker's own worker
    threads use."""
    return threadpool_limits(limits=1, user_api="blas")


def capture_frame(capture: SilhouetteCapture | None, frame: RenderedFrame) -> CapturedFrame | None:
    """The frame's silhouettes extracted from its RGB, with their IoU against the render's masks (None: the run
    captures none)."""
    if capture is None:
        return None
    captured = capture.step(
        {name: view.rgb for name, view in frame.views.items()},
        {name: view.labels > 0 for name, view in frame.views.items()},
    )
    frame.timings_ms["capture"] = captured.ms
    return captured


def estimate(tracker: Tracker, frame: RenderedFrame, observation: Observation) -> StepResult | None:
    """The tracker's step on what it observes of ``frame``, timed (``estimate`` and its own stages as
    ``estimate_<stage>``, into the frame's timings)."""
    start = time.perf_counter()
    result = tracker.step(observation)
    if result is not None:
        frame.timings_ms["estimate"] = elapsed_ms(start)
        frame.timings_ms.update({f"estimate_{k}": v for k, v in result.timings_ms.items()})
    return result


def evaluate(components: Components, frame: RenderedFrame, result: StepResult | None) -> tuple[dict, dict]:
    """The model's evaluation columns of the frame (`tracker.evaluation`): per part, per frame; timed as
    ``evaluate``."""
    if components.evaluation is None:
        return {}, {}
    start = time.perf_counter()
    columns = components.evaluation.columns(components.model, frame.truth, None if result is None else result.estimate)
    frame.timings_ms["evaluate"] = elapsed_ms(start)
    return columns


def record_frame(
    recording: RunRecording,
    frame: RenderedFrame,
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
