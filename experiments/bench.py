"""Benchmarks, apart from the tests: ``python -m experiments.bench render|abis [--frames N] [--size WxH]``.

``render``: the paper-1 arm scene through the off-screen renderer, per frame and per view, split into the lit RGB
+ depth pass and the label pass, after a warm-up frame. Reports medians and the ratio of the two passes measured
in the same run.

``abis``: AbIS estimation per frame with ``lm`` and with ``sd`` on the same rendered frames (the rendering of the
synthetic input excluded, the tracker's visibility z-buffer included), with their ratio measured in the same run.
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from experiments.config import option_values
from tracker.abis.tracker import AbisTracker
from tracker.geometry.rigs import orthogonal3
from tracker.models.dsq import PARAM_INDEX
from tracker.models.dsq_arm import build_arm
from tracker.motion.arm_swing import ArmSwing
from tracker.render.offscreen import SceneRenderer
from tracker.sequence import simulate

log = logging.getLogger(__name__)


def default_scene(width: int, height: int):
    """The configured default arm, its motion and the orthogonal rig at ``width`` x ``height``."""
    arm = build_arm(**option_values("model", "dsq_arm"), seed=0)
    motion = ArmSwing(**option_values("scene", "arm_swing")["arm"])
    rig = orthogonal3(**{**option_values("rig", "orthogonal3"), "width": width, "height": height})
    return arm, motion, rig


def bench_render(frames: int, width: int, height: int) -> dict[str, float]:
    arm, motion, rig = default_scene(width, height)
    frame_ms, rgb_ms, label_ms, pose_ms = [], [], [], []
    with SceneRenderer(width, height) as renderer:
        renderer.render(rig, arm.surface_meshes(motion.params(arm, 0)))  # warm-up: shader compilation, uploads
        rss_start = _resident_mb()
        for frame in range(1, frames + 1):
            start = time.perf_counter()
            meshes = arm.surface_meshes(motion.params(arm, frame))
            posed = time.perf_counter()
            renderer.render(rig, meshes)
            done = time.perf_counter()
            pose_ms.append(1e3 * (posed - start))
            frame_ms.append(1e3 * (done - posed))
            rgb_ms.append(renderer.last_pass_ms["rgb_depth"])
            label_ms.append(renderer.last_pass_ms["labels"])
        rss_growth = _resident_mb() - rss_start
    views = len(rig)
    return {
        "views": views,
        "pose_ms_per_frame": statistics.median(pose_ms),
        "render_ms_per_frame": statistics.median(frame_ms),
        "render_ms_per_view": statistics.median(frame_ms) / views,
        "rgb_depth_pass_ms_per_view": statistics.median(rgb_ms) / views,
        "label_pass_ms_per_view": statistics.median(label_ms) / views,
        "resident_growth_mb": rss_growth,
    }


def _resident_mb() -> float:
    """Resident memory of this process (Linux ``/proc``), in MB."""
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def bench_abis(frames: int, width: int, height: int) -> dict[str, dict[str, float]]:
    """AbIS estimation time per frame (features, fit, visibility z-buffer, pairing; the synthetic input's own
    rendering excluded) for `lm` and `sd`, on the same rendered frames, after frame 0."""
    arm, motion, rig = default_scene(width, height)
    with SceneRenderer(width, height) as renderer:
        inputs = list(simulate(arm, motion, rig, renderer, frames))
    results = {}
    for optimizer in ("lm", "sd"):
        settings = option_values("tracker", "abis")
        tracker = AbisTracker.from_config(**{**settings, "fit": {**settings["fit"], "optimizer": optimizer}})
        tracker.start(arm, rig, inputs[0].truth, np.random.default_rng([0, 1]))
        per_frame, stages, estimates = [], {}, []
        try:
            for frame in inputs:
                start = time.perf_counter()
                result = tracker.step(frame)
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
            **{f"{stage}_ms": statistics.median(values) for stage, values in stages.items()},
            "part2_b1_rms_pct": 100 * float(np.sqrt(np.mean((estimates[:, 1, b1] - truths[:, 1, b1]) ** 2))
                                        / np.ptp(truths[:, 1, b1])),
            "part2_r2_rms_deg": float(np.degrees(np.sqrt(np.mean((estimates[:, 1, r2] - truths[:, 1, r2]) ** 2)))),
        }  # fmt: skip
    return results


def report_abis(results: dict[str, dict[str, float]], frames: int, width: int, height: int) -> None:
    log.info("AbIS estimation, paper-1 arm, 3 views at %dx%d, median over frames 1..%d:", width, height, frames - 1)
    for optimizer, figures in results.items():
        stages = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in figures.items() if k.endswith("_ms") and k != "estimate_ms")
        log.info("  %s  %6.1f ms/frame  (%s)  part2 b1 RMS %.1f%% of range, r2 RMS %.2f deg", optimizer,
                 figures["estimate_ms"], stages, figures["part2_b1_rms_pct"], figures["part2_r2_rms_deg"])
    log.info("  sd / lm time ratio: %.2f", results["sd"]["estimate_ms"] / results["lm"]["estimate_ms"])


def _report_machine() -> None:
    log.info("machine: %s, %d cores, %s; OpenGL platform %s", platform.processor() or platform.machine(),
             os.cpu_count(), platform.python_implementation() + " " + platform.python_version(),
             os.environ.get("PYOPENGL_PLATFORM"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", choices=["render", "abis"])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT of every view")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    width, height = (int(v) for v in args.size.lower().split("x"))
    if args.target == "abis":
        results = bench_abis(args.frames, width, height)
        _report_machine()  # after the run: loading the renderer sets the OpenGL platform
        report_abis(results, args.frames, width, height)
        return
    result = bench_render(args.frames, width, height)
    _report_machine()
    log.info("render, paper-1 arm, %d views at %dx%d, median of %d frames:", result["views"], width, height,
             args.frames)
    log.info("  pose + mesh        %7.2f ms/frame", result["pose_ms_per_frame"])
    log.info("  render (all views) %7.2f ms/frame", result["render_ms_per_frame"])
    log.info("  render per view    %7.2f ms  = lit RGB + depth pass %.2f ms + label pass %.2f ms (ratio %.2f)",
             result["render_ms_per_view"], result["rgb_depth_pass_ms_per_view"], result["label_pass_ms_per_view"],
             result["rgb_depth_pass_ms_per_view"] / result["label_pass_ms_per_view"])
    log.info("  resident memory    %+7.1f MB over the %d frames after warm-up",
             result["resident_growth_mb"], args.frames)


if __name__ == "__main__":
    main()
