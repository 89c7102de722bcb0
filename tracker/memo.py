"""Results of slow, deterministic computations kept on disk between processes (`memoized`), under a key of
everything that determines them: their inputs as the caller names them, and the core's own source code, so that
any change to the code makes a new key rather than a stale result. A file that cannot be read is computed again.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import zipfile
import zlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tracker.atomic import atomic_path

log = logging.getLogger(__name__)
CORE = Path(__file__).resolve().parent
# What reading a damaged ``.npz`` raises: a truncated or flipped file, a zip member whose CRC or deflate fails.
DAMAGED_NPZ = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)


@functools.cache
def source_digest() -> str:
    """A digest of every module of the core (`tracker/`), as it is on disk."""
    digest = hashlib.sha256()
    for path in sorted(CORE.rglob("*.py")):
        digest.update(str(path.relative_to(CORE)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def memo_key(inputs: Any) -> str:
    """The key of a computation of ``inputs`` (JSON-able: settings, names, digests of files) by the core as it is."""
    text = json.dumps(inputs, sort_keys=True, default=str)
    return hashlib.sha256((text + source_digest()).encode()).hexdigest()[:24]


def memoized(folder: str | Path, inputs: Any, compute: Callable[[], Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The arrays ``compute`` returns for ``inputs``: from ``folder`` when computed before, else computed and kept
    there (written atomically)."""
    path = Path(folder) / f"{memo_key(inputs)}.npz"
    try:
        with np.load(path, allow_pickle=False) as stored:
            return {name: stored[name] for name in stored.files}
    except FileNotFoundError:
        pass
    except DAMAGED_NPZ as error:
        log.warning("%s cannot be read (%s): computing it again", path, error)
    arrays = {name: np.asarray(value) for name, value in compute().items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temporary, open(temporary, "wb") as file:
        np.savez(file, **arrays)
    return arrays


def file_digest(path: str | Path) -> str:
    """A digest of a file's bytes (an input a key should name by content, such as a motion capture clip)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
