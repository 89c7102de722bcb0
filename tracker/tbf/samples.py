"""Pose sample sets (paper 2, 3.1): body poses with their part-label images at several resolutions, cached.

A sample set is built from pose vectors (`tracker.models.body_skeleton`), near-duplicates already removed
(`tracker.tbf.pose_sets.remove_near_duplicates`): every pose is rendered as a part-label image (0 background, part
k+1) at the finest of the tree's resolutions (`LEVEL_RESOLUTIONS`) and reduced to the others by blocks
(`reduce_labels`: a coarse pixel is in the silhouette when at least half of it is, as
`tracker.observe.silhouettes.resize_silhouette` does for observed silhouettes, and takes the part covering most
of it). Images are cropped to the window W: the rectangle holding every pose's projection (the bounding box of all
posed vertices, 1 px margin, widened to whole coarsest pixels), which is also the window of the silhouette
distances (`tracker.tbf.distances`). Each part's projected area A_j (eq 3) is counted at the finest resolution.

Cache: ``<cache_dir>/<key>/`` with ``meta.json`` and one ``.npy`` per array, the key a hash of everything that
affects the content (the body's source key, the camera, the poses, the resolutions, the format). Written into a
temporary folder and renamed when complete; on loading, the meta, shapes and SHA-256 of every array are checked,
and anything stale or corrupt is rebuilt (with a warning), never used.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from tracker.atomic import exclusive
from tracker.geometry.cameras import Camera, resized
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import PART_NAMES
from tracker.render.mesh import SurfaceMesh
from tracker.tbf.distances import SilhouetteStack, Window

log = logging.getLogger(__name__)

LEVEL_RESOLUTIONS = ((80, 60), (160, 120), (320, 240))  # (width, height) of the tree's levels, top to bottom
RESOLUTIONS = LEVEL_RESOLUTIONS[::-1]  # as rendered: the finest first, the others reduced from it
FORMAT_VERSION = 2


@dataclass(frozen=True, eq=False)
class PoseSampleSet:
    poses: np.ndarray  # (n, POSE_SIZE)
    labels: dict[tuple[int, int], np.ndarray]  # (width, height) -> (n, v1 - v0, u1 - u0) uint8, cropped to W
    windows: dict[tuple[int, int], Window]  # (width, height) -> W in that resolution's pixels
    areas: np.ndarray  # (n, parts) pixels of each part at the finest resolution
    key: str
    _stacks: dict[tuple[int, int], SilhouetteStack] = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return len(self.poses)

    def silhouettes(self, resolution: tuple[int, int]) -> SilhouetteStack:
        """The silhouettes at ``resolution`` (the label images themselves, not a copy), one stack per resolution
        so that its runs are found once."""
        if resolution not in self._stacks:
            self._stacks[resolution] = SilhouetteStack(self.labels[resolution], self.windows[resolution])
        return self._stacks[resolution]

    def occluded(self, area_threshold_px: float) -> np.ndarray:
        """``(n, parts)`` bool: eq 3's occlusion flags, part area below ``area_threshold_px``."""
        return occlusion_flags(self.areas, area_threshold_px)


def occlusion_flags(areas: np.ndarray, area_threshold_px: float) -> np.ndarray:
    """Eq 3: part j is occluded when its projected area A_j is below T_A."""
    if area_threshold_px < 0:
        raise ValueError(f"T_A={area_threshold_px}: must be >= 0")
    return np.asarray(areas) < area_threshold_px


def cache_key(body: BodyMesh, camera: Camera, poses: np.ndarray, resolutions=RESOLUTIONS) -> str:
    digest = hashlib.sha256()
    for part in (f"v{FORMAT_VERSION}", body.source_key, repr(tuple(map(tuple, resolutions))),
                 repr((camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy))):  # fmt: skip
        digest.update(part.encode())
    for array in (camera.rotation, camera.position, poses):
        digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    return digest.hexdigest()[:20]


def load_or_build(body: BodyMesh, camera: Camera, poses: np.ndarray, cache_dir: str | Path,
                  resolutions=RESOLUTIONS, progress: bool | None = None) -> PoseSampleSet:  # fmt: skip
    """The sample set of ``poses`` (already de-duplicated) seen by ``camera``: from the cache when it is intact,
    else rendered (with a progress bar) and cached."""
    poses = np.asarray(poses, dtype=np.float64)
    key = cache_key(body, camera, poses, resolutions)
    folder = Path(cache_dir) / key
    with exclusive(Path(cache_dir) / f".{key}.lock"):  # parallel jobs of a sweep build it once
        if folder.exists():
            try:
                return _load(folder, key, resolutions)
            except (OSError, ValueError, KeyError) as problem:
                log.warning("sample cache %s is unusable (%s): rebuilding it", folder, problem)
                shutil.rmtree(folder, ignore_errors=True)
        start = time.perf_counter()
        _build(body, camera, poses, folder, key, resolutions, progress)
        log.info("built %d samples in %.1f s into %s", len(poses), time.perf_counter() - start, folder)
        return _load(folder, key, resolutions)


def _load(folder: Path, key: str, resolutions) -> PoseSampleSet:
    meta = json.loads((folder / "meta.json").read_text())
    if meta.get("key") != key or meta.get("format") != FORMAT_VERSION:
        raise ValueError("its key or format does not match")
    arrays = {}
    for name, expected in meta["arrays"].items():
        path = folder / f"{name}.npy"
        if _sha256(path) != expected["sha256"]:
            raise ValueError(f"{path.name} does not match its checksum")
        arrays[name] = np.load(path, mmap_mode="r")
        if list(arrays[name].shape) != expected["shape"]:
            raise ValueError(f"{path.name} has shape {arrays[name].shape}, expected {expected['shape']}")
    names = [_labels_name(resolution) for resolution in resolutions]
    return PoseSampleSet(
        poses=np.asarray(arrays["poses"]),
        labels={tuple(res): arrays[name] for res, name in zip(resolutions, names, strict=True)},
        windows={tuple(res): tuple(meta["windows"][name]) for res, name in zip(resolutions, names, strict=True)},
        areas=np.asarray(arrays["areas"]),
        key=key,
    )


