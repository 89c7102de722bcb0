"""Benchmarks, apart from the tests: ``python -m experiments.bench render [--frames N] [--size WxH]``.

``render``: the paper-1 arm scene through the off-screen renderer, per frame and per view, split into the lit RGB
+ depth pass and the label pass, after a warm-up frame. Reports medians and the ratio of the two passes measured
in the same run.
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import statistics
import time
from pathlib import Path

from experiments.config import option_values
from tracker.geometry.rigs import orthogonal3
from tracker.models.dsq_arm import build_arm
from tracker.motion.arm_swing import ArmSwing
from tracker.render.offscreen import SceneRenderer

log = logging.getLogger(__name__)


def bench_render(frames: int, width: int, height: int) -> dict[str, float]:
    arm = build_arm(**option_values("model", "dsq_arm"), seed=0)
    motion = ArmSwing(**option_values("scene", "arm_swing"))
    rig = orthogonal3(**{**option_values("rig", "orthogonal3"), "width": width, "height": height})
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", choices=["render"])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT of every view")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    width, height = (int(v) for v in args.size.lower().split("x"))
    result = bench_render(args.frames, width, height)
    log.info("machine: %s, %d cores, %s; OpenGL platform %s", platform.processor() or platform.machine(),
             os.cpu_count(), platform.python_implementation() + " " + platform.python_version(),
             os.environ.get("PYOPENGL_PLATFORM"))
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
