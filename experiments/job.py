"""One run: build the components a composed config names, run the frames, write the three outputs.

Outputs in the job's directory, each written atomically: ``run.rrd`` (Rerun), ``frames.parquet`` (one row per
frame and part; columns in `experiments.outputs`), ``timings.json`` (per-stage medians, ms) and, last,
``metrics.json`` (choices, seed, frames, status, accuracy where the tracker estimates). Timings are kept out of
``metrics.json`` so that the same seed gives the same bytes; a complete ``metrics.json`` marks a finished job.
A failure inside the loop is recorded as ``status: "failed: <reason>"`` with every output still written.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from hydra.errors import InstantiationException
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from experiments.config import check_config
from experiments.outputs import accuracy, body_tracking, frame_rows, silhouette_quality
from experiments.recording import RunRecording
from tracker.atomic import write_json, write_parquet
from tracker.models.body_mesh import BodyMesh
from tracker.observe.silhouettes import SilhouetteCapture, SilhouetteSettings
from tracker.render.nuisance import SensorNuisance
from tracker.render.offscreen import Lighting, SceneRenderer
from tracker.sequence import background_frames, simulate

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Components:
    """What a run is made of, built from the config's groups."""

    model: Any
    motion: Any
    cameras: tuple
    tracker: Any

    @property
    def views(self) -> list[str]:
        return [camera.name for camera in self.cameras]


def build(cfg: DictConfig) -> Components:
    # tracker=tbf takes the chosen silhouette cost and motion model (their own config groups).
    extras = {"cost": instantiate(cfg.cost), "motion": instantiate(cfg.motion)} if cfg.get("cost") else {}
    return Components(
        model=instantiate(cfg.model, _convert_="all"),
        motion=instantiate(cfg.scene, _convert_="all"),
        cameras=instantiate(cfg.rig, _convert_="all"),
        # (passed to the partial: instantiate would turn dataclass objects given as arguments into dicts)
        tracker=instantiate(cfg.tracker, _convert_="all", _partial_=True)(**extras),
    )


