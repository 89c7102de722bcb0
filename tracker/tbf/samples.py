"""Pose sample sets (paper 2, 3.1): body poses with their silhouettes at the tree's resolutions, cached.

A sample set is built from pose vectors (`tracker.models.body_skeleton`), near-duplicates already removed
(`tracker.tbf.pose_sets.remove_near_duplicates`): every pose is rendered as a part-label image (0 background, part
k+1) at the finest of the tree's resolutions (`LEVEL_RESOLUTIONS`) and reduced to the others by blocks
(`reduce_labels`: a coarse pixel is in the silhouette when at least half of it is, as
`tracker.observe.silhouettes.resize_silhouette` does for observed silhouettes, and takes the part covering most
of it). Images are cropped to the window W: the rectangle holding every pose's projection (the bounding box of all
posed vertices, 1 px margin, widened to whole coarsest pixels), which is also the window of the silhouette
distances (`tracker.tbf.costs`). Each part's projected area A_j (eq 3) is counted at the finest resolution, and
each silhouette's runs of inside pixels (`tracker.tbf.scoring.SilhouetteRuns`) are kept at every resolution: all
that the tree and the filter read (the images themselves, tens of kB a sample, are not kept: their runs give them
back, `SilhouetteStack.masks`).

Several cameras see the same poses as several sets, one per view (`SampleViews`): the tree and the filter work on
the views together.

`tracker.tbf.sample_build.load_or_build` gives a set: from the cache (`tracker.tbf.sample_store`:
``<cache_dir>/<key>/``, the key a hash of everything that affects the content; loaded without reading every byte,
a stale or corrupt set rebuilt, never used) or built (batched rendering, in shards over processes, resumable).
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numba
import numpy as np

from tracker.atomic import exclusive
from tracker.geometry.cameras import Camera
from tracker.tbf import cache_manifest
from tracker.tbf.costs import Window
from tracker.tbf.scoring import SilhouetteRuns, SilhouetteStack


class Posable(Protocol):
    """A model whose pose samples can be rendered: the body (`tracker.models.body_mesh.BodyMesh`) or the DSQ arm
    (`tracker.tbf.arm_dictionary.ArmDictionary`). One mesh of every part's faces, each face labelled by its part."""

    faces: np.ndarray  # (F, 3)
    face_parts: np.ndarray  # (F,) part index
    rest_vertices: np.ndarray  # (V, 3): its length is the vertex count of every pose
    source_key: str  # names the model in caches
    closed: bool  # every edge borders two faces: back faces need not be drawn

    @property
    def part_names(self) -> tuple[str, ...]: ...

    def posed_vertices(self, poses: np.ndarray) -> np.ndarray: ...  # (n, V, 3) world points


LEVEL_RESOLUTIONS = ((80, 60), (160, 120), (320, 240))  # (width, height) of the tree's levels, top to bottom
RESOLUTIONS = LEVEL_RESOLUTIONS[::-1]  # as rendered: the finest first, the others reduced from it
FORMAT_VERSION = 4  # 4: silhouettes kept as runs only (3 kept the label images too)


@dataclass(frozen=True, eq=False)
class PoseSampleSet:
    poses: np.ndarray  # (n, POSE_SIZE)
    windows: dict[tuple[int, int], Window]  # (width, height) -> W in that resolution's pixels
    runs: dict[tuple[int, int], SilhouetteRuns]  # (width, height) -> every sample's runs of inside pixels in W
    areas: np.ndarray  # (n, parts) pixels of each part at the finest resolution
    key: str
    folder: Path | None = None  # where it is cached (derived values and trees are kept there too)

    def __len__(self) -> int:
        return len(self.poses)

    def silhouettes(self, resolution: tuple[int, int]) -> SilhouetteStack:
        """The silhouettes at ``resolution``, cropped to its window."""
        return SilhouetteStack(self.windows[resolution], self.runs[resolution])

    def occluded(self, area_threshold_px: float) -> np.ndarray:
        """``(n, parts)`` bool: eq 3's occlusion flags, part area below ``area_threshold_px``."""
        return occlusion_flags(self.areas, area_threshold_px)

    def derived(self, name: str, compute: Callable[[], float]) -> float:
        """A number derived from the set alone (e.g. a cost's calibration), computed once and kept in the set's
        manifest (`tracker.tbf.cache_manifest`)."""
        if self.folder is None:
            return compute()
        with exclusive(self.folder.parent / f".{self.key}.derived.lock"):  # parallel jobs compute it once
            known = cache_manifest.derived_values(self.folder)
            if name not in known:
                known[name] = float(compute())
                cache_manifest.add_derived(self.folder, name, known[name])
        return known[name]


