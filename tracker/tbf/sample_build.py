"""Building a pose sample set (`tracker.tbf.samples`): in shards, over processes, resumable; and `load_or_build`.

1. Layout: every pose is posed and projected (in batches, `Posable.posed_vertices`: the body's or the arm's) to
   find the window W (all vertices, 1 px margin, aligned to whole coarsest pixels, kept inside the image) and the
   tile rendered (W widened to hold every vertex, so that no pose spills into a neighbour's tile where the window
   was cut by the image).
2. Shards of ``shard_size`` poses are rendered by `tracker.render.labels.LabelRenderer` (many poses per draw call)
   on joblib's processes (``backend="loky"``) or on Ray (``backend="ray"``), each shard's labels reduced to every
   resolution, its areas counted and its runs found; only the areas and the runs come back (the images stay in
   the worker). The parent writes each finished shard into the set's areas (a memory-mapped file in
   ``<cache_dir>/.<key>.building/``) and its runs beside them, and then marks it done.
3. When every shard is done, the runs are joined, ``meta.json`` written, and the folder renamed to ``<key>``.
A build that was killed leaves its ``.building`` folder: the next build of the same key renders only the shards
not marked done.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from tqdm import tqdm

from tracker.atomic import atomic_path, exclusive
from tracker.geometry.cameras import Camera, resized
from tracker.sequence import label_areas
from tracker.tbf import sample_store
from tracker.tbf.build_workers import BuildSettings, run_tasks
from tracker.tbf.costs import Window
from tracker.tbf.samples import (
    RESOLUTIONS,
    Posable,
    PoseSampleSet,
    cache_key,
    reduce_labels,
    resolution_factor,
    resolution_name,
)
from tracker.tbf.scoring import SilhouetteRuns, run_index_type
from tracker.tol import MIN_DEPTH_M

log = logging.getLogger(__name__)

SKIN_BATCH = 64  # poses skinned at once (larger batches leave the cache and get slower per pose)


@dataclass(frozen=True)
class Layout:
    """Where the samples fall in the finest image: the window W and the tile rendered (both ``(u0, v0, u1, v1)``
    pixels of the image; the tile holds W and every vertex, even outside the image), and a depth nearer than every
    vertex (metres: the label renderer's ``near``, one for the whole set so that a pose's image never depends on
    its shard)."""

    window: Window
    tile: Window
    near: float


def load_or_build(
    body: Posable,
    camera: Camera,
    poses: np.ndarray,
    cache_dir: str | Path,
    resolutions=RESOLUTIONS,
    progress: bool | None = None,
    build: BuildSettings | None = None,
    check: Literal["sampled", "full"] = "sampled",
) -> PoseSampleSet:
    """The sample set of ``poses`` (already de-duplicated) seen by ``camera``: from the cache when it is intact
    (``check``: how much of it is read to tell, `tracker.tbf.sample_store`), else built (``build``) and cached."""
    poses = np.asarray(poses, dtype=np.float64)
    key = cache_key(body, camera, poses, resolutions)
    folder = Path(cache_dir) / key
    with exclusive(Path(cache_dir) / f".{key}.lock"):  # parallel jobs of a sweep build it once
        if folder.exists():
            try:
                return sample_store.load(folder, key, resolutions, check)
            except (OSError, ValueError, KeyError) as problem:
                log.warning("sample cache %s is damaged (%s): rebuilding it", folder, problem)
                shutil.rmtree(folder, ignore_errors=True)
        start = time.perf_counter()
        build_set(body, camera, poses, folder, resolutions, build or BuildSettings(), progress)
        log.info("built %d samples in %.1f s into %s", len(poses), time.perf_counter() - start, folder)
        return sample_store.load(folder, key, resolutions, check)


def build_set(
    body: Posable,
    camera: Camera,
    poses: np.ndarray,
    folder: Path,
    resolutions,
    settings: BuildSettings,
    progress: bool | None = None,
) -> None:
    """Render ``poses`` into the set at ``folder`` (its name: the set's key), resuming a killed build."""
    building = folder.parent / f".{folder.name}.building"
    building.mkdir(parents=True, exist_ok=True)
    finest = resized(camera, *resolutions[0])
    factors = [resolution_factor(resolutions[0], resolution) for resolution in resolutions]
    shards = [
        slice(first, min(first + settings.shard_size, len(poses)))
        for first in range(0, len(poses), settings.shard_size)
    ]
    layout = _layout(building, body, finest, poses, shards, max(factors), settings)
    windows = {
        res: tuple(side // factor for side in layout.window) for res, factor in zip(resolutions, factors, strict=True)
    }
    areas = _array(building, "areas", (len(poses), len(body.part_names)), np.int64)
    todo = [k for k in range(len(shards)) if not (building / f"shard{k}.done").exists()]
    if len(todo) < len(shards):
        log.info("resuming the build of %s: %d of %d shards done", folder.name, len(shards) - len(todo), len(shards))
    show = sys.stderr.isatty() if progress is None else progress
    tasks = ((render_shard, (body, finest, poses[shards[k]], layout, factors), {"shard": k}) for k in todo)
    for shard in tqdm(
        run_tasks(tasks, settings), total=len(todo), desc="rendering pose samples", disable=not show, unit="shard"
    ):
        _store_shard(building, shard, shards[shard["shard"]], areas)
    _finish(building, folder, poses, shards, resolutions, windows)


def _store_shard(building: Path, shard: dict, rows: slice, areas: np.ndarray) -> None:
    """A rendered shard's ``areas`` into the set's memory-mapped array at ``rows``, its runs beside it, and marked
    done: a killed build resumes after it."""
    areas[rows] = shard["areas"]
    runs = shard["runs"]
    with atomic_path(building / f"shard{shard['shard']}.runs.npz") as temporary, open(temporary, "wb") as file:
        np.savez(
            file,
            **{f"{resolution_name(r)}_{part}": runs[r][part] for r in runs for part in ("starts", "ends", "counts")},
        )
    areas.flush()
    (building / f"shard{shard['shard']}.done").touch()


def render_shard(
    body: Posable, camera: Camera, poses: np.ndarray, layout: Layout, factors: list[int], shard: int = 0
) -> dict:
    """One shard's part areas at the finest resolution and its silhouettes' runs of inside pixels at every
    resolution (`shard_labels`), what the set keeps of it."""
    labels, areas = shard_labels(body, camera, poses, layout, factors)
    runs = {}
    for resolution, images in labels.items():
        found = SilhouetteRuns.from_masks(images)
        runs[resolution] = {"starts": found.starts, "ends": found.ends, "counts": np.diff(found.ptr)}
    return {"shard": shard, "areas": areas, "runs": runs}


def shard_labels(
    body: Posable, camera: Camera, poses: np.ndarray, layout: Layout, factors: list[int]
) -> tuple[dict[tuple[int, int], np.ndarray], np.ndarray]:
    """``poses``' part-label images cropped to the window at every resolution (finest first, by ``factors``; 0
    background, part k + 1), and each part's area at the finest."""
    t0, s0, t1, s1 = layout.tile
    u0, v0, u1, v1 = layout.window
    renderer = _renderer(body, t1 - t0, s1 - s0)
    crops, areas = [], []
    for first in range(0, len(poses), SKIN_BATCH):
        pixels, depth = project(camera, body.posed_vertices(poses[first : first + SKIN_BATCH]))
        images = renderer.render(pixels - [t0, s0], depth, layout.near)[:, v0 - s0 : v1 - s0, u0 - t0 : u1 - t0]
        crops.append(images)
        areas.append(label_areas(images, len(body.part_names)))
    finest = np.concatenate(crops)
    labels = {
        (camera.width // factor, camera.height // factor): reduce_labels(finest, factor, len(body.part_names))
        for factor in factors
    }
    return labels, np.concatenate(areas)


def project(camera: Camera, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 3)`` world points -> their ``(..., 2)`` pixels and ``(...)`` camera depths (`Camera.project`)."""
    uv, depth = camera.project(vertices.reshape(-1, 3))
    return uv.reshape(*vertices.shape[:-1], 2), depth.reshape(vertices.shape[:-1])


def shard_bounds(body: Posable, camera: Camera, poses: np.ndarray) -> list[float]:
    """The projected vertices' bounding box ``[u_min, v_min, u_max, v_max]`` and their smallest depth."""
    low, high, nearest = np.full(2, np.inf), np.full(2, -np.inf), np.inf
    for first in range(0, len(poses), SKIN_BATCH):
        pixels, depth = project(camera, body.posed_vertices(poses[first : first + SKIN_BATCH]))
        nearest = min(nearest, float(depth.min()))
        if nearest > MIN_DEPTH_M:
            low, high = np.minimum(low, pixels.reshape(-1, 2).min(0)), np.maximum(high, pixels.reshape(-1, 2).max(0))
    return [*map(float, low), *map(float, high), nearest]


def _layout(
    building: Path,
    body: Posable,
    camera: Camera,
    poses: np.ndarray,
    shards: list[slice],
    align: int,
    settings: BuildSettings,
) -> Layout:
    """The build's layout: computed once (in shards) and kept in the building folder, so a resumed build keeps
    the window its finished shards were cropped to."""
    path = building / "layout.json"
    if path.exists():
        saved = json.loads(path.read_text())
        return Layout(tuple(saved["window"]), tuple(saved["tile"]), saved["near"])
    bounds = np.array(list(run_tasks(((shard_bounds, (body, camera, poses[rows]), {}) for rows in shards), settings)))
    if bounds[:, 4].min() <= MIN_DEPTH_M:
        raise ValueError("a pose sample reaches behind the camera")
    low, high = bounds[:, :2].min(axis=0), bounds[:, 2:4].max(axis=0)
    u0, v0 = (np.maximum(np.floor(low).astype(int) - 1, 0) // align) * align
    u1, v1 = np.minimum(-(-(np.ceil(high).astype(int) + 2) // align) * align, [camera.width, camera.height])
    if u1 <= u0 or v1 <= v0:
        raise ValueError("the pose samples are not in the camera's view")
    reach = np.floor(low).astype(int) - 1, np.ceil(high).astype(int) + 2
    tile = (min(u0, reach[0][0]), min(v0, reach[0][1]), max(u1, reach[1][0]), max(v1, reach[1][1]))
    layout = Layout(tuple(map(int, (u0, v0, u1, v1))), tuple(map(int, tile)), 0.5 * float(bounds[:, 4].min()))
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps({"window": layout.window, "tile": layout.tile, "near": layout.near}))
    return layout


def _array(building: Path, name: str, shape: tuple[int, ...], dtype) -> np.memmap:
    """An array of the set in the building folder: made now, or reopened when resuming."""
    path = building / f"{name}.npy"
    if path.exists():
        array = np.load(path, mmap_mode="r+")
        if array.shape == shape and array.dtype == dtype:
            return array
    return np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)


def _finish(building: Path, folder: Path, poses: np.ndarray, shards: list[slice], resolutions, windows: dict) -> None:
    """Join the shards' runs, write the poses and ``meta.json``, and make the set visible under its key."""
    for res in resolutions:
        name = resolution_name(res)
        parts = [np.load(building / f"shard{k}.runs.npz") for k in range(len(shards))]
        counts = np.concatenate([part[f"{name}_counts"] for part in parts])
        starts, ends = (np.concatenate([part[f"{name}_{side}"] for part in parts]) for side in ("starts", "ends"))
        index = run_index_type(int(ends.max(initial=0)))  # as the shards made them (one resumed from before: int32)
        np.save(building / f"{sample_store.runs_name(res, 'starts')}.npy", starts.astype(index))
        np.save(building / f"{sample_store.runs_name(res, 'ends')}.npy", ends.astype(index))
        np.save(building / f"{sample_store.runs_name(res, 'ptr')}.npy", np.r_[0, np.cumsum(counts)].astype(np.int64))
    np.save(building / "poses.npy", poses)
    sample_store.write_meta(building, folder.name, resolutions, windows)
    for path in building.glob("shard*"):
        path.unlink()
    (building / "layout.json").unlink()
    os.replace(building, folder)


_RENDERERS: dict[tuple, object] = {}


def _renderer(body: Posable, width: int, height: int):
    """A label renderer of ``body``'s topology for tiles of ``width`` x ``height``, one per process and kind."""
    from tracker.render.labels import LabelRenderer

    key = (body.source_key, width, height)
    if key not in _RENDERERS:
        _RENDERERS[key] = LabelRenderer(
            body.faces, body.face_parts + 1, len(body.rest_vertices), width, height, closed=body.closed
        )
    return _RENDERERS[key]
