"""The silhouette tree-based filtering tracker (paper 2): `tracker=tbf` with a cost and a motion model.

`start` picks the tracker's own body (``body``: MakeHuman's base mesh, or the standard body nearest the subject's
stature and chest girth, measured on the subject as a tailor would), builds (or loads from ``cache_dir``) the pose
sample set of that body seen by each camera of the rig and their tree (``thresholds``, or ``node_shares``), then
sets the initial prior around the configured initial pose (upright, arms down, facing ``initial_yaw_deg``); `step`
takes the frame's observed silhouettes (background subtraction, done by the run's capture stage:
``observation.silhouettes``), moves each onto its view's samples' feet or places the person on the floor when ``align``
says so (`tracker.tbf.alignment`; from several views, where their centroid rays cross), and runs
`tracker.tbf.filter.TreeFilter` on the views together (their likelihoods multiplied): the estimate is its best
sample, or the end of the best chain of each frame's most likely ones (``chain``, `tracker.tbf.chains`). The tracker
never sees the truth: measuring the subject's size at `start` stands for the paper's measuring of the person. It
describes its samples as ``dictionary`` (`tracker.protocol.SampleDictionary`), by which the evaluation measures
after the run what the samples allow and where the silhouette could not tell (`tracker.evaluation.dictionary`). The
DSQ arm (``model=dsq_arm``) is tracked the same way over a grid of its parameters (`tracker.tbf.arm_dictionary`),
from the initial pose at frame 0 as paper 1 starts.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.geometry.rotations import mean_rotation_vectors
from tracker.models.body_mesh import BodyMesh
from tracker.models.dsq_arm import DSQArm
from tracker.motion.posture import arms_pose
from tracker.presentation import STAGES_PANEL, Panel, Presentation
from tracker.protocol import Observation, SampleDictionary, StepResult, Tracker
from tracker.registry import TRACKERS, Fit
from tracker.tbf.alignment import GroundPlacement, ViewsPlacement, sample_anchors, sample_spots, spot_pixels
from tracker.tbf.arm_dictionary import ArmDictionary
from tracker.tbf.chains import BestChain
from tracker.tbf.costs import Cost, EmptySilhouette
from tracker.tbf.filter import FilterResult, TreeFilter
from tracker.tbf.flips import depth_flips, line_of_sight
from tracker.tbf.motion import BODY_SPACE, PoseSpace, RandomWalk
from tracker.tbf.own_body import own_body
from tracker.tbf.placing import AsSeen, FeetAligned, GroundPlaced, Placing, ViewsPlaced
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.sample_spec import cached_joint_positions, cached_sample_poses
from tracker.tbf.samples import LEVEL_RESOLUTIONS, SampleViews
from tracker.tbf.settings import TbfSettings, check_settings
from tracker.tbf.tree import PoseTree, load_or_build_tree, thresholds_for_shares
from tracker.timing import elapsed_ms

log = logging.getLogger(__name__)


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


TBF_LOOK = Presentation(
    panels=lambda parts: [
        Panel(
            "tree: nodes evaluated and kept per level",
            "metrics/tree",
            tuple(f"level{level}/**" for level in range(1, len(LEVEL_RESOLUTIONS) + 1)),
        ),
        Panel("posterior entropy (nats)", "metrics/tree", ("entropy",)),
        STAGES_PANEL,
    ]
)


def most_probable(posterior: np.ndarray, count: int) -> np.ndarray:
    """The indices of the ``count`` largest nonzero entries of ``posterior``, largest first (of equal ones, the lower
    index first): the stable sort of the nonzero entries alone, as a stable sort of all would rank them (a posterior
    is zero on most samples)."""
    nonzero = np.flatnonzero(posterior > 0)
    return nonzero[np.argsort(-posterior[nonzero], kind="stable")[:count]]


@TRACKERS.register(
    "tbf",
    settings=TbfSettings,
    needs={"cost": "nwxor", "motion": "dm2"},
    # paper 2: one camera; from more, the views' likelihoods multiplied
    models={"body_mesh": Fit((1, 4)), "dsq_arm": Fit((1, 4))},
    observes=("silhouettes",),
    presentation=TBF_LOOK,
    min_image=LEVEL_RESOLUTIONS[0],  # the tree's coarsest level
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
        if self.settings.filter.flip_share > 0 and len(cameras) > 1:  # before the samples are loaded or built
            raise ValueError(
                f"tracker.filter.flip_share={self.settings.filter.flip_share}: {len(cameras)} views tell a pose from "
                "its depth flip, allowed 0 (one camera's ambiguity)"
            )
        self.cameras, self.part_names = tuple(cameras), model.part_names
        start = time.perf_counter()
        posable, space, poses, initial_pose = self._dictionary(model, initial)
        self._samples_and_tree(posable, poses)
        spots = sample_spots(self.cameras, self.samples) if self._placed_by_views else None
        anchors = sample_anchors(self.samples.sets[0]) if self._placed_by_anchors else None
        if spots is not None:
            pixels = [spot_pixels(self.cameras, spots, level.resolution) for level in self.tree.levels]
        elif anchors is not None:  # the finest level's pixels in each level's
            finest = np.array(LEVEL_RESOLUTIONS[-1], dtype=np.float64)
            pixels = [anchors[:, None] * (np.array(level.resolution) / finest) for level in self.tree.levels]
        else:
            pixels = None
        self.filter = TreeFilter(
            self.samples,
            self.tree,
            self.cost,
            self.motion,
            self.settings.filter,
            self.transitions,
            space,
            pixels,
            self._flips(),
        )
        # frame -> the silhouettes the filter saw (finest level, packed) and the sample whose spot they were placed on
        self._seen: dict[int, tuple[list[np.ndarray], int | None]] = {}
        self.filter.start(initial_pose)
        chain = self.settings.chain
        self.chain = BestChain(self._joint_positions(), chain.step_m) if chain.candidates > 0 else None
        self.placing = self._placing(spots, anchors)
        # whether the last frame's placing found where the person stands (else its estimate's root is its sample's
        # own: the views could not place him, e.g. someone out of a view, or ``align=none``)
        self.person_placed = False
        self._estimate = self.estimate_of(np.asarray(self.samples.poses[0]))
        self.dictionary = SampleDictionary(
            poses=self.samples.poses,
            model=model if self.body is None else self.body,
            parameters=self.estimate_of,
            pose_of=self.arm_grid.pose_of if self.arm_grid is not None else np.asarray,
            steps=self.motion.base_sigmas(space),
            prefers=self.prefers,
            joint_positions=None if self.body is None else self._joint_positions,
        )
        setup_s = time.perf_counter() - start
        sigmas = ["/".join(f"{sigma:.3g}" for sigma in views) for views in self.filter.level_sigmas]
        log.info(
            "tbf: %d samples, tree %s nodes per level, likelihood sigma per level %s (%.1f s)",
            len(self.samples),
            self.tree.node_counts,
            sigmas,
            setup_s,
        )

    def _joint_positions(self) -> np.ndarray:
        """The body samples' joint positions, on the tracker's own body (`SampleDictionary.joint_positions`)."""
        return cached_joint_positions(self.body, self.samples.poses, Path(self.settings.cache_dir) / "joints")

    def _flips(self) -> np.ndarray | None:
        """Each sample's depth flip for the one camera (`tracker.tbf.flips`), when the filter moves a share of its
        prior to them (``filter.flip_share``); else None."""
        if self.settings.filter.flip_share == 0:
            return None
        joints = self._joint_positions()
        self._aligned_joints = joints - joints[:, :1]
        return depth_flips(joints, line_of_sight(self.cameras[0], np.median(self.samples.poses[:, :3], axis=0)))

    def _dictionary(
        self, model: BodyMesh | DSQArm, initial: np.ndarray
    ) -> tuple[Any, PoseSpace, np.ndarray, np.ndarray]:
        """What the samples pose, the space of their pose vectors, the pose vectors and frame 0's pose: the body's
        (the tracker's own body; upright, arms down, facing ``initial_yaw_deg``, or the given ``initial`` posture:
        ``initial_pose``), or the arm's grid (started where paper 1 starts: at the initial pose)."""
        settings, self.arm_grid, self.body = self.settings, None, None
        if isinstance(model, DSQArm):
            self.arm_grid, self.transitions = ArmDictionary(model, settings.arm_samples), None
            return self.arm_grid, self.arm_grid.space, self.arm_grid.poses(), self.arm_grid.pose_of(initial)
        cache_dir = Path(settings.cache_dir)
        self.body, self.body_choice = own_body(model, settings.body, settings.body_triangles, cache_dir / "bodies")
        poses, self.transitions = cached_sample_poses(settings.samples, self.body, cache_dir / "poses")
        initial_pose = arms_pose(self.body, (0.0, 8.0, 0.0), (0.0, 8.0, 0.0), yaw_deg=settings.initial_yaw_deg)
        if settings.initial_pose == "given":  # the given pose's posture, where the samples stand (they do in place)
            initial_pose = np.r_[initial_pose[:3], np.asarray(initial, dtype=np.float64)[3:]]
        return self.body, BODY_SPACE, poses, initial_pose

    def _samples_and_tree(self, posable: Any, poses: np.ndarray) -> None:
        """Each view's sample set of ``poses`` and their tree, from the cache or built into it."""
        settings, cache_dir = self.settings, Path(self.settings.cache_dir)
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
        self.tree = load_or_build_tree(self.samples, self.thresholds)

    @property
    def _placed_by_views(self) -> bool:
        """Placed on the floor where the views' centroid rays cross (several views)."""
        return self.settings.align == "ground" and len(self.cameras) > 1

    @property
    def _placed_by_anchors(self) -> bool:
        """Placed on the floor from one view, each sample scored from its own anchor (``placed_on=own``)."""
        return self.settings.align == "ground" and len(self.cameras) == 1 and self.settings.placed_on == "own"

    def _placing(self, spots: np.ndarray | None, anchors: np.ndarray | None) -> Placing:
        """The alignment mode (`TbfSettings.align`); the floor's placings start on the initial prior's sample."""
        align, initial = self.settings.align, self.filter.initial_sample
        finest = len(self.tree.levels) - 1

        def at_finest(silhouette: np.ndarray) -> np.ndarray:
            return self.filter.observation_at(finest, silhouette)

        if align == "feet":
            return FeetAligned(self.cameras, self.samples)
        if self._placed_by_views:
            return ViewsPlaced(ViewsPlacement(self.cameras, self.samples, initial, spots), at_finest)
        if align == "ground":
            return GroundPlaced(GroundPlacement(self.cameras[0], self.samples.sets[0], initial, anchors), at_finest)
        return AsSeen()

    def mean_rotations(self) -> np.ndarray:
        """The joint rotations the mean estimate averages (`mean_rotation_vectors`), weighted: a pose vector's entries
        from 3 on. With a chain, its candidates near its best (`BestChain.around_best`), by their chains'
        probabilities; else the ``mean_of`` most probable samples (those of nonzero posterior; with flips, of the most
        probable sample's side), by their posterior."""
        if self.chain is not None:
            averaged, weights = self.chain.around_best(self.settings.chain.mean_radius_m)
        else:
            averaged = most_probable(self.filter.posterior, self.settings.mean_of)
            if self.filter.flips is not None:
                averaged = averaged[self.on_side_of(averaged[0], averaged)]
            weights = self.filter.posterior[averaged]
        rotations = np.asarray(self.samples.poses[averaged], dtype=np.float64)[:, 3:]
        return mean_rotation_vectors(rotations.reshape(len(averaged), -1, 3), weights).ravel()

    def on_side_of(self, sample: int, others: np.ndarray) -> np.ndarray:
        """Which of ``others`` lie on ``sample``'s side of the depth ambiguity: nearer it than its flip (root-aligned
        joints, as `tracker.tbf.flips` measures). A posterior may hold both sides; their mean is neither."""
        joints, flip = self._aligned_joints, self.filter.flips[sample]
        own = ((joints[others] - joints[sample]) ** 2).sum(axis=(1, 2))
        return own <= ((joints[others] - joints[flip]) ** 2).sum(axis=(1, 2))

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

    @property
    def last_observation(self) -> tuple[np.ndarray | None, ...]:
        """What the filter saw at the last step, per view (None: a view that had lost the person): benchmarks
        score it again."""
        return self.filter.observed

    def prefers(self, frame: int, sample: int, other: int) -> bool:
        """Whether the silhouettes the filter saw at ``frame`` are at least as likely under ``sample`` as under
        ``other`` (by the run's cost at the finest level; with several views, the product of their likelihoods, each
        sample moved onto the spot the silhouettes were placed on, as the filter scores it). False for a frame the
        filter did not see (it failed)."""
        if frame not in self._seen:
            return False
        width, height = self.tree.levels[-1].resolution
        packed, reference = self._seen[frame]
        seen = tuple(
            None if view is None else np.unpackbits(view, count=width * height).reshape(height, width) > 0
            for view in packed
        )
        finest = len(self.tree.levels) - 1
        distances = self.filter.score_samples(finest, seen, np.array([sample, other]), reference)
        likelihood = self.filter.log_likelihood(finest, distances)
        return bool(likelihood[0] >= likelihood[1])

    def step(self, observation: Observation) -> TbfResult:
        """Place the frame's silhouettes (`placing`), filter them down the tree, and put the best sample (with a
        ``chain``, the end of the best chain) where the person stands (with ``estimate=mean``, its joints turned to
        the mean of the most probable samples, or of the chain's candidates near its end)."""
        if not observation.silhouettes:
            raise ValueError("tracker=tbf needs the frame's silhouette (the capture stage of a body scene)")
        start = time.perf_counter()
        placed = self.placing.place([observation.silhouettes[camera.name] for camera in self.cameras])
        self.person_placed = placed.how is not None
        try:
            found = self.filter.step(placed.silhouettes, placed.reference)
        except EmptySilhouette as error:  # nobody in view: keep the last estimate, say why
            return TbfResult.of(
                self.part_names,
                None,
                frame=observation.frame,
                estimate=self._estimate.copy(),
                timings_ms={"filter": elapsed_ms(start)},
                failure=f"{error}",
            )
        if self.chain is not None:
            sample = self.chain.step(*self.filter.most_likely(self.settings.chain.candidates))
            pose, occluded = np.asarray(self.samples.poses[sample]).copy(), self.filter.occluded_of(sample)
            found = replace(found, sample=sample, pose=pose, occluded=occluded)
        finest = len(self.tree.levels) - 1
        packed = [
            None if view is None else np.packbits(self.filter.observation_at(finest, view))
            for view in self.filter.observed
        ]
        self._seen[observation.frame] = (packed, placed.reference)
        estimate = self.placing.estimate(found.sample, found.pose, placed)
        if self.settings.estimate == "mean":
            estimate[3:] = self.mean_rotations()
        self._estimate = self.estimate_of(estimate)
        result = TbfResult.of(
            self.part_names,
            found,
            frame=observation.frame,
            estimate=self._estimate,
            timings_ms={**found.timings_ms, "filter": elapsed_ms(start)},
        )
        result.frame_columns.update(self.placing.columns(placed))
        return result