@dataclass(frozen=True, eq=False)
class SampleViews:
    """The same poses seen by each camera of a rig: one `PoseSampleSet` per view, in the rig's order. A view's
    silhouette distance is its set's; the views' distances add up (the likelihood is the product over views).
    One view is exactly that view's set: same key, same derived values."""

    sets: tuple[PoseSampleSet, ...]

    def __post_init__(self) -> None:
        if not self.sets or any(len(s) != len(self.sets[0]) for s in self.sets):
            raise ValueError("the views of a sample set must hold the same poses, one set per view")

    @classmethod
    def of(cls, samples: PoseSampleSet | SampleViews | Sequence[PoseSampleSet]) -> SampleViews:
        if isinstance(samples, SampleViews):
            return samples
        return cls((samples,) if isinstance(samples, PoseSampleSet) else tuple(samples))

    def __len__(self) -> int:
        return len(self.sets[0])

    @property
    def poses(self) -> np.ndarray:
        return self.sets[0].poses

    @functools.cached_property
    def key(self) -> str:
        if len(self.sets) == 1:
            return self.sets[0].key
        return hashlib.sha256(" ".join(s.key for s in self.sets).encode()).hexdigest()[:20]

    @functools.cached_property
    def areas(self) -> np.ndarray:
        """``(n, parts)``: each part's area in the view where it is most visible (finest resolution)."""
        return functools.reduce(np.maximum, (s.areas for s in self.sets[1:]), self.sets[0].areas)

    def silhouettes(self, resolution: tuple[int, int]) -> tuple[SilhouetteStack, ...]:
        """Each view's silhouettes at ``resolution``."""
        return tuple(s.silhouettes(resolution) for s in self.sets)

    def occluded(self, area_threshold_px: float) -> np.ndarray:
        """``(n, parts)`` bool: eq 3's flags, a part occluded when below ``area_threshold_px`` in every view."""
        return occlusion_flags(self.areas, area_threshold_px)

    def derived(self, name: str, compute: Callable[[], float]) -> float:
        """A number derived from the views together, computed once and kept with the first view's set."""
        return self.sets[0].derived(name if len(self.sets) == 1 else f"{name} views={self.key}", compute)


def occlusion_flags(areas: np.ndarray, area_threshold_px: float) -> np.ndarray:
    """Eq 3: part j is occluded when its projected area A_j is below T_A."""
    if area_threshold_px < 0:
        raise ValueError(f"T_A={area_threshold_px}: must be >= 0")
    return np.asarray(areas) < area_threshold_px


def cache_key(body: Posable, camera: Camera, poses: np.ndarray, resolutions=RESOLUTIONS) -> str:
    digest = hashlib.sha256()
    for part in (
        f"v{FORMAT_VERSION}",
        body.source_key,
        repr(tuple(map(tuple, resolutions))),
        repr((camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy)),
    ):
        digest.update(part.encode())
    for array in (camera.rotation, camera.position, poses):
        digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    return digest.hexdigest()[:20]


def reduce_labels(labels: np.ndarray, factor: int, n_parts: int) -> np.ndarray:
    """Label images ``(..., h, w)`` ``factor`` times smaller: each block is background unless at least half of it is
    covered, else the part covering most of it (ties: the lower label). Sides must be multiples of ``factor``;
    ``n_parts`` bounds the labels (they must fit a byte)."""
    labels = np.asarray(labels)
    if factor == 1:
        return labels.copy()
    if n_parts > 255:
        raise ValueError(f"{n_parts} parts do not fit a byte")
    *lead, height, width = labels.shape
    if height % factor or width % factor:
        raise ValueError(f"label images of {width}x{height} are not whole blocks of {factor}x{factor}")
    images = np.ascontiguousarray(labels.reshape(-1, height, width), dtype=np.uint8)
    return _block_majorities(images, factor).reshape(*lead, height // factor, width // factor)


@numba.njit(cache=True, nogil=True)
def _block_majorities(labels: np.ndarray, factor: int) -> np.ndarray:
    """`reduce_labels` of ``(n, h, w)`` uint8 images, block by block: each label's pixels counted, then the lowest
    label of the most pixels where at least half the block is covered, else 0."""
    n, height, width = labels.shape
    size = factor * factor
    reduced = np.empty((n, height // factor, width // factor), np.uint8)
    counts = np.zeros(256, np.int64)
    for i in range(n):
        for row in range(height // factor):
            top = row * factor
            for column in range(width // factor):
                left = column * factor
                first, same = labels[i, top, left], True
                for v in range(top, top + factor):
                    for u in range(left, left + factor):
                        counts[labels[i, v, u]] += 1
                        same &= labels[i, v, u] == first
                if same:  # one label over the block (background most often): that label
                    reduced[i, row, column] = first
                    counts[first] = 0
                    continue
                best, most = 0, 0
                for v in range(top, top + factor):
                    for u in range(left, left + factor):
                        label = labels[i, v, u]
                        if label != 0 and (counts[label] > most or (counts[label] == most and label < best)):
                            best, most = label, counts[label]
                reduced[i, row, column] = best if (size - counts[0]) * 2 >= size else 0
                for v in range(top, top + factor):
                    for u in range(left, left + factor):
                        counts[labels[i, v, u]] = 0
    return reduced


def resolution_factor(finest: tuple[int, int], resolution: tuple[int, int]) -> int:
    factor = finest[0] // resolution[0]
    if factor * resolution[0] != finest[0] or factor * resolution[1] != finest[1]:
        raise ValueError(f"resolution {resolution} is not the finest {finest} divided by a whole number")
    return factor


def resolution_name(resolution: tuple[int, int]) -> str:
    return f"{resolution[0]}x{resolution[1]}"
