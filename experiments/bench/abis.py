"""``python -m experiments.bench abis [--frames N] [--size WxH]``: AbIS estimation per frame with ``lm`` and with
``sd`` on the same rendered frames (the rendering of the synthetic input excluded, the tracker's visibility z-buffer
included), with their ratio measured in the same run; and the evaluation's point-to-surface distances of each
``lm`` estimate (every part, both ways: `tracker.evaluation.arm.part_surface_distances_mm`)."""

from __future__ import annotations

import argparse
import logging
import statistics
import time

import numpy as np

from experiments.bench.common import default_scene, report_machine
from experiments.loop import frame_threads
from tracker.evaluation.arm import part_surface_distances_mm
from tracker.models.dsq import PARAM_INDEX
from tracker.render.offscreen import SceneRenderer
from tracker.sequence import simulate

log = logging.getLogger(__name__)


def bench_abis(frames: int, width: int, height: int) -> dict[str, dict[str, float]]:
    """AbIS estimation time per frame (features, fit, visibility z-buffer, pairing; the synthetic input's own
    rendering excluded) for `lm` and `sd`, on the same rendered frames, after frame 0."""
    scene = default_scene(width, height)
    arm, rig = scene.model, scene.cameras
    with SceneRenderer(width, height) as renderer:
        inputs = list(simulate(arm, scene.scene, rig, renderer, frames))
    results = {}
    for optimizer in ("lm", "sd"):
        tracker = default_scene(width, height, "tracker=abis", f"tracker.fit.optimizer={optimizer}").tracker
        tracker.start(arm, rig, inputs[0].truth, np.random.default_rng([0, 1]))
        per_frame, stages, estimates = [], {}, []
        try:
            with frame_threads():  # as a run steps it
                for frame in inputs:
                    start = time.perf_counter()
                    result = tracker.step(frame.observation())
                    if frame.frame > 0:
                        per_frame.append(1e3 * (time.perf_counter() - start))
                        for stage, ms in result.timings_ms.items():
                            stages.setdefault(stage, []).append(ms)
                    estimates.append(result.estimate)
        finally:
            tracker.close()
        estimates, truths = np.array(estimates), np.array([frame.truth for frame in inputs])
        b1, r2 = PARAM_INDEX["b1"], PARAM_INDEX["r2"]
        results[optimizer] = {
            "estimate_ms": statistics.median(per_frame),
            **({"point_to_surface_ms": point_to_surface_ms(arm, truths, estimates)} if optimizer == "lm" else {}),
            **{f"{stage}_ms": statistics.median(values) for stage, values in stages.items()},
            "part2_b1_rms_pct": 100
            * float(np.sqrt(np.mean((estimates[:, 1, b1] - truths[:, 1, b1]) ** 2)) / np.ptp(truths[:, 1, b1])),
            "part2_r2_rms_deg": float(np.degrees(np.sqrt(np.mean((estimates[:, 1, r2] - truths[:, 1, r2]) ** 2)))),
        }
    return results


def point_to_surface_ms(arm, truths: np.ndarray, estimates: np.ndarray) -> float:
    """Median ms per frame of the evaluation's point-to-surface distances (every part, both ways)."""
    per_frame = []
    for truth, estimate in zip(truths[1:], estimates[1:], strict=True):
        start = time.perf_counter()
        part_surface_distances_mm(arm, estimate, truth, arm.sample_points(estimate), arm.sample_points(truth))
        per_frame.append(1e3 * (time.perf_counter() - start))
    return statistics.median(per_frame)


def report_abis(results: dict[str, dict[str, float]], frames: int, width: int, height: int) -> None:
    log.info("AbIS estimation, paper-1 arm, 3 views at %dx%d, median over frames 1..%d:", width, height, frames - 1)
    for optimizer, figures in results.items():
        stages = ", ".join(
            f"{k[:-3]} {v:.1f}"
            for k, v in figures.items()
            if k.endswith("_ms") and k not in ("estimate_ms", "point_to_surface_ms")
        )
        log.info(
            "  %s  %6.1f ms/frame  (%s)  part2 b1 RMS %.1f%% of range, r2 RMS %.2f deg",
            optimizer,
            figures["estimate_ms"],
            stages,
            figures["part2_b1_rms_pct"],
            figures["part2_r2_rms_deg"],
        )
    log.info("  sd / lm time ratio: %.2f", results["sd"]["estimate_ms"] / results["lm"]["estimate_ms"])
    log.info(
        "evaluation: point-to-surface distances of the lm estimates, every part both ways: %.1f ms/frame",
        results["lm"]["point_to_surface_ms"],
    )


def run(args: argparse.Namespace) -> dict:
    results = bench_abis(args.frames, args.width, args.height)
    report_machine()  # after the run: loading the renderer sets the OpenGL platform
    report_abis(results, args.frames, args.width, args.height)
    return results