def finished_metrics(cfg: DictConfig, output_dir: Path) -> dict[str, Any] | None:
    """The metrics of a finished job of this very config in ``output_dir`` (status ok, same resolved config), or
    None. A killed job never leaves a complete ``metrics.json`` (it is written last, atomically)."""
    try:
        metrics = json.loads((output_dir / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(metrics, dict) or metrics.get("status") != "ok":
        return None
    return metrics if metrics.get("config") == OmegaConf.to_container(cfg, resolve=True) else None


def remove_stale_temporaries(output_dir: Path) -> None:
    """Temporary files a killed job left behind (`tracker.atomic` names them ``.<name>.<random>.tmp``)."""
    for path in output_dir.glob(".*.tmp"):
        path.unlink(missing_ok=True)


def run_job(cfg: DictConfig, output_dir: Path, choices: dict[str, str]) -> dict[str, Any]:
    """Run the configured scene for ``cfg.frames`` frames into ``output_dir``; return the metrics written."""
    check_config(cfg, choices)  # an invalid config raises before any output exists
    remove_stale_temporaries(output_dir)
    rows: list[dict[str, Any]] = []
    timings: list[dict[str, float]] = []
    components: Components | None = None
    recording: RunRecording | None = None
    status = "ok"
    stop = StopRequest.install()
    try:
        components = build(cfg)
        model, cameras = components.model, components.cameras
        silhouettes = isinstance(model, BodyMesh)  # paper 2's observation: background-subtraction silhouettes
        recording = RunRecording(
            output_dir / "run.rrd",
            cameras=cameras,
            part_names=model.part_names,
            part_colors=model.part_colors,
            jpeg_quality=cfg.record.jpeg_quality,
            images=cfg.record.images,
            silhouettes=silhouettes,
            weight_maps=cfg.record.weight_maps,
        )
        nuisance = camera_nuisance(cfg)
        nuisance_rng = np.random.default_rng([cfg.seed, 2])  # the camera's own stream (1: the tracker's)
        renderer = SceneRenderer(
            cameras[0].width,
            cameras[0].height,
            background_rgb=tuple(cfg.render.background_rgb),
            lighting=Lighting(ambient=cfg.render.ambient),
        )
        tracker = components.tracker
        # The tracker's own random stream (stream 1 of the run's seed; the model's textures use others).
        tracker.start(model, cameras, components.motion.params(model, 0), np.random.default_rng([cfg.seed, 1]))
        with renderer:
            capture = None
            if silhouettes:
                empty = background_frames(cameras, renderer, cfg.silhouette.background_frames, nuisance, nuisance_rng)
                settings = {k: v for k, v in cfg.silhouette.items() if k != "background_frames"}
                capture = SilhouetteCapture.learn(empty, SilhouetteSettings(**settings))
            frames = simulate(model, components.motion, cameras, renderer, cfg.frames, nuisance, nuisance_rng)
            for frame in tqdm(frames, total=cfg.frames, desc="frames", disable=not sys.stderr.isatty()):
                captured = None
                if capture is not None:
                    captured = capture.step({name: view.rgb for name, view in frame.views.items()},
                                            {name: view.labels > 0 for name, view in frame.views.items()})
                    frame.timings_ms["capture"] = captured.ms
                    frame = dataclasses.replace(frame, silhouettes=captured.silhouettes)
                start = time.perf_counter()
                result = tracker.step(frame)
                estimated = time.perf_counter()
                if result is not None:
                    frame.timings_ms["estimate"] = 1e3 * (estimated - start)
                    frame.timings_ms.update({f"estimate_{k}": v for k, v in result.timings_ms.items()})
                recording.log_frame(frame, model)
                if captured is not None:
                    recording.log_capture(captured)
                if result is not None:
                    recording.log_estimate(result, model)
                frame.timings_ms["record"] = 1e3 * (time.perf_counter() - estimated)
                recording.log_timings(frame.frame, frame.timings_ms)
                rows.extend(frame_rows(frame, model, result, captured))
                timings.append(frame.timings_ms)
                if stop.requested:
                    break
    except Exception as error:  # recorded, not raised: a sweep goes on and every output stays readable
        log.exception("run failed at frame %d", len(timings))
        status = f"failed: {failure_reason(error)}"
    except BaseException:  # an exit or interrupt raised anyway: the outputs still say the run did not finish
        status = "failed: interrupted"
        raise
    finally:
        if components is not None:
            components.tracker.close()
        stop.restore()
        if stop.requested:
            status = f"failed: interrupted by {stop.requested}"
        if recording is not None:
            recording.close()
        table = pd.DataFrame(rows)
        write_parquet(output_dir / "frames.parquet", table)
        write_json(output_dir / "timings.json", timing_summary(timings, components.views if components else []))
        metrics = summarize(cfg, choices, components, table, timings, status)
        write_json(output_dir / "metrics.json", metrics)
    if stop.requested:  # outputs are safe; now stop like the signal asked (a sweep stops too)
        raise KeyboardInterrupt if stop.requested == "SIGINT" else SystemExit(128 + signal.SIGTERM)
    return metrics


class StopRequest:
    """SIGINT and SIGTERM ask the frame loop to stop after the current frame (then the run writes its outputs).

    A KeyboardInterrupt raised wherever the signal lands can be swallowed (inside a finalizer of a GL object it is
    only printed), and the run would go on; a flag checked once per frame cannot be missed. A second signal of the
    same kind takes the default action at once.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested: str | None = None
        self._previous: dict[int, Any] = {}

    @classmethod
    def install(cls) -> StopRequest:
        request = cls()
        if threading.current_thread() is threading.main_thread():  # signal handlers live in the main thread
            for number in cls.SIGNALS:
                request._previous[number] = signal.signal(number, request._handle)
        return request

    def _handle(self, number: int, _frame: Any) -> None:
        self.requested = signal.Signals(number).name
        log.warning("%s: stopping after this frame (again to stop at once)", self.requested)
        signal.signal(number, self._previous.get(number, signal.SIG_DFL))

    def restore(self) -> None:
        for number, previous in self._previous.items():
            signal.signal(number, previous)
        self._previous = {}


def failure_reason(error: BaseException) -> str:
    """``Type: message`` on one line, of the error a factory raised rather than Hydra's wrapper around it."""
    if isinstance(error, InstantiationException) and error.__cause__ is not None:
        error = error.__cause__
    message = str(error).strip().splitlines()
    return f"{type(error).__name__}: {message[0]}" if message else type(error).__name__


def summarize(
    cfg: DictConfig,
    choices: dict[str, str],
    components: Components | None,
    table: pd.DataFrame,
    timings: list[dict[str, float]],
    status: str,
) -> dict[str, Any]:
    """The run's metrics.json content: everything but the timings (`timing_summary`), so it is reproducible."""
    metrics: dict[str, Any] = {
        "status": status,
        "choices": dict(sorted(choices.items())),
        "seed": int(cfg.seed),
        "frames": int(cfg.frames),
        "frames_done": len(timings),
        "views": components.views if components else [],
        "tracker": components.tracker.name if components else None,
        "config": OmegaConf.to_container(cfg, resolve=True),
    }
    describe = getattr(components.tracker, "describe", None) if components else None
    if describe is not None:  # what the tracker built at start (e.g. TBF's sample and tree sizes)
        metrics.update(describe())
    if not table.empty:
        metrics["min_visible_fraction"] = min_visible_fraction(table, components.views)
        metrics.update(silhouette_quality(table))
        metrics.update(body_tracking(table))
        metrics.update(accuracy(table))
    return metrics


def timing_summary(timings: list[dict[str, float]], views: list[str]) -> dict[str, float]:
    """timings.json: the median ms of every stage over the frames (frame 0 lacks some stages), and per view."""
    if not timings:
        return {}
    stages = timings[-1].keys()
    summary = {f"{stage}_ms_median": float(np.median([t[stage] for t in timings if stage in t])) for stage in stages}
    if views and "render_ms_median" in summary:
        summary["render_ms_per_view_median"] = summary["render_ms_median"] / len(views)
    return summary


def camera_nuisance(cfg: DictConfig) -> SensorNuisance | None:
    """The configured sensor noise and illumination change, or None when both are off."""
    render = cfg.render
    if render.noise_std == 0 and render.gain_amplitude == 0:
        return None
    return SensorNuisance(render.noise_std, render.gain_amplitude, render.gain_period_frames)


def min_visible_fraction(table: pd.DataFrame, views: list[str]) -> dict[str, dict[str, float]]:
    """Per part and view: the fewest label pixels over the run relative to the most (0 = fully hidden at times)."""
    fractions: dict[str, dict[str, float]] = {}
    for part, rows in table.groupby("part", sort=False):
        fractions[part] = {}
        for view in views:
            pixels = rows[f"visible_px_{view}"]
            fractions[part][view] = round(float(pixels.min() / pixels.max()), 4) if pixels.max() > 0 else 0.0
    return fractions
