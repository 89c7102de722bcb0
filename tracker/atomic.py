"""Atomic file output: write to a temporary file beside the target, then rename over it.

A reader (or a resumed sweep) therefore sees either the complete previous file, the complete new file, or none.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class AtomicFile:
    """A temporary file beside ``target`` that becomes ``target`` on `commit` (or disappears on `discard`)."""

    def __init__(self, target: str | Path) -> None:
        self.target = Path(target)
        self.target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=f".{self.target.name}.", suffix=".tmp", dir=self.target.parent)
        os.close(handle)
        self.temporary = Path(temporary)
        os.chmod(self.temporary, 0o666 & ~_current_umask())  # mkstemp makes 0600; outputs are ordinary files

    def commit(self) -> None:
        os.replace(self.temporary, self.target)

    def discard(self) -> None:
        self.temporary.unlink(missing_ok=True)


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success rename it to ``target``, on error delete it."""
    file = AtomicFile(target)
    try:
        yield file.temporary
        file.commit()
    finally:
        file.discard()


def nearest_folder(path: str | Path) -> Path:
    """``path``, or its nearest ancestor that exists: where making it would start. A ValueError if that is a file
    (nothing can be made under it)."""
    absolute = Path(path).absolute()
    existing = next(parent for parent in (absolute, *absolute.parents) if parent.exists())
    if not existing.is_dir():
        raise ValueError(f"{existing} is a file, not a folder")
    return existing


def write_json(target: str | Path, data: Any) -> None:
    with atomic_path(target) as temporary:
        temporary.write_text(json.dumps(data, indent=2, sort_keys=True, allow_nan=False) + "\n")


def write_parquet(target: str | Path, frame) -> None:
    """Write a pandas DataFrame as parquet (zstd: a third smaller than the default snappy on a run's table, whose
    per-frame columns repeat on every part's row), atomically."""
    with atomic_path(target) as temporary:
        frame.to_parquet(temporary, index=False, compression="zstd")


@contextmanager
def exclusive(lock_path: str | Path) -> Iterator[None]:
    """Hold an exclusive lock on ``lock_path`` (created if missing) while the block runs: parallel jobs that
    would build the same cache entry take turns, and the later ones find it built."""
    import fcntl

    lock_path = Path(lock_path)
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
