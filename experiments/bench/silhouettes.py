"""``python -m experiments.bench silhouettes [--samples N]`` (paper 2's observation and costs): builds a pose sample
set of ``--samples`` poses (the right-arm grid, side-on) into a fresh cache and reports the build time per 1,000
samples; extracts the silhouette of a rendered frame under the nuisance model (ms and IoU); scores it against every
sample at 80x60 with each cost (ms for the whole set, from the samples' runs), checked against the per-pair function
on 100 samples."""

from __future__ import annotations

import argparse
import logging
import statistics
import tempfile
import time

import numpy as np

from experiments.bench.common import report_machine
from experiments.components import Components, build, compose
from tracker.observe.silhouettes import CapturedFrame, SilhouetteCapture, resize_silhouette
from tracker.registry import COSTS
from tracker.sequence import background_frames
from tracker.tbf.costs import silhouette_distance
from tracker.tbf.pose_sets import arm_grid, remove_near_duplicates
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.scoring import ObservationScorer, SilhouetteStack
from tracker.tol import TINY

log = logging.getLogger(__name__)


def bench_silhouettes(samples: int) -> dict[str, float]:
    """Sample-set build time, silhouette extraction, and scoring one observation against every sample at 80x60."""
    scene = build(compose(["model=body_mesh"]))  # the body, side-on, with its capture setting
    body, rig = scene.model, scene.cameras
    left = (0.0, -30.0, 30.0, 60.0, 90.0, -60.0, 120.0)
    poses = arm_grid(
        body,
        np.arange(-60.0, 121.0, 6.0),
        np.arange(0.0, 61.0, 10.0),
        np.arange(0.0, 101.0, 10.0),
        left_swing_deg=left[: max(1, -(-samples // 2387))],
    )
    start = time.perf_counter()
    kept = remove_near_duplicates(poses)[:samples]
    dedupe_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as cache:
        start = time.perf_counter()
        sample_set = load_or_build(body, rig[0], poses[kept], cache)
        build_s = time.perf_counter() - start
        stack = sample_set.silhouettes((80, 60))
        assert len(stack.runs) == len(stack)  # the runs are found once per sample set, not timed
        captured = _captured(scene)
        observed = resize_silhouette(captured[-1].silhouettes["main"], 80, 60)
        return {
            "samples": len(sample_set),
            "grid_poses": len(poses),
            "dedupe_s": dedupe_s,
            "build_s_per_1000": 1e3 * build_s / len(sample_set),
            "window_80x60": stack.window,
            "capture_ms": statistics.median(c.ms for c in captured),
            "capture_iou": captured[-1].iou["main"],
            **{key: value for cost in COSTS.names() for key, value in _scoring(cost, observed, stack).items()},
        }


def _captured(scene: Components) -> list[CapturedFrame]:
    """Frame 10 of the scene's swing, its silhouette extracted 20 times under the camera's nuisance."""
    body, rig, render = scene.model, scene.cameras, scene.settings.render
    nuisance, rng = render.nuisance(), np.random.default_rng(0)
    with render.renderer(320, 240) as renderer:
        capture = SilhouetteCapture.learn(background_frames(rig, renderer, 20, nuisance, rng))
        view = renderer.render(rig, body.surface_meshes(scene.scene.params(body, 10)))["main"]
    return [capture.step({"main": nuisance.apply(view.rgb, 10, rng)}, {"main": view.labels > 0}) for _ in range(20)]


def _scoring(cost: str, observed: np.ndarray, stack: SilhouetteStack) -> dict[str, float]:
    """One observation scored against every sample with ``cost`` (median ms of 7), and the largest relative
    difference from the per-pair function on the first 100."""
    times = []
    for _ in range(7):
        start = time.perf_counter()
        scores = ObservationScorer(cost, observed, stack.window).scores(stack)
        times.append(1e3 * (time.perf_counter() - start))
    reference = [
        silhouette_distance(cost, observed, np.pad(mask, _padding(stack.window, (80, 60))), stack.window)
        for mask in stack.masks(np.arange(min(100, len(stack))))
    ]
    relative = np.abs(scores[:100] - reference) / np.maximum(np.abs(reference), TINY)
    return {f"{cost}_ms": statistics.median(times), f"{cost}_max_relative_difference": float(relative.max())}


def _padding(window, size):
    u0, v0, u1, v1 = window
    return ((v0, size[1] - v1), (u0, size[0] - u1))


def run(args: argparse.Namespace) -> dict:
    figures = bench_silhouettes(args.samples)
    report_machine()
    log.info("paper 2 body, side-on camera:")
    log.info(
        "  sample set: %d samples (of %d grid poses, de-duplicated in %.1f s), built in %.2f s per 1,000",
        figures["samples"],
        figures["grid_poses"],
        figures["dedupe_s"],
        figures["build_s_per_1000"],
    )
    log.info(
        "  silhouette extraction 320x240: %.2f ms (median of 20), IoU %.4f against the render mask",
        figures["capture_ms"],
        figures["capture_iou"],
    )
    for cost in COSTS.names():
        log.info(
            "  %-5s one observation vs %d samples at 80x60 (window %s): %.2f ms; max relative difference "
            "to the per-pair function %.1e",
            cost,
            figures["samples"],
            figures["window_80x60"],
            figures[f"{cost}_ms"],
            figures[f"{cost}_max_relative_difference"],
        )
    return figures
