"""Benchmarks, apart from the tests:
``python -m experiments.bench render|abis|silhouettes|tbf [--frames N] [--size WxH]``.

``render``: the paper-1 arm scene through the off-screen renderer, per frame and per view, split into the lit RGB
+ depth pass and the label pass, after a warm-up frame. Reports medians and the ratio of the two passes measured
in the same run.

``silhouettes`` (paper 2's observation and costs): builds a pose sample set of ``--samples`` poses (the right-arm
grid, side-on) into a fresh cache and reports the build time per 1,000 samples; extracts the silhouette of a
rendered frame under the nuisance model (ms and IoU); scores it against every sample at 80x60 with each cost
(ms for the whole set, from the samples' runs), checked against the per-pair function on 100 samples.

``abis``: AbIS estimation per frame with ``lm`` and with ``sd`` on the same rendered frames (the rendering of the
synthetic input excluded, the tracker's visibility z-buffer included), with their ratio measured in the same run.

``samples [--poses N] [--build] [overrides]``: label rendering before and after, the paper-scale set built cold
(`experiments.bench_samples`).

``tbf [--experiment tbf_table4c|tbf_paper_scale] [overrides]``: the tree-based filter per frame on the preset's
scene, from every camera of its rig (`experiments.bench_tbf`).
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

from experiments.components import Components, build, compose
from tracker.models.dsq import PARAM_INDEX
from tracker.registry import COSTS
from tracker.render.offscreen import SceneRenderer
from tracker.sequence import simulate
from tracker.tbf.scoring import ObservationScorer
from tracker.tol import TINY

log = logging.getLogger(__name__)


def default_scene(width: int, height: int, *overrides: str) -> Components:
    """The default run's components (the arm, its swing, the orthogonal rig) at ``width`` x ``height``, built as a
    run builds them."""
    return build(compose([f"rig.width={width}", f"rig.height={height}", *overrides]))


def bench_render(frames: int, width: int, height: int) -> dict[str, float]:
    scene = default_scene(width, height)
    arm, motion, rig = scene.model, scene.scene, scene.cameras
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
            **{f"{stage}_ms": statistics.median(values) for stage, values in stages.items()},
            "part2_b1_rms_pct": 100
            * float(np.sqrt(np.mean((estimates[:, 1, b1] - truths[:, 1, b1]) ** 2)) / np.ptp(truths[:, 1, b1])),
            "part2_r2_rms_deg": float(np.degrees(np.sqrt(np.mean((estimates[:, 1, r2] - truths[:, 1, r2]) ** 2)))),
        }
    return results


def bench_silhouettes(samples: int) -> dict[str, float]:
    """Sample-set build time, silhouette extraction, and scoring one observation against every sample at 80x60."""
    import tempfile

    from tracker.observe.silhouettes import SilhouetteCapture, resize_silhouette
    from tracker.sequence import background_frames
    from tracker.tbf.costs import silhouette_distance
    from tracker.tbf.pose_sets import arm_grid, remove_near_duplicates
    from tracker.tbf.sample_build import load_or_build

    scene = build(compose(["model=body_mesh"]))  # the body, side-on, with its capture setting
    body, rig, render = scene.model, scene.cameras, scene.settings.render
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
        nuisance, rng = render.nuisance(), np.random.default_rng(0)
        with render.renderer(320, 240) as renderer:
            capture = SilhouetteCapture.learn(background_frames(rig, renderer, 20, nuisance, rng))
            view = renderer.render(rig, body.surface_meshes(scene.scene.params(body, 10)))["main"]
        captured = [
            capture.step({"main": nuisance.apply(view.rgb, 10, rng)}, {"main": view.labels > 0}) for _ in range(20)
        ]
        observed = resize_silhouette(captured[-1].silhouettes["main"], 80, 60)
        assert len(stack.runs) == len(stack)  # the runs are found once per sample set, not timed
        results = {
            "samples": len(sample_set),
            "grid_poses": len(poses),
            "dedupe_s": dedupe_s,
            "build_s_per_1000": 1e3 * build_s / len(sample_set),
            "window_80x60": stack.window,
            "capture_ms": statistics.median(c.ms for c in captured),
            "capture_iou": captured[-1].iou["main"],
        }
        for cost in COSTS.names():
            times = []
            for _ in range(7):
                start = time.perf_counter()
                scores = ObservationScorer(cost, observed, stack.window).scores(stack)
                times.append(1e3 * (time.perf_counter() - start))
            reference = [
                silhouette_distance(cost, observed, np.pad(mask, _padding(stack.window, (80, 60))), stack.window)
                for mask in stack.images[:100] != 0
            ]
            results[f"{cost}_ms"] = statistics.median(times)
            relative = np.abs(scores[:100] - reference) / np.maximum(np.abs(reference), TINY)
            results[f"{cost}_max_relative_difference"] = float(relative.max())
    return results


def _padding(window, size):
    u0, v0, u1, v1 = window
    return ((v0, size[1] - v1), (u0, size[0] - u1))


def report_abis(results: dict[str, dict[str, float]], frames: int, width: int, height: int) -> None:
    log.info("AbIS estimation, paper-1 arm, 3 views at %dx%d, median over frames 1..%d:", width, height, frames - 1)
    for optimizer, figures in results.items():
        stages = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in figures.items() if k.endswith("_ms") and k != "estimate_ms")
        log.info(
            "  %s  %6.1f ms/frame  (%s)  part2 b1 RMS %.1f%% of range, r2 RMS %.2f deg",
            optimizer,
            figures["estimate_ms"],
            stages,
            figures["part2_b1_rms_pct"],
            figures["part2_r2_rms_deg"],
        )
    log.info("  sd / lm time ratio: %.2f", results["sd"]["estimate_ms"] / results["lm"]["estimate_ms"])


def _report_machine() -> None:
    log.info(
        "machine: %s, %d cores, %s; OpenGL platform %s",
        platform.processor() or platform.machine(),
        os.cpu_count(),
        platform.python_implementation() + " " + platform.python_version(),
        os.environ.get("PYOPENGL_PLATFORM"),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", choices=["render", "abis", "silhouettes", "tbf", "samples"])
    parser.add_argument("--poses", type=int, default=300, help="samples: poses rendered both ways")
    parser.add_argument("--build", action="store_true", help="samples: also build the whole set and tree cold")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--samples", type=int, default=10_000, help="pose samples (silhouettes)")
    parser.add_argument(
        "--experiment", default="tbf_table4c", help="tbf: the experiment preset (tbf_table4c, tbf_paper_scale)"
    )
    parser.add_argument("overrides", nargs="*", help="tbf: config overrides on top of the experiment")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT of every view")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    width, height = (int(v) for v in args.size.lower().split("x"))
    if args.target == "samples":
        from experiments.bench_samples import run

        run(args.poses, args.build, args.overrides)
        _report_machine()
        return
    if args.target == "tbf":
        from experiments.bench_tbf import run

        run(args.frames, args.experiment, args.overrides)
        _report_machine()
        return
    if args.target == "silhouettes":
        figures = bench_silhouettes(args.samples)
        _report_machine()
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
        return
    if args.target == "abis":
        results = bench_abis(args.frames, width, height)
        _report_machine()  # after the run: loading the renderer sets the OpenGL platform
        report_abis(results, args.frames, width, height)
        return
    result = bench_render(args.frames, width, height)
    _report_machine()
    log.info(
        "render, paper-1 arm, %d views at %dx%d, median of %d frames:", result["views"], width, height, args.frames
    )
    log.info("  pose + mesh        %7.2f ms/frame", result["pose_ms_per_frame"])
    log.info("  render (all views) %7.2f ms/frame", result["render_ms_per_frame"])
    log.info(
        "  render per view    %7.2f ms  = lit RGB + depth pass %.2f ms + label pass %.2f ms (ratio %.2f)",
        result["render_ms_per_view"],
        result["rgb_depth_pass_ms_per_view"],
        result["label_pass_ms_per_view"],
        result["rgb_depth_pass_ms_per_view"] / result["label_pass_ms_per_view"],
    )
    log.info(
        "  resident memory    %+7.1f MB over the %d frames after warm-up", result["resident_growth_mb"], args.frames
    )


if __name__ == "__main__":
    main()
