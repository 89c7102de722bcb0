"""``python -m experiments.bench render [--frames N] [--size WxH]``: the paper-1 arm scene through the off-screen
renderer, per frame and per view, split into the lit RGB + depth pass and the label pass, after a warm-up frame:
medians, and the ratio of the two passes measured in the same run."""

from __future__ import annotations

import argparse
import logging
import statistics
import time

from experiments.bench.common import default_scene, report_machine, resident_mb
from tracker.render.offscreen import SceneRenderer

log = logging.getLogger(__name__)


def bench_render(frames: int, width: int, height: int) -> dict[str, float]:
    scene = default_scene(width, height)
    arm, motion, rig = scene.model, scene.scene, scene.cameras
    frame_ms, rgb_ms, label_ms, pose_ms = [], [], [], []
    with SceneRenderer(width, height) as renderer:
        renderer.render(rig, arm.surface_meshes(motion.params(arm, 0)))  # warm-up: shader compilation, uploads
        rss_start = resident_mb()
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
        rss_growth = resident_mb() - rss_start
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


def run(args: argparse.Namespace) -> dict:
    width, height = args.width, args.height
    result = bench_render(args.frames, width, height)
    report_machine()
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
    return result
