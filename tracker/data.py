"""Third-party data read in place, never copied into the repository: the data directory.

The motion capture clips (CMU, with their terms) live in the data directory beside the project on every machine:
``../shared/data`` relative to the project's folder, or wherever the environment variable
``ARTICULATED_DATA_DIR`` says (for other checkouts). A relative data path (``mocap/143_33.bvh``) names a file there,
unless it names an existing file relative to the working directory; an absolute path is used as it is. Where
several files are wanted (a dictionary's clips), a path may hold wildcards (`data_files`).
"""

from __future__ import annotations

import glob
import os
from pathlib import Path

DATA_DIR_VARIABLE = "ARTICULATED_DATA_DIR"
DEFAULT_DATA_DIR = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


def data_dir() -> Path:
    """The data directory: ``$ARTICULATED_DATA_DIR``, or ``../shared/data`` beside the project."""
    return Path(os.environ.get(DATA_DIR_VARIABLE) or DEFAULT_DATA_DIR)


def data_path(path: str | Path) -> Path:
    """The file a data path names (see the module docstring); it need not exist."""
    path = Path(path)
    if path.is_absolute() or path.exists():
        return path
    return data_dir() / path


def data_files(pattern: str) -> list[Path]:
    """The files a data path names, which may hold shell wildcards (``mocap_daz/*.bvh``): sorted; a path without
    wildcards names one file (it need not exist)."""
    if not glob.has_magic(pattern):
        return [data_path(pattern)]
    return [Path(name) for name in sorted(glob.glob(str(data_path(pattern))))]
