"""What components and the experiment layer agree on: models, scenes, trackers, and what a tracker's step returns.

A tracker's `StepResult` is plain data that describes itself, so one writer of recordings, tables and figures
serves every tracker without knowing it: the estimate (in the model's own parameters), why a frame failed, and
named columns, series, points and images (see the class). A tracker's own result type may add fields of its own
(`tracker.abis.tracker.AbisResult`); the experiment layer reads only these.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.registry import TRACKERS, Fit
from tracker.render.mesh import SurfaceMesh
from tracker.render.offscreen import RenderedView


@dataclass(frozen=True, eq=False)
class Observation:
    """What a tracker's `step` sees of one frame: each view's RGB image and, in runs that capture them, the
    silhouettes background subtraction extracted from it. Never the truth.

    images: view -> ``(h, w, 3)`` uint8 RGB; silhouettes: view -> ``(h, w)`` bool (body scenes: what
    `tracker=tbf` observes).
    """

    frame: int
    images: Mapping[str, np.ndarray]
    silhouettes: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class RenderedFrame:
    """One frame of a synthetic sequence as the run knows it: the truth and what the cameras rendered of it. The
    tracker is given only its `observation`; the truth goes to the evaluation and the recording.

    truth: ``(n_parts, n_params)`` truth parameters; meshes: the truth surfaces that were rendered;
    views: rendered images keyed by camera name; visible_px: per view, ``(n_parts,)`` label pixel counts
    (part k's count at index k); in_view: per view, whether the camera sees the whole object (some label pixels,
    none on the image's border: `tracker.geometry.cameras.wholly_in_view`); timings_ms: stage name -> milliseconds.
    """

    frame: int
    truth: np.ndarray
    meshes: list[SurfaceMesh]
    views: dict[str, RenderedView]
    visible_px: dict[str, np.ndarray]
    in_view: dict[str, bool] = field(default_factory=dict)
    timings_ms: dict[str, float] = field(default_factory=dict)

    def observation(self, silhouettes: Mapping[str, np.ndarray] | None = None) -> Observation:
        """What a tracker sees of this frame: the views' RGB images (and the captured ``silhouettes``)."""
        return Observation(self.frame, {name: view.rgb for name, view in self.views.items()}, silhouettes or {})


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


@dataclass(frozen=True, eq=False)
class SampleDictionary:
    """The samples a tracker that searches a dictionary searched (tree filtering's pose samples), as the evaluation
    judges them against the truth after the run (`tracker.evaluation.dictionary`): the best any search over them
    could do, and the frames where the tracker's own cost could not tell. The tracker answers questions about its
    samples and its observations; it is never given the truth.

    poses: ``(n, k)`` the samples' pose vectors; model: the tracker's own model that they pose (the standard body it
    chose, or the arm); parameters: a pose vector -> that model's parameters (the estimate the sample makes);
    pose_of: model parameters -> the nearest pose vector of the samples' space (its coordinates, not a sample);
    steps: ``(k,)`` the motion model's step on each pose component (distances in the samples' space, in steps);
    prefers: ``(frame, a, b)`` -> whether that frame's observation is at least as likely under sample ``a`` as
    under sample ``b`` by the tracker's own cost (False for a frame it did not use); joint_positions: ``() ->
    model.joint_positions(poses)`` where the tracker keeps them between runs (None: the evaluation computes them).
    """

    poses: np.ndarray
    model: Any
    parameters: Callable[[np.ndarray], np.ndarray]
    pose_of: Callable[[np.ndarray], np.ndarray]
    steps: np.ndarray
    prefers: Callable[[int, int, int], bool]
    joint_positions: Callable[[], np.ndarray] | None = None


class Tracker(Protocol):
    """What a run drives: `start` once with the model, the cameras and the frame-0 pose (``initial``: the run gives
    frame 0's truth, standing in for the papers' user-assisted alignment), `step` once per frame with what the
    cameras saw (`Observation`: images only), `close`. After `start`, a tracker that searches a dictionary of
    samples describes it as ``dictionary`` (`SampleDictionary`), so that the evaluation can judge it."""

    name: ClassVar[str]
    dictionary: SampleDictionary | None = None

    def start(self, model: Model, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator) -> None: ...

    def step(self, observation: Observation) -> StepResult | None: ...

    def describe(self) -> dict[str, Any]:
        """What `start` built, for the run's metrics (e.g. sample and tree sizes)."""
        return {}

    def summarize(self, table: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """The run's figures of the tracker's own columns: ``table`` holds those its `StepResult`s named, with
        ``frame``, ``part`` and ``failure`` (column -> ``(rows,)``, one row per frame and part, frame-major)."""
        return {}

    def close(self) -> None:
        """Free what `start` took (a renderer, say)."""


@TRACKERS.register("render_only", models={"dsq_arm": Fit((1, 4)), "body_mesh": Fit((1, 4))})
@dataclass(frozen=True)
class RenderOnly(Tracker):
    """No estimation: the run renders and records the scene (what every tracker observes)."""

    name: ClassVar[str] = "render_only"
    estimates: ClassVar[bool] = False  # the recording leaves out the panels of the estimate's errors

    def start(self, model: Model, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator) -> None:
        pass

    def step(self, observation: Observation) -> None:
        return None
