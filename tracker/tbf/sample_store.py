"""A sample set on disk: ``<cache_dir>/<key>/`` with its manifest ``meta.json`` and one ``.npy`` per array.

Arrays: ``poses``, ``areas``, and per resolution the silhouettes' runs of inside pixels
(``runs_<w>x<h>_{starts,ends,ptr}``, what the tree and the filter read; `tracker.tbf.samples`). The manifest
(`tracker.tbf.cache_manifest`, which also vouches for what is added later: derived values, trees) holds the key,
the format, the windows and, per array, its shape, its size in bytes, a SHA-256 of all of it and a sampled digest
(`sampled_digest`: its first and last 64 KiB and 62 blocks spread evenly between). Loading checks the key, the
format, every size and shape and every sampled digest (``check="sampled"``: a truncated, swapped or
damaged-at-the-ends file is caught in milliseconds), or every byte (``check="full"``: the SHA-256 of each array).
Anything that fails is reported with a `ValueError` and rebuilt by `tracker.tbf.sample_build.load_or_build`, never
used.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Literal

import numpy as np

from tracker.tbf import cache_manifest
from tracker.tbf.samples import FORMAT_VERSION, PoseSampleSet, resolution_name
from tracker.tbf.scoring import SilhouetteRuns

BLOCK = 1 << 16
SAMPLED_BLOCKS = 64
RUN_PARTS = ("starts", "ends", "ptr")


def runs_name(resolution: tuple[int, int], part: str) -> str:
    return f"runs_{resolution_name(resolution)}_{part}"


def array_names(resolutions) -> list[str]:
    names = ["poses", "areas"]
    for resolution in resolutions:
        names += [runs_name(resolution, part) for part in RUN_PARTS]
    return names


def sampled_digest(path: Path) -> str:
    """SHA-256 of the file's size and of `SAMPLED_BLOCKS` blocks of `BLOCK` bytes: the first, the last, and the
    others spread evenly between (the whole file when it is smaller)."""
    size = path.stat().st_size
    digest = hashlib.sha256(str(size).encode())
    with path.open("rb") as file:
        if size <= SAMPLED_BLOCKS * BLOCK:
            digest.update(file.read())
        else:
            for offset in np.linspace(0, size - BLOCK, SAMPLED_BLOCKS).astype(np.int64):
                file.seek(int(offset))
                digest.update(file.read(BLOCK))
    return digest.hexdigest()


def write_meta(folder: Path, key: str, resolutions, windows: dict[tuple[int, int], tuple[int, ...]]) -> None:
    """The manifest of the arrays already in ``folder`` (written last: a folder without it is incomplete)."""
    arrays = {}
    for name in array_names(resolutions):
        path = folder / f"{name}.npy"
        arrays[name] = {
            "shape": list(np.load(path, mmap_mode="r").shape),
            "bytes": path.stat().st_size,
            "sampled": sampled_digest(path),
            "sha256": cache_manifest.full_digest(path),
        }
    meta = {
        "key": key,
        "format": FORMAT_VERSION,
        "samples": arrays["poses"]["shape"][0],
        "windows": {resolution_name(r): list(map(int, windows[r])) for r in resolutions},
        "arrays": arrays,
    }
    cache_manifest.write(folder, meta)


def load(folder: Path, key: str, resolutions, check: Literal["sampled", "full"] = "sampled") -> PoseSampleSet:
    meta = cache_manifest.read(folder)
    if meta.get("key") != key or meta.get("format") != FORMAT_VERSION:
        raise ValueError("its key or format does not match")
    arrays = {}
    for name in array_names(resolutions):
        expected, path = meta["arrays"][name], folder / f"{name}.npy"
        if path.stat().st_size != expected["bytes"]:
            raise ValueError(f"{path.name} has {path.stat().st_size} bytes, expected {expected['bytes']}")
        found = cache_manifest.full_digest(path) if check == "full" else sampled_digest(path)
        if found != expected["sha256" if check == "full" else "sampled"]:
            raise ValueError(f"{path.name} does not match its checksum")
        arrays[name] = np.load(path, mmap_mode="r")
        if list(arrays[name].shape) != expected["shape"]:
            raise ValueError(f"{path.name} has shape {arrays[name].shape}, expected {expected['shape']}")
    runs = {
        tuple(resolution): SilhouetteRuns(*(np.asarray(arrays[runs_name(resolution, part)]) for part in RUN_PARTS))
        for resolution in resolutions
    }
    return PoseSampleSet(
        poses=np.asarray(arrays["poses"]),
        windows={tuple(r): tuple(meta["windows"][resolution_name(r)]) for r in resolutions},
        runs=runs,
        areas=np.asarray(arrays["areas"]),
        key=key,
        folder=folder,
    )
