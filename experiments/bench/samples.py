"""Benchmark of pose sample sets: ``python -m experiments.bench samples [--poses N] [--build] [--ray] [overrides]``.

On the poses of ``experiment=tbf_paper_scale`` (or the overrides' set), in one run:

- the label pass of ``--poses`` poses spread through the set: the per-part pass of `tracker.render.offscreen`
  (one pyrender node per body part, the full image: how sample sets were rendered before) against the batched
  `tracker.render.labels.LabelRenderer` (the poses of a batch in one draw call, the window only), ms per pose
  each after a warm-up, their ratio, and how many pixels differ;
- a sample set's label images of the same poses, all three resolutions and the part areas: before (one process:
  the per-part pass, and each image reduced by counting its blocks' labels with one ``bincount``) against now
  (`tracker.tbf.sample_build.build_set`: the batched pass, sorted-block reduction, in shards over every core),
  wall-clock ms per pose each and their ratio;
- with ``--build``: the whole set built cold into a fresh cache (sharded over the machine's cores), the tree built,
  and then the tracker started again on the cached set, each timed;
- with ``--ray`` (``make ray``; ``--ray-address`` a cluster's, else a local Ray): the set of the same poses built on
  Ray with 1 and 2 workers, and on joblib's processes with 2, and the ratio of Ray's 1 to 2 workers.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.bench.common import report_machine
from experiments.components import Components, build, compose
from tracker.render.labels import LabelRenderer
from tracker.render.mesh import SurfaceMesh
from tracker.render.offscreen import SceneRenderer
from tracker.tbf import sample_build, sample_store
from tracker.tbf.build_workers import BuildSettings
from tracker.tbf.sample_spec import sample_poses

log = logging.getLogger(__name__)


def per_part_meshes(body, pose: np.ndarray) -> list[SurfaceMesh]:
    """The label pass's meshes as sample sets were rendered before: one unlit mesh per body part."""
    vertices = body.posed_vertices(pose)
    return [
        SurfaceMesh(
            key=f"body_{name}", label=k + 1, vertices=vertices[used], faces=faces, normals=None, color=(255, 255, 255)
        )
        for k, (name, (used, faces)) in enumerate(zip(body.part_names, body.part_topology, strict=True))
        if len(faces)
    ]


