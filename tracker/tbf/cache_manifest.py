"""The manifest of a cached sample set, ``<set>/meta.json``: one file that vouches for everything in the set's folder.

- ``arrays``: each array's shape, size in bytes, sampled digest and SHA-256 (`tracker.tbf.sample_store` writes them
  last when the set is built: a folder without a manifest is incomplete);
- ``derived``: the numbers computed from the set later (eq 10's sigma calibration, the thresholds found for node
  shares), with one SHA-256 of them all;
- ``files``: the files added later (the pose trees), each with its size in bytes and SHA-256.

Each addition rewrites the manifest atomically under the set's manifest lock, so parallel jobs keep each other's
entries. What does not match its entry is damaged and made again by its owner: an array, the whole set; the
derived values, those values; a tree, that tree. A manifest that cannot be read condemns the whole set.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tracker.atomic import exclusive, write_json

log = logging.getLogger(__name__)
MANIFEST = "meta.json"


def full_digest(path: Path) -> str:
    """SHA-256 of every byte of the file."""
    digest = hashlib.sha256()
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()


def values_digest(values: dict[str, float]) -> str:
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()


def read(folder: Path) -> dict[str, Any]:
    """The set's manifest (an OSError or ValueError when it is missing or cannot be read)."""
    return json.loads((folder / MANIFEST).read_text())


def write(folder: Path, manifest: dict[str, Any]) -> None:
    write_json(folder / MANIFEST, manifest)


def update(folder: Path, change: Callable[[dict[str, Any]], None]) -> None:
    """Read the manifest, ``change`` it in place and write it back, atomically, one process at a time."""
    with exclusive(folder.parent / f".{folder.name}.manifest.lock"):
        manifest = read(folder)
        change(manifest)
        write(folder, manifest)


def _trusted_values(manifest: dict[str, Any]) -> dict[str, float] | None:
    """The manifest's derived values, or None when they do not match their digest."""
    section = manifest.get("derived", {})
    values = section.get("values", {})
    return values if not values or values_digest(values) == section.get("sha256") else None


def derived_values(folder: Path) -> dict[str, float]:
    """The derived values the manifest holds; none (all computed again, with a warning) when they do not match
    their digest: edited by hand, or written by another version."""
    values = _trusted_values(read(folder))
    if values is None:
        log.warning(
            "the derived values in %s are damaged (they do not match their digest): computing them again", folder
        )
        return {}
    return values


def add_derived(folder: Path, name: str, value: float) -> None:
    def change(manifest: dict[str, Any]) -> None:
        values = _trusted_values(manifest) or {}  # damaged ones are not carried over
        values[name] = value
        manifest["derived"] = {"values": values, "sha256": values_digest(values)}

    update(folder, change)


def checked_file(folder: Path, name: str) -> Path | None:
    """The file ``name`` of the set's folder when the manifest vouches for it (size and every byte); None when
    neither the file nor its entry exists; a ValueError saying what is wrong otherwise."""
    path, entry = folder / name, read(folder).get("files", {}).get(name)
    if entry is None:
        if path.exists():
            raise ValueError(f"{name} is not in the set's manifest (written by another version, or cut off)")
        return None
    if not path.exists():
        raise ValueError(f"{name} is missing")
    if path.stat().st_size != entry["bytes"] or full_digest(path) != entry["sha256"]:
        raise ValueError(f"{name} does not match its checksum")
    return path


def add_file(folder: Path, name: str) -> None:
    """Vouch for file ``name`` of the set's folder, as it is now."""
    path = folder / name
    entry = {"bytes": path.stat().st_size, "sha256": full_digest(path)}
    update(folder, lambda manifest: manifest.setdefault("files", {}).__setitem__(name, entry))
