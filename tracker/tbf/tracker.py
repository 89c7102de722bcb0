"""The silhouette tree-based filtering tracker (paper 2): `tracker=tbf` with a cost and a motion model.

`start` picks the tracker's own body (``body``: MakeHuman's base mesh, or the standard body nearest the subject's
stature and chest girth, measured on the subject as a tailor would), builds (or loads from ``cache_dir``) the pose
sample set of that body seen by each camera of the rig and their tree (``thresholds``, or ``node_shares``), then
sets the initial prior around the configured initial pose (upright, arms down, facing ``initial_yaw_deg``); `step`
takes the frame's observed silhouettes (background subtraction, done by the run's capture stage:
``observation.silhouettes``), moves each onto its view's samples' feet or places the person on the floor when ``align``
says so (`tracker.tbf.alignment`; from several views, where their centroid rays cross), and runs
`tracker.tbf.filter.TreeFilter` on the views together (their likelihoods multiplied). The tracker never sees the
truth: measuring the subject's size at `start` stands for the paper's measuring of the person. It describes its
samples as ``dictionary`` (`tracker.protocol.SampleDictionary`), by which the evaluation measures after the run
what the samples allow and where the silhouette could not tell (`tracker.evaluation.dictionary`). The DSQ arm
(``model=dsq_arm``) is tracked the same way over a grid of its parameters (`tracker.tbf.arm_dictionary`), from
the initial pose at frame 0 as paper 1 starts.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_shapes import standard_shape
from tracker.models.dsq_arm import DSQArm
from tracker.models.makehuman import Triangles, body_measurements, build_body, nearest_standard_body
from tracker.motion.mocap import read_body_clip
from tracker.motion.posture import arms_pose
from tracker.presentation import Panel, Presentation
from tracker.protocol import Observation, SampleDictionary, StepResult, Tracker
from tracker.ranges import Finite, Positive, Range
from tracker.registry import TRACKERS, Fit
from tracker.tbf.alignment import (
    GroundPlacement,
    Placement,
    ViewsPlacement,
    feet_anchor,
    sample_spots,
    samples_anchor,
    shifted,
    spot_pixels,
    world_offset,
)
from tracker.tbf.arm_dictionary import ArmDictionary, ArmGridSpec
from tracker.tbf.costs import Cost, EmptySilhouette
from tracker.tbf.filter import FilterResult, FilterSettings, TreeFilter
from tracker.tbf.motion import BODY_SPACE, RandomWalk
from tracker.tbf.sample_build import BuildSettings, load_or_build
from tracker.tbf.sample_spec import SampleSpec, clip_files, sample_poses
from tracker.tbf.samples import SampleViews
from tracker.tbf.tree import PoseTree, load_or_build_tree, thresholds_for_shares
from tracker.timing import elapsed_ms

log = logging.getLogger(__name__)

Share = Annotated[float, Range(0.0, 1.0, low_open=True)]


@dataclass(frozen=True)
class TbfSettings:
    """Paper 2's silhouette tree-based filter: pose samples, a tree of them by silhouette distance, Bayesian
    filtering down the tree with pruning."""

    samples: SampleSpec = field(default_factory=SampleSpec)
    # T_l: XOR distance (fraction of the window) at 80x60, 160x120, 320x240.
    thresholds: tuple[Positive, Positive, Positive] = (0.006, 0.002, 0.001)
    # Or T_l chosen for the sample set at hand: each level holds this share of the samples as nodes
    # (`tracker.tbf.tree.thresholds_for_shares`; the paper's experiment A: 0.203, 0.882, 0.971). Replaces thresholds.
    node_shares: tuple[Share, Share, Share] | None = None
    filter: FilterSettings = field(default_factory=FilterSettings)
    initial_yaw_deg: Finite = -90.0  # the initial pose: upright, arms down, facing this way (the body faces -y)
    cache_dir: str = ".cache/tbf"  # sample sets and trees, keyed by everything that affects them
    # How much of a cached sample set is read to trust it: a sampled digest of each array, or every byte.
    cache_check: Literal["sampled", "full"] = "sampled"
    build: BuildSettings = field(default_factory=BuildSettings)  # shards, processes, joblib backend
    body_triangles: Triangles = 4500  # the tracker's model: the standard body (the subject may differ)
    # Which standard body: MakeHuman's base mesh, or the one of `STANDARD_BODIES` nearest to the subject's
    # stature and chest girth, measured on the subject as a tailor would (paper 2, section 7).
    body: Literal["base", "nearest_standard"] = "base"
    # The observed silhouette as it is, or moved by whole pixels so that its feet stand where the samples' do,
    # the estimate's root moved back by as much (`tracker.tbf.alignment`): a person who steps about. Or placed on
    # the floor: scaled by its feet's depth and moved onto the samples' feet, the root estimated on the ground from
    # where the feet stand (`tracker.tbf.alignment.GroundPlacement`): a person who walks about.
    align: Literal["none", "feet", "ground"] = "none"
    # The DSQ arm's pose samples (model=dsq_arm; `tracker.tbf.arm_dictionary`): a grid of its parameters.
    arm_samples: ArmGridSpec = field(default_factory=ArmGridSpec)


@dataclass(frozen=True, eq=False, kw_only=True)
class TbfResult(StepResult):
    """A frame of tree-based filtering: the filter's result (None when the frame failed). Build it with
    `TbfResult.of`, which also fills the columns and series every run records."""

    filter: FilterResult | None

    @classmethod
    def of(cls, part_names: Sequence[str], found: FilterResult | None, **fields: Any) -> TbfResult:
        if found is None:
            return cls(filter=None, **fields)
        columns: dict[str, Any] = {
            "est_sample": found.sample,
            "entropy": found.entropy,
            "prior_terms": found.prior_terms,
        }
        series: dict[str, float] = {"tree/entropy": found.entropy}
        for level, (evaluated, kept) in enumerate(zip(found.nodes_evaluated, found.nodes_kept, strict=True), 1):
            columns[f"nodes_level{level}"], columns[f"kept_level{level}"] = evaluated, kept
            series[f"tree/level{level}/evaluated"], series[f"tree/level{level}/kept"] = float(evaluated), float(kept)
        return cls(
            filter=found,
            frame_columns=columns,
            part_columns={"occluded_est": found.occluded.copy()},
            series=series,
            **fields,
        )


def check_settings(settings: TbfSettings, frames: int, key: str, model: str) -> None:
    """Before a run: every clip the samples come from is a readable clip of a known skeleton; the arm is not placed
    on a floor."""
    if model == "dsq_arm" and settings.align != "none":
        raise ValueError(f"{key}.align={settings.align}: the arm stands on no floor, allowed none")
    for index, path, rate in clip_files(settings.samples, key):
        pattern = settings.samples.clips[index]
        read_body_clip(path, f"{key}.samples.clips[{index}]" + (f" ({pattern})" if path != pattern else ""), rate)


TBF_LOOK = Presentation(
    panels=lambda parts: [
        Panel("tree: nodes evaluated and kept per level", "metrics/tree", ("level*/**",)),
        Panel("posterior entropy (nats)", "metrics/tree", ("entropy",)),
    ]
)


@TRACKERS.register(
    "tbf",
    settings=TbfSettings,
    needs={"cost": "nwxor", "motion": "dm2"},
    # paper 2: one camera; from more, the views' likelihoods multiplied
    models={"body_mesh": Fit((1, 4)), "dsq_arm": Fit((1, 4))},
    observes=("silhouettes",),
    presentation=TBF_LOOK,
    check=check_settings,
)
class TbfTracker(Tracker):
    name: ClassVar[str] = "tbf"

    def __init__(self, settings: TbfSettings, cost: Cost, motion: RandomWalk) -> None:
        self.settings, self.cost, self.motion = settings, cost, motion
        self.samples: SampleViews | None = None
        self.tree: PoseTree | None = None

    def start(
        self, model: BodyMesh | DSQArm, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator
    ) -> None:
        self.cameras = tuple(cameras)
        self.subject, self.part_names = model, model.part_names
        start = time.perf_counter()
        settings = self.settings
        cache_dir = Path(settings.cache_dir)
        self.arm_grid = self.body = None
        if isinstance(model, DSQArm):  # its own grid of poses, started where paper 1 starts: at the initial pose
            self.arm_grid = ArmDictionary(model, settings.arm_samples)
            posable, space, self.transitions = self.arm_grid, self.arm_grid.space, None
            poses, initial_pose = self.arm_grid.poses(), self.arm_grid.pose_of(initial)
        else:
            self.body = posable = self.standard_body(model)
            space, (poses, self.transitions) = BODY_SPACE, sample_poses(settings.samples, self.body)
            initial_pose = arms_pose(self.body, (0.0, 8.0, 0.0), (0.0, 8.0, 0.0), yaw_deg=settings.initial_yaw_deg)
        self.samples = SampleViews(
            tuple(
                load_or_build(
                    posable, camera, poses, cache_dir / "samples", build=settings.build, check=settings.cache_check
                )
                for camera in self.cameras
            )
        )
        self.thresholds = settings.thresholds
        if settings.node_shares is not None:
            self.thresholds = thresholds_for_shares(self.samples, settings.node_shares)
        self.tree = load_or_build_tree(self.samples, self.thresholds, cache_dir / "trees")
        placed_by_views = settings.align == "ground" and len(self.cameras) > 1  # where the views' rays cross
        spots = sample_spots(self.cameras, self.samples) if placed_by_views else None
        self.filter = TreeFilter(
            self.samples,
            self.tree,
            self.cost,
            self.motion,
            settings.filter,
            self.transitions,
            space,
            None
            if spots is None
            else [spot_pixels(self.cameras, spots, level.resolution) for level in self.tree.levels],
        )
        self.anchors = [samples_anchor(view) for view in self.samples.sets] if settings.align == "feet" else None
        # frame -> the silhouettes the filter saw (finest level, packed) and the sample whose spot they were placed on
        self._seen: dict[int, tuple[list[np.ndarray], int | None]] = {}
        self.filter.start(initial_pose)
        self.placement = self.views_placement = None
        if settings.align == "ground" and len(self.cameras) == 1:  # the feet to place on at first: the initial
            self.placement = GroundPlacement(self.cameras[0], self.samples.sets[0], self.filter.initial_sample)
        if placed_by_views:
            self.views_placement = ViewsPlacement(self.cameras, self.samples, self.filter.initial_sample, spots)
        self._estimate = self.estimate_of(np.asarray(self.samples.poses[0]))
        self.dictionary = SampleDictionary(
            poses=self.samples.poses,
            model=posable if self.body is None else self.body,
            parameters=self.estimate_of,
            pose_of=self.arm_grid.pose_of if self.arm_grid is not None else np.asarray,
            steps=self.motion.base_sigmas(space),
            prefers=self.prefers,
        )
        self.setup_s = time.perf_counter() - start
        sigmas = ["/".join(f"{sigma:.3g}" for sigma in views) for views in self.filter.level_sigmas]
        log.info(
            "tbf: %d samples, tree %s nodes per level, likelihood sigma per level %s (%.1f s)",
            len(self.samples),
            self.tree.node_counts,
            sigmas,
            self.setup_s,
        )

    def standard_body(self, subject: BodyMesh) -> BodyMesh:
        """The tracker's own model: MakeHuman's base mesh or the standard body nearest the subject
        (`TbfSettings.body`), whatever the subject's own shape; ``body_choice`` says which, with both measured."""
        measured = body_measurements(subject)
        self.body_name = "base"
        if self.settings.body == "nearest_standard":
            self.body_name = nearest_standard_body(subject, self.settings.body_triangles)
        body = build_body(triangles=self.settings.body_triangles, shape=standard_shape(self.body_name))
        chosen = body_measurements(body)
        self.body_choice = {
            "name": self.body_name,
            "stature_m": round(chosen.stature_m, 4),
            "chest_girth_m": round(chosen.chest_girth_m, 4),
            "subject_stature_m": round(measured.stature_m, 4),
            "subject_chest_girth_m": round(measured.chest_girth_m, 4),
        }
        return body

    def estimate_of(self, pose: np.ndarray) -> np.ndarray:
        """A sample's pose vector as the run's estimate: the body's pose vector itself, the arm's parameters."""
        return self.arm_grid.params(pose) if self.arm_grid is not None else pose.copy()

    def describe(self) -> dict[str, Any]:
        """What `start` built: the standard body chosen, the number of pose samples and the tree's nodes per level."""
        if self.samples is None or self.tree is None:
            return {}
        chosen = {"body": self.body_choice} if self.body is not None else {}
        return {
            **chosen,
            "samples": len(self.samples),
            "tree_nodes": self.tree.node_counts,
            "tree_thresholds": [round(t, 6) for t in self.thresholds],
        }

    def summarize(self, table: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """The tree search's mean effort: nodes evaluated per level, and the fraction of them pruned."""
        frame = table["part"] == self.part_names[0]  # one row per frame
        levels = sorted(column for column in table if column.startswith("nodes_level"))
        evaluated = [table[column][frame] for column in levels]
        kept = [table[column.replace("nodes", "kept")][frame] for column in levels]
        # (failed frames have no tree search: NaN in these columns)
        return {
            "nodes_evaluated_mean": [float(np.nanmean(values)) for values in evaluated],
            "pruned_fraction_mean": [
                float(1 - np.nansum(k) / np.nansum(e)) for k, e in zip(kept, evaluated, strict=True)
            ],
        }

    def prefers(self, frame: int, sample: int, other: int) -> bool:
        """Whether the silhouettes the filter saw at ``frame`` are at least as likely under ``sample`` as under
        ``other`` (by the run's cost at the finest level; with several views, the product of their likelihoods, each
        sample moved onto the spot the silhouettes were placed on, as the filter scores it). False for a frame the
        filter did not see (it failed)."""
        if frame not in self._seen:
            return False
        width, height = self.tree.levels[-1].resolution
        packed, reference = self._seen[frame]
        seen = tuple(np.unpackbits(view, count=width * height).reshape(height, width) > 0 for view in packed)
        finest = len(self.tree.levels) - 1
        distances = self.filter.score_samples(finest, seen, np.array([sample, other]), reference)
        likelihood = self.filter.log_likelihood(finest, distances)
        return bool(likelihood[0] >= likelihood[1])

    def step(self, observation: Observation) -> TbfResult:
        silhouettes = observation.silhouettes
        if not silhouettes:
            raise ValueError("tracker=tbf needs the frame's silhouette (the capture stage of a body scene)")
        start = time.perf_counter()
        finest = len(self.tree.levels) - 1
        observed = [silhouettes[camera.name] for camera in self.cameras]
        shifts = [self._alignment(view, silhouette) for view, silhouette in enumerate(observed)]
        placed, offset = None, None
        if self.placement is not None or self.views_placement is not None:
            observed = [self.filter.observation_at(finest, silhouette) for silhouette in observed]
        if self.placement is not None:  # one view; None: no feet below the horizon, taken as it is
            placed = self.placement.place(observed[0])
            observed[0] = placed.silhouette if placed else observed[0]
        if self.views_placement is not None and (views_placed := self.views_placement.place(observed)) is not None:
            observed, offset = views_placed
        seen = tuple(
            shifted(silhouette, *shift) if any(shift) else silhouette
            for silhouette, shift in zip(observed, shifts, strict=True)
        )
        self.last_observation = seen  # what the filter sees (benchmarks score it again)
        reference = None if self.views_placement is None else self.views_placement.reference
        try:
            found = self.filter.step(seen, reference)
        except EmptySilhouette as error:  # nobody in view: keep the last estimate, say why
            return TbfResult.of(
                self.part_names,
                None,
                frame=observation.frame,
                estimate=self._estimate.copy(),
                timings_ms={"filter": elapsed_ms(start)},
                failure=f"{error}",
            )
        self._seen[observation.frame] = (
            [np.packbits(self.filter.observation_at(finest, view)) for view in seen],
            reference,
        )
        estimate = self._placed_estimate(found, shifts, placed, offset)
        self._estimate = estimate
        result = TbfResult.of(
            self.part_names,
            found,
            frame=observation.frame,
            estimate=estimate,
            timings_ms={**found.timings_ms, "filter": elapsed_ms(start)},
        )
        if self.anchors is not None:
            result.frame_columns.update(align_du_px=shifts[0][0], align_dv_px=shifts[0][1])
        if self.placement is not None:
            result.frame_columns.update(placement_scale=placed.scale if placed else float("nan"))
        if self.views_placement is not None:
            dx, dy = offset[:2] if offset is not None else (float("nan"), float("nan"))
            result.frame_columns.update(placement_dx_m=float(dx), placement_dy_m=float(dy))
        return result

    def _placed_estimate(
        self, found: FilterResult, shifts: list[tuple[int, int]], placed: Placement | None, offset: np.ndarray | None
    ) -> np.ndarray:
        """The filter's sample where the alignment puts it: placed on the floor (one view's ground placement, or
        several views' offset), or its root moved back by the views' shifts (their mean)."""
        if self.arm_grid is not None:
            return self.estimate_of(found.pose)
        if offset is not None:
            return self.views_placement.pose(found.sample, offset)
        if placed is not None:
            return self.placement.pose(found.sample, placed)
        estimate = found.pose.copy()
        if any(any(shift) for shift in shifts):  # the subject stands away from the samples' spot: so does the estimate
            estimate[:3] += np.mean(
                [
                    world_offset(camera, estimate[:3], -du, -dv) if du or dv else np.zeros(3)
                    for camera, (du, dv) in zip(self.cameras, shifts, strict=True)
                ],
                axis=0,
            )
        return estimate

    def _alignment(self, view: int, observed: np.ndarray) -> tuple[int, int]:
        """Whole pixels ``(du, dv)`` that move the observed feet onto view ``view``'s samples' (`TbfSettings.align`)."""
        found = feet_anchor(observed) if self.anchors is not None else None
        if found is None:
            return 0, 0
        anchor = self.anchors[view]
        return int(round(anchor[0] - found[0])), int(round(anchor[1] - found[1]))