def bench_rendering(poses: np.ndarray, body, camera, window, near: float, repeats: int = 3) -> dict[str, float]:
    u0, v0, u1, v1 = window
    old, new = [], []
    with SceneRenderer(camera.width, camera.height) as renderer:
        renderer.render_depth_labels([camera], per_part_meshes(body, poses[0]))  # warm-up
        for _ in range(repeats):
            start = time.perf_counter()
            before = [
                renderer.render_depth_labels([camera], per_part_meshes(body, pose))[camera.name].labels
                for pose in poses
            ]
            old.append(1e3 * (time.perf_counter() - start) / len(poses))
    with LabelRenderer(
        body.faces, body.face_parts + 1, len(body.rest_vertices), u1 - u0, v1 - v0, closed=body.closed
    ) as renderer:
        for _ in range(repeats + 1):  # the first: warm-up
            start = time.perf_counter()
            after = []
            for batch in np.array_split(poses, -(-len(poses) // sample_build.SKIN_BATCH)):
                pixels, depth = sample_build.project(camera, body.posed_vertices(batch))
                after.append(renderer.render(pixels - [u0, v0], depth, near))
            after = np.concatenate(after)
            new.append(1e3 * (time.perf_counter() - start) / len(poses))
    differing = (after != in_window(np.array(before), window)).sum(axis=(1, 2))
    return {
        "per_part_ms": statistics.median(old),
        "batched_ms": statistics.median(new[1:]),
        "differing_px_mean": float(differing.mean()),
        "differing_px_max": int(differing.max()),
    }


def in_window(images: np.ndarray, window) -> np.ndarray:
    """``(n, h, w)`` images cut to ``window`` (u0, v0, u1, v1), which may reach past the image: background there."""
    u0, v0, u1, v1 = window
    cut = np.zeros((len(images), v1 - v0, u1 - u0), dtype=images.dtype)
    rows = slice(max(v0, 0), min(v1, images.shape[1]))
    cols = slice(max(u0, 0), min(u1, images.shape[2]))
    cut[:, rows.start - v0 : rows.stop - v0, cols.start - u0 : cols.stop - u0] = images[:, rows, cols]
    return cut


def reduce_by_counting(labels: np.ndarray, factor: int, n_parts: int) -> np.ndarray:
    """How sample sets reduced a label image before: every block's labels counted with one ``bincount``."""
    height, width = labels.shape
    rows, cols = height // factor, width // factor
    block = (np.arange(height)[:, None] // factor) * cols + np.arange(width)[None, :] // factor
    counts = np.bincount((block * (n_parts + 1) + labels).ravel(), minlength=rows * cols * (n_parts + 1))
    counts = counts.reshape(rows, cols, n_parts + 1)
    covered = (factor * factor - counts[..., 0]) * 2 >= factor * factor
    return np.where(covered, np.argmax(counts[..., 1:], axis=2) + 1, 0).astype(np.uint8)


def bench_set_images(poses: np.ndarray, body, camera) -> dict[str, float]:
    """The set's images of ``poses`` now (sharded over every core) and before (one process), ms per pose."""
    with tempfile.TemporaryDirectory() as cache:
        start = time.perf_counter()
        folder = Path(cache) / "set"
        sample_build.build_set(body, camera, poses, folder, sample_build.RESOLUTIONS, BuildSettings())
        now_ms = 1e3 * (time.perf_counter() - start) / len(poses)
        meta = json.loads((folder / "meta.json").read_text())
        built = sample_store.load(folder, meta["key"], sample_build.RESOLUTIONS)
        coarse = built.silhouettes((80, 60)).masks()
        u0, v0, u1, v1 = built.windows[(320, 240)]
    start = time.perf_counter()
    before = {factor: [] for factor in (1, 2, 4)}
    with SceneRenderer(camera.width, camera.height) as renderer:
        for pose in poses:
            image = renderer.render_depth_labels([camera], per_part_meshes(body, pose))[camera.name].labels
            np.bincount(image.ravel(), minlength=len(body.part_names) + 1)  # the areas
            for factor in before:
                before[factor].append(reduce_by_counting(image[v0:v1, u0:u1], factor, len(body.part_names)))
    before_ms = 1e3 * (time.perf_counter() - start) / len(poses)
    differing = int((coarse != (np.array(before[4]) > 0)).sum())
    return {"before_ms": before_ms, "now_ms": now_ms, "differing_silhouette_px_80x60": differing}


def bench_build(overrides: list[str]) -> dict[str, float]:
    """The whole set, then its tree, built cold; then the tracker's start (the likelihood calibration, cached with
    the set), and a second start on everything cached."""
    from tracker.tbf.tree import load_or_build_tree

    with tempfile.TemporaryDirectory() as cache:
        run = build(compose([*overrides, f"tracker.cache_dir={cache}"]))
        settings, started = run.tracker.settings, time.perf_counter()
        poses, _ = sample_poses(run.tracker.settings.samples, run.model)
        times = {"poses_s": time.perf_counter() - started}
        started = time.perf_counter()
        samples = sample_build.load_or_build(run.model, run.cameras[0], poses, f"{cache}/samples", build=settings.build)
        times["samples_s"], started = time.perf_counter() - started, time.perf_counter()
        load_or_build_tree(samples, settings.thresholds)
        times["tree_s"] = time.perf_counter() - started
        for name in ("first", "second"):
            again = build(compose([*overrides, f"tracker.cache_dir={cache}"]))
            started = time.perf_counter()
            again.tracker.start(
                again.model, again.cameras, again.scene.params(again.model, 0), np.random.default_rng(0)
            )
            times[f"{name}_start_s"] = time.perf_counter() - started
        times["samples"] = len(samples)
    return times


def bench_ray_build(poses: np.ndarray, body, camera, address: str | None, shard_size: int = 64) -> dict[str, float]:
    """The set of ``poses`` built cold on Ray with 1 and then 2 workers (Ray started first, not timed), and on
    joblib's processes with 2 for reference: seconds each, and the ratio of 1 to 2 workers on Ray."""
    from tracker.tbf.build_workers import start_ray

    start_ray(address)
    seconds = {}
    for name, settings in (
        ("ray_1_worker_s", BuildSettings(jobs=1, backend="ray", shard_size=shard_size, ray_address=address)),
        ("ray_2_workers_s", BuildSettings(jobs=2, backend="ray", shard_size=shard_size, ray_address=address)),
        ("loky_2_workers_s", BuildSettings(jobs=2, backend="loky", shard_size=shard_size)),
    ):
        with tempfile.TemporaryDirectory() as cache:
            start = time.perf_counter()
            sample_build.build_set(body, camera, poses, Path(cache) / "set", sample_build.RESOLUTIONS, settings)
            seconds[name] = time.perf_counter() - start
    return {**seconds, "ray_1_over_2_workers": seconds["ray_1_worker_s"] / seconds["ray_2_workers_s"]}


def run(args: argparse.Namespace) -> dict:
    overrides = args.overrides or ["experiment=tbf_paper_scale"]
    composed = build(compose(overrides))
    poses, _ = sample_poses(composed.tracker.settings.samples, composed.model)
    rendering = _report_rendering(composed, poses, args.poses, overrides)
    chosen = poses[np.linspace(0, len(poses) - 1, 4 * args.poses).astype(int)]
    images = bench_set_images(chosen, composed.model, composed.cameras[0])
    log.info(
        "a set's images (3 resolutions, areas) of %d poses: before %.2f ms/pose (one process), now %.2f "
        "ms/pose (%s): %.1fx; silhouette pixels differing at 80x60 in all: %d",
        len(chosen),
        images["before_ms"],
        images["now_ms"],
        f"shards over {os.cpu_count()} cores",
        images["before_ms"] / images["now_ms"],
        images["differing_silhouette_px_80x60"],
    )
    build_times = _report_build(overrides, len(poses)) if args.build else {}
    on_ray = _report_ray(chosen, composed, args.ray_address) if args.ray else {}
    report_machine()
    return {"rendering": rendering, "set_images": images, "build": build_times, "ray": on_ray}


def _report_ray(poses: np.ndarray, composed: Components, address: str | None) -> dict:
    figures = bench_ray_build(poses, composed.model, composed.cameras[0], address)
    log.info(
        "the same %d poses' set built on Ray (%s): 1 worker %.1f s, 2 workers %.1f s: %.2fx; joblib's 2 processes "
        "%.1f s",
        len(poses),
        address or "a local Ray",
        figures["ray_1_worker_s"],
        figures["ray_2_workers_s"],
        figures["ray_1_over_2_workers"],
        figures["loky_2_workers_s"],
    )
    return figures


def _report_rendering(composed: Components, poses: np.ndarray, count: int, overrides: list[str]) -> dict:
    """Label rendering of ``count`` of the ``poses``, per part as before and batched."""
    chosen = poses[np.linspace(0, len(poses) - 1, count).astype(int)]
    camera = composed.cameras[0]
    layout = sample_build._layout(
        Path(tempfile.mkdtemp()),
        composed.model,
        camera,
        poses,
        [slice(0, len(poses))],
        4,
        BuildSettings(jobs=1),
    )
    figures = bench_rendering(chosen, composed.model, camera, layout.tile, layout.near)
    log.info(
        "label rendering, %d poses of %s (window %s of %dx%d):",
        count,
        " ".join(overrides),
        layout.window,
        camera.width,
        camera.height,
    )
    log.info(
        "  per-part pass (before) %.2f ms/pose, batched %.2f ms/pose: %.1fx; pixels differing per pose: "
        "mean %.2f, max %d",
        figures["per_part_ms"],
        figures["batched_ms"],
        figures["per_part_ms"] / figures["batched_ms"],
        figures["differing_px_mean"],
        figures["differing_px_max"],
    )
    return figures


def _report_build(overrides: list[str], poses: int) -> dict:
    log.info("building the set cold (%d poses), then starting on the cached set ...", poses)
    times = bench_build(overrides)
    log.info(
        "  poses %.1f s, sample set (%d, cold) %.1f s, tree %.1f s: %.1f s in all",
        times["poses_s"],
        times["samples"],
        times["samples_s"],
        times["tree_s"],
        times["poses_s"] + times["samples_s"] + times["tree_s"],
    )
    log.info(
        "  tracker start on them: %.1f s the first time (the likelihood calibration, then cached), %.1f s the second",
        times["first_start_s"],
        times["second_start_s"],
    )
    return times
