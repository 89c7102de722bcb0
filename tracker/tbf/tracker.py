"""The silhouette tree-based filtering tracker (paper 2): `tracker=tbf` with a cost and a motion model.

`start` builds (or loads from ``cache_dir``) the pose sample set of the standard body (``body_triangles``; the
rendered subject may differ in height and girth) seen by the camera and its tree, then sets the
initial prior around the configured initial pose (upright, arms down, facing ``initial_yaw_deg``); `step` takes
the frame's observed silhouette (background subtraction, done by the run's capture stage: ``frame.silhouettes``)
and runs `tracker.tbf.filter.TreeFilter`. The tracker never sees the truth after `start`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh, build_body
from tracker.motion.body_swing import arms_pose
from tracker.sequence import FrameInput
from tracker.tbf.distances import EmptySilhouette, SilhouetteCost
from tracker.tbf.filter import FilterResult, FilterSettings, TreeFilter
from tracker.tbf.motion import MotionModel
from tracker.tbf.pose_sets import arm_grid, clip_samples, varied
from tracker.tbf.samples import PoseSampleSet, load_or_build, remove_near_duplicates
from tracker.tbf.tree import PoseTree, load_or_build_tree

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class GridSpec:
    """The right-arm grid (`tracker.tbf.pose_sets.arm_grid`): ranges as ``[start, stop, step]`` degrees, stop
    included; lists of values for the left arm's swing and the body's yaw."""

    swing_deg: tuple[float, float, float] = (-60.0, 120.0, 6.0)
    abduction_deg: tuple[float, float, float] = (0.0, 40.0, 8.0)
    elbow_deg: tuple[float, float, float] = (0.0, 60.0, 30.0)
    left_swing_deg: tuple[float, ...] = (0.0, 20.0)
    yaw_deg: tuple[float, ...] = (-100.0, -90.0, -80.0)

    def poses(self, body: BodyMesh) -> np.ndarray:
        def values(start, stop, step):
            return np.arange(start, stop + step / 2, step)

        return np.concatenate([arm_grid(body, values(*self.swing_deg), values(*self.abduction_deg),
                                        values(*self.elbow_deg), self.left_swing_deg, yaw_deg=yaw)
                               for yaw in self.yaw_deg])  # fmt: skip


@dataclass(frozen=True)
class SampleSpec:
    grid: GridSpec | None = field(default_factory=GridSpec)
    clips: tuple[str, ...] = ()  # BVH files: every frame at clip_fps, facing clip_yaw_deg at its start
    clip_fps: float = 10.0
    clip_yaw_deg: float = -90.0
    clip_in_place: bool = True  # postures only: every clip pose's root moved over the origin (height kept)
    clip_turns_deg: tuple[float, ...] = (0.0,)  # procedural variation: each clip pose also turned by these
    clip_copies: int = 0  # ... and this many jittered copies of each (every joint, clip_jitter_deg per axis)
    clip_jitter_deg: float = 10.0
    seed: int = 0  # of the jitter
    min_joint_deg: float = 5.0  # near-duplicates (within this in every joint) are removed


@dataclass(frozen=True, eq=False)
class TbfResult:
    frame: int
    estimate: np.ndarray  # pose vector
    filter: FilterResult | None
    timings_ms: dict[str, float]
    failure: str | None = None


class TbfTracker:
    name = "tbf"

    def __init__(self, cost: SilhouetteCost, motion: MotionModel, samples: SampleSpec | None = None,
                 thresholds: Sequence[float] = (0.006, 0.002, 0.001), filter: FilterSettings | None = None,
                 initial_yaw_deg: float = -90.0, cache_dir: str = ".cache/tbf",
                 body_triangles: int = 4500) -> None:  # fmt: skip
        self.cost, self.motion, self.sample_spec = cost, motion, samples or SampleSpec()
        self.thresholds, self.filter_settings = tuple(thresholds), filter or FilterSettings()
        self.initial_yaw_deg, self.cache_dir = initial_yaw_deg, Path(cache_dir)
        self.body_triangles = body_triangles
        self.samples: PoseSampleSet | None = None
        self.tree: PoseTree | None = None

    @classmethod
    def from_config(cls, cost: SilhouetteCost, motion: MotionModel, samples: dict[str, Any],
                    filter: dict[str, Any], **values: Any) -> TbfTracker:  # fmt: skip
        grid = samples.get("grid")
        sources = {k: tuple(v) if isinstance(v, list) else v for k, v in samples.items() if k != "grid"}
        spec = SampleSpec(grid=None if grid is None else GridSpec(**{k: tuple(v) for k, v in grid.items()}), **sources)
        return cls(cost, motion, spec, filter=FilterSettings(**filter), **values)

    def start(self, model: BodyMesh, cameras: Sequence[Camera], truth: np.ndarray, rng: np.random.Generator) -> None:
        if not isinstance(model, BodyMesh) or len(cameras) != 1:
            raise ValueError("tracker=tbf tracks the body mesh from one camera")
        self.camera = cameras[0]
        start = time.perf_counter()
        # The tracker's own model is the standard body, whatever the subject's height and girth.
        self.body = build_body(triangles=self.body_triangles)
        poses = self._sample_poses(self.body)
        self.samples = load_or_build(self.body, self.camera, poses, self.cache_dir / "samples")
        self.tree = load_or_build_tree(self.samples, self.thresholds, self.cache_dir / "trees")
        self.filter = TreeFilter(self.samples, self.tree, self.cost, self.motion, self.filter_settings)
        self.filter.start(arms_pose(self.body, (0.0, 8.0, 0.0), (0.0, 8.0, 0.0), yaw_deg=self.initial_yaw_deg))
        self._estimate = np.asarray(self.samples.poses[0]).copy()
        self.setup_s = time.perf_counter() - start
        log.info("tbf: %d samples, tree %s nodes per level, likelihood sigma per level %s (%.1f s)",
                 len(self.samples), self.tree.node_counts, [f"{s:.3g}" for s in self.filter.level_sigmas],
                 self.setup_s)  # fmt: skip

    def describe(self) -> dict[str, Any]:
        """What `start` built: the number of pose samples and the tree's nodes per level."""
        if self.samples is None or self.tree is None:
            return {}
        return {"samples": len(self.samples), "tree_nodes": self.tree.node_counts}

    def _sample_poses(self, body: BodyMesh) -> np.ndarray:
        spec = self.sample_spec
        parts = []
        if spec.grid is not None:
            parts.append(spec.grid.poses(body))
        if spec.clips:
            clips = clip_samples(body, spec.clips, spec.clip_fps, spec.clip_yaw_deg)
            if spec.clip_in_place:
                clips[:, :2] = 0.0
            parts.append(varied(clips, spec.clip_turns_deg, spec.clip_copies, spec.clip_jitter_deg,
                                np.random.default_rng(spec.seed)))  # fmt: skip
        if not parts:
            raise ValueError("tracker.samples names no poses: set a grid or clips")
        poses = np.concatenate(parts)
        return poses[remove_near_duplicates(poses, spec.min_joint_deg)]

    def step(self, frame: FrameInput) -> TbfResult:
        silhouettes = frame.silhouettes
        if not silhouettes:
            raise ValueError("tracker=tbf needs the frame's silhouette (the capture stage of a body scene)")
        observed = silhouettes[self.camera.name]
        start = time.perf_counter()
        try:
            result = self.filter.step(observed)
        except EmptySilhouette as error:  # nobody in view: keep the last estimate, say why
            return TbfResult(frame.frame, self._estimate.copy(), None, {"filter": _ms(start)}, f"{error}")
        self._estimate = result.pose
        return TbfResult(frame.frame, result.pose, result, {**result.timings_ms, "filter": _ms(start)})

    def close(self) -> None:
        pass


def _ms(start: float) -> float:
    return 1e3 * (time.perf_counter() - start)
