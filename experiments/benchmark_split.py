"""The real-motion benchmark's split (``conf/benchmark/<name>.yaml``): which clips build the dictionaries, which
may tune a setting (validation), which are tracked for the table (test), and the rows it runs. `load_split` reads
and checks it before anything runs: a key it does not know, a value out of range, an entry that names no clip or a
clip in two lists stops it with one line (`SplitError`).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated

import numpy as np
import yaml

from experiments.schemas import CONFIG_DIR
from tracker.data import data_dir, data_files, data_path
from tracker.models.body_shapes import MacroShape, draw_subject
from tracker.ranges import Positive, Range, Seed
from tracker.settings import check_values, from_plain, settings_of
from tracker.tbf.sample_spec import TrueRate, true_rate

SPLITS_DIR = CONFIG_DIR / "benchmark"
LISTS = ("dictionary", "validation", "test")


class SplitError(ValueError):
    """A split that cannot run: its message is the one line the user sees."""


@dataclass(frozen=True)
class Row:
    """One tracker setup of the table: what it says, the ``experiment=`` preset it runs and overrides of its own."""

    label: str
    experiment: str
    overrides: tuple[str, ...] = ()


@dataclass(frozen=True)
class Split:
    dictionary: tuple[str, ...]
    validation: tuple[str, ...] = ()
    test: tuple[str, ...] = ()
    true_fps: tuple[TrueRate, ...] = ()
    fps: Positive = 15.0
    max_frames: Annotated[int, Range(1, 1_000_000)] | None = None
    subject_seed: Seed = 0
    rows: dict[str, Row] = field(default_factory=dict)

    def clips(self, name: str) -> list[str]:
        """The data paths of one list (`LISTS`), wildcards expanded, in order."""
        return [clip for pattern in getattr(self, name) for clip in expand(pattern)]

    def true_rate(self, clip: str) -> float | None:
        """The capture rate of ``clip`` when its header's is wrong (`true_fps`), else None."""
        return true_rate(clip, self.true_fps)

    def subject(self, clip: str) -> MacroShape:
        """The subject of ``clip``: drawn from the standard bodies' range by the seed and the clip's name, so a
        clip keeps its subject whatever other clips the split holds."""
        return draw_subject(np.random.default_rng([self.subject_seed, zlib.crc32(clip.encode())]))


def expand(pattern: str) -> list[str]:
    """The existing clips a data path names, as data paths (relative to the data directory where they are in it)."""
    found = []
    for path in data_files(pattern):
        if path.exists():
            inside = path.resolve().is_relative_to(data_dir().resolve())
            found.append(str(path.resolve().relative_to(data_dir().resolve())) if inside else str(path))
    return found


def load_split(path: str | Path) -> Split:
    """The split at ``path``, or the one named ``path`` in ``conf/benchmark/``, checked (`SplitError`)."""
    path = Path(path)
    if not path.exists() and not path.suffix:
        path = SPLITS_DIR / f"{path}.yaml"
    if not path.exists():
        known = ", ".join(sorted(p.stem for p in SPLITS_DIR.glob("*.yaml")))
        raise SplitError(f"benchmark split {path}: no such file (the project's: {known})")
    plain = yaml.safe_load(path.read_text()) or {}
    allowed = [setting.name for setting in settings_of(Split)]
    unknown = [key for key in plain if key not in allowed]
    if unknown:
        raise SplitError(f"{path}: unknown key {unknown[0]}: allowed {', '.join(allowed)}")
    try:
        check_values(settings_of(Split), {key: value for key, value in plain.items() if key != "rows"})
        rows = {folder: Row(**row) for folder, row in (plain.get("rows") or {}).items()}
    except (TypeError, ValueError) as error:
        raise SplitError(f"{path}: {error}") from None
    split = replace(from_plain(Split, {key: value for key, value in plain.items() if key != "rows"}), rows=rows)
    check_clips(split, path)
    return split


def check_clips(split: Split, path: Path) -> None:
    """Every entry names a clip, and no clip is in two lists (a test clip in a dictionary least of all)."""
    if not split.dictionary:
        raise SplitError(f"{path}: dictionary=[] is not allowed: the rows' dictionaries are built from its clips")
    owner: dict[Path, str] = {}
    for name in LISTS:
        for index, pattern in enumerate(getattr(split, name)):
            clips = expand(pattern)
            if not clips:
                raise SplitError(f"{path}: {name}[{index}]={pattern} names no clip in the data directory {data_dir()}")
            for clip in clips:
                where = data_path(clip).resolve()
                if where in owner:
                    raise SplitError(f"{path}: {clip} is in both {owner[where]} and {name}: a clip is in one list only")
                owner[where] = f"{name}[{index}]={pattern}"
