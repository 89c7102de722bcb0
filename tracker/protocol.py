"""What components and the experiment layer agree on: models, scenes, trackers, and what a tracker's step returns.

A tracker's `StepResult` is plain data that describes itself, so one writer of recordings, tables and figures
serves every tracker without knowing it: the estimate (in the model's own parameters), why a frame failed, and
named columns, series, points and images (see the class). A tracker's own result type may add fields of its own
(`tracker.abis.tracker.AbisResult`); the experiment layer reads only these.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.registry import TRACKERS
from tracker.render.mesh import SurfaceMesh
from tracker.render.offscreen import RenderedView


@dataclass(frozen=True, eq=False)
class FrameInput:
    """One frame of a synthetic sequence: what a tracker's `step` sees (the truth aside, which it must not use).

    truth: ``(n_parts, n_params)`` truth parameters; meshes: the truth surfaces that were rendered;
    views: rendered images keyed by camera name; visible_px: per view, ``(n_parts,)`` label pixel counts
    (part k's count at index k); timings_ms: stage name -> milliseconds; silhouettes: per view, the silhouette
    background subtraction extracted from the RGB (body scenes; what `tracker=tbf` observes).
    """

    frame: int
    truth: np.ndarray
    meshes: list[SurfaceMesh]
    views: dict[str, RenderedView]
    visible_px: dict[str, np.ndarray]
    timings_ms: dict[str, float] = field(default_factory=dict)
    silhouettes: dict[str, np.ndarray] = field(default_factory=dict)


class Model(Protocol):
    """An articulated object: parts (label k + 1 in label images is part k), its meshes for a parameter array."""

    name: ClassVar[str]  # its registered name

    @property
    def part_names(self) -> Sequence[str]: ...

    @property
    def part_colors(self) -> Sequence[tuple[int, int, int]]: ...

    def surface_meshes(self, params: np.ndarray) -> list[SurfaceMesh]: ...

    def parameter_series(self, params: np.ndarray) -> dict[str, float]:
        """Named scalars of a parameter array, for time series (e.g. ``forearm/b1``)."""
        ...


class Scene(Protocol):
    """The truth motion: the model's parameters at each frame."""

    def params(self, model: Model, frame: int) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class Points:
    """2-D points drawn over a view's image: ``uv`` ``(n, 2)`` pixels, each (optionally) in one of ``states``
    (``state`` ``(n,)`` indices into it, e.g. a feature's "tracked", "new", "discarded")."""

    uv: np.ndarray
    state: np.ndarray | None = None
    states: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False, kw_only=True)
class StepResult:
    """One frame's outcome.

    estimate: the model's parameters (the last estimate again when the frame failed); failure: why the frame could
    not be used (None: it could); timings_ms: the tracker's own stages. For the run's outputs:
    part_columns: ``frames.parquet`` columns with one value per part (``(n_parts,)`` arrays);
    frame_columns: columns with one value per frame (repeated on each part's row);
    series: time series of the recording (``metrics/<name>``);
    points, images: per view, named overlays over its image (``world/cameras/<view>/image/<name>``).
    """

    frame: int
    estimate: np.ndarray | None
    failure: str | None = None
    timings_ms: Mapping[str, float] = field(default_factory=dict)
    part_columns: Mapping[str, np.ndarray] = field(default_factory=dict)
    frame_columns: Mapping[str, Any] = field(default_factory=dict)
    series: Mapping[str, float] = field(default_factory=dict)
    points: Mapping[str, Mapping[str, Points]] = field(default_factory=dict)
    images: Mapping[str, Mapping[str, np.ndarray]] = field(default_factory=dict)


class Tracker(Protocol):
    """What a run drives: `start` once with the model, cameras and frame-0 truth (a tracker may use it only to
    initialise, as the papers' user-assisted alignment), `step` once per frame (images only), `close`."""

    name: ClassVar[str]

    def start(self, model: Model, cameras: Sequence[Camera], truth: np.ndarray, rng: np.random.Generator) -> None: ...

    def step(self, frame: FrameInput) -> StepResult | None: ...

    def describe(self) -> dict[str, Any]:
        """What `start` built, for the run's metrics (e.g. sample and tree sizes)."""
        return {}

    def summarize(self, table: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """The run's figures of the tracker's own columns (``table``: column -> ``(rows,)``, frame-major)."""
        return {}

    def close(self) -> None:
        """Free what `start` took (a renderer, say)."""


@TRACKERS.register("render_only")
@dataclass(frozen=True)
class RenderOnly(Tracker):
    """No estimation: the run renders and records the scene (what every tracker observes)."""

    name: ClassVar[str] = "render_only"

    def start(self, model: Model, cameras: Sequence[Camera], truth: np.ndarray, rng: np.random.Generator) -> None:
        pass

    def step(self, frame: FrameInput) -> None:
        return None