def _build(body: BodyMesh, camera: Camera, poses: np.ndarray, folder: Path, key: str, resolutions,
           progress: bool | None) -> None:  # fmt: skip
    from tracker.render.offscreen import SceneRenderer

    finest = resized(camera, *resolutions[0])
    factors = [_factor(resolutions[0], resolution) for resolution in resolutions]
    folder.parent.mkdir(parents=True, exist_ok=True)
    temporary = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=folder.parent))
    try:
        u0, v0, u1, v1 = _window(body, poses, finest, max(factors))
        windows = [(u0 // f, v0 // f, u1 // f, v1 // f) for f in factors]
        labels = [np.lib.format.open_memmap(temporary / f"{_labels_name(res)}.npy", mode="w+", dtype=np.uint8,
                                            shape=(len(poses), w[3] - w[1], w[2] - w[0]))
                  for res, w in zip(resolutions, windows, strict=True)]  # fmt: skip
        areas = np.zeros((len(poses), len(PART_NAMES)), np.int64)
        show = sys.stderr.isatty() if progress is None else progress
        with SceneRenderer(finest.width, finest.height) as renderer:
            for index in tqdm(range(len(poses)), desc="rendering pose samples", disable=not show, unit="pose"):
                image = renderer.render_depth_labels([finest], _label_meshes(body, poses[index]))[finest.name].labels
                areas[index] = np.bincount(image.ravel(), minlength=len(PART_NAMES) + 1)[1:]
                crop = image[v0:v1, u0:u1]
                for factor, out in zip(factors, labels, strict=True):
                    out[index] = reduce_labels(crop, factor, len(PART_NAMES))
        for out in labels:
            out.flush()
        del labels
        np.save(temporary / "poses.npy", poses)
        np.save(temporary / "areas.npy", areas)
        names = ["poses", "areas", *(_labels_name(res) for res in resolutions)]
        meta = {
            "key": key,
            "format": FORMAT_VERSION,
            "samples": len(poses),
            "parts": list(PART_NAMES),
            "windows": {_labels_name(res): list(map(int, w)) for res, w in zip(resolutions, windows, strict=True)},
            "arrays": {name: {"shape": list(np.load(temporary / f"{name}.npy", mmap_mode="r").shape),
                              "sha256": _sha256(temporary / f"{name}.npy")} for name in names},
        }  # fmt: skip
        (temporary / "meta.json").write_text(json.dumps(meta, indent=2))
        os.replace(temporary, folder)
    finally:
        shutil.rmtree(temporary, ignore_errors=True)


def reduce_labels(labels: np.ndarray, factor: int, n_parts: int) -> np.ndarray:
    """A label image ``factor`` times smaller: each block is background unless at least half of it is covered,
    else the part covering most of it (ties: the lower label). Sides must be multiples of ``factor``."""
    if factor == 1:
        return labels.copy()
    height, width = labels.shape
    rows, cols = height // factor, width // factor
    block = (np.arange(height)[:, None] // factor) * cols + np.arange(width)[None, :] // factor
    counts = np.bincount((block * (n_parts + 1) + labels).ravel(), minlength=rows * cols * (n_parts + 1))
    counts = counts.reshape(rows, cols, n_parts + 1)
    covered = (factor * factor - counts[..., 0]) * 2 >= factor * factor
    return np.where(covered, np.argmax(counts[..., 1:], axis=2) + 1, 0).astype(np.uint8)


def _factor(finest: tuple[int, int], resolution: tuple[int, int]) -> int:
    factor = finest[0] // resolution[0]
    if factor * resolution[0] != finest[0] or factor * resolution[1] != finest[1]:
        raise ValueError(f"resolution {resolution} is not the finest {finest} divided by a whole number")
    return factor


def _labels_name(resolution: tuple[int, int]) -> str:
    return f"labels_{resolution[0]}x{resolution[1]}"


def _label_meshes(body: BodyMesh, pose: np.ndarray) -> list[SurfaceMesh]:
    vertices = body.posed_vertices(pose)
    return [SurfaceMesh(key=f"body_{name}", label=k + 1, vertices=vertices[used], faces=faces, normals=None,
                        color=(255, 255, 255))
            for k, (name, (used, faces)) in enumerate(zip(PART_NAMES, body.part_topology, strict=True))
            if len(faces)]  # fmt: skip


def _window(body: BodyMesh, poses: np.ndarray, camera: Camera, align: int) -> Window:
    """The pixel rectangle holding every pose's projected vertices, 1 px margin, widened to multiples of
    ``align`` and kept inside the image."""
    low, high = np.full(2, np.inf), np.full(2, -np.inf)
    for pose in poses:
        uv, depth = camera.project(body.posed_vertices(pose))
        if not (depth > 0).all():
            raise ValueError("a pose sample reaches behind the camera")
        low, high = np.minimum(low, uv.min(axis=0)), np.maximum(high, uv.max(axis=0))
    u0, v0 = (np.maximum(np.floor(low).astype(int) - 1, 0) // align) * align
    u1, v1 = np.minimum(-(-(np.ceil(high).astype(int) + 2) // align) * align, [camera.width, camera.height])
    if u1 <= u0 or v1 <= v0:
        raise ValueError("the pose samples are not in the camera's view")
    return int(u0), int(v0), int(u1), int(v1)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()
