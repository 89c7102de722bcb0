"""A step of ``make reproduce``: what it runs and writes, and its part of the report."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Section:
    console: str  # what the command prints
    markdown: str  # its part of report.md


@dataclass(frozen=True)
class Step:
    """``title``: what it makes; ``presets``: the ``experiment=`` presets it runs; ``outputs``: what it writes into
    ``reports/``; ``run(reports)``: runs it; ``scale``: ``default``, or ``paper`` for ``make reproduce SCALE=paper``
    only."""

    title: str
    presets: tuple[str, ...]
    outputs: tuple[str, ...]
    run: Callable[[Path], Section]
    scale: str = "default"
