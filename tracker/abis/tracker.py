"""The AbIS tracker (paper 1): features -> pairs -> top-down per-part fitting -> visibility -> pair upkeep; here
the tracker (`AbisTracker`, which tracks the arm by `ArmAbis` and a body by `tracker.abis.body_tracker.BodyAbis`)
and the arm's sequence, whose frame loop every model shares (`tracker.abis.frame_steps.AbisSequence`).

Per frame t it sees only the views' RGB images. Frame 0 starts from an initial estimate (the paper aligns the model
with a user's help; `initial_estimate` stands in with the truth plus configurable noise) and pairs features with
visible samples. Every later frame:
    1. features are tracked; pairs whose feature was lost are dropped ("lost"), the rest carry over ("tracked");
    2. parts are fitted top-down (root first, each child against its freshly fitted parent), eq 8;
    3. a z-buffer render of the new estimate decides visibility: pairs whose point is now hidden, or that another
       part's edge is about to reach (the model's prediction of occlusion), are discarded ("discarded_occlusion"),
       then pairs whose residual exceeds `max_residual_px` ("discarded_error"); the rest are anchored again to the
       material point their feature shows (`tracker.abis.anchoring`), against the features' drift;
    4. unpaired features are paired with visible samples not yet taken ("new"), refined to lie under their feature
       and anchored likewise.
``selection=none`` is the ablation of steps 3-4's model image: nothing is discarded for occlusion, and features
pair with any sample facing the camera (`tracker.abis.visibility.facing_samples`), as bottom-up tracking would.
So per part and view: pairs(t) = pairs(t-1) - lost - discarded_occlusion - discarded_error + new.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import ClassVar

import cv2
import numpy as np

from tracker.abis.anchoring import texture_offsets
from tracker.abis.body_tracker import BodyAbis
from tracker.abis.correspondences import (
    POLE_MARGIN_RAD,
    Pairs,
    pair_features,
    pixel_jacobian,
    refine_surface_coordinates,
)
from tracker.abis.fitting import PartProblem, Prior, ViewPairs, fit_part
from tracker.abis.frame_steps import (
    NEW,
    AbisResult,
    AbisSequence,
    discard,
    feature_rows,
    interior_labels,
)
from tracker.abis.settings import AbisSettings, InitialNoise
from tracker.abis.visibility import (
    VisibleSamples,
    facing_samples,
    in_image,
    occlusion_edges,
    outward_normals,
    reached_by_other_parts,
    visible_mask,
    visible_samples,
)
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.models.dsq import PARAM_INDEX, pole_point
from tracker.models.dsq_arm import DSQArm
from tracker.observe.features import FeatureFrame
from tracker.presentation import Panel, Presentation, paper_part_first
from tracker.protocol import Observation, Tracker
from tracker.registry import TRACKERS, Fit
from tracker.render.offscreen import DepthLabels, SceneRenderer


def initial_estimate(arm: DSQArm, initial: np.ndarray, noise: InitialNoise, rng: np.random.Generator) -> np.ndarray:
    """The frame-0 estimate: the ``initial`` parameters with noise on the root position, every rotation and every
    scale."""
    estimate = np.array(initial, dtype=np.float64)
    estimate[0, PARAM_INDEX["c1"] : PARAM_INDEX["c3"] + 1] += rng.normal(0, noise.translation_m, 3)
    estimate[:, PARAM_INDEX["r1"] : PARAM_INDEX["r3"] + 1] += rng.normal(0, noise.rotation_rad, (len(estimate), 3))
    estimate[:, PARAM_INDEX["a"]] *= 1 + rng.normal(0, noise.scale_fraction, len(estimate))
    return arm.connect(estimate)


# Paper 1's three orthogonal views, or more; the body by the features of its textured skin, from 3 or 4 views at
# 640x480 (at 320x240 the margins kept from silhouettes and occlusion edges leave too few features to pair).
ABIS_FITS = {
    "dsq_arm": Fit((1, 4)),
    "body_mesh": Fit((3, 4), rig="body_multi_vga", settings=(("model.texture_seed", 0),)),
}
ABIS_LOOK = Presentation(
    panels=lambda parts: [
        *(Panel(f"{part} pairs", f"metrics/correspondences/{part}") for part in paper_part_first(parts)),
        Panel("cost (eq 8, px^2)", "metrics/cost"),
    ],
    state_colors={
        "tracked": (0, 220, 0),
        "new": (0, 160, 255),
        "discarded": (255, 40, 40),
        "unpaired": (150, 150, 150),
    },
    point_colors={"estimate": (255, 255, 0)},
)


@TRACKERS.register("abis", settings=AbisSettings, models=ABIS_FITS, presentation=ABIS_LOOK)
class AbisTracker(Tracker):
    """`start` with the model, the cameras and the frame-0 pose; then `step` once per frame; `close`."""

    name: ClassVar[str] = "abis"

    def __init__(self, settings: AbisSettings | None = None) -> None:
        self.settings = settings or AbisSettings()
        self._renderer: SceneRenderer | None = None
        self._sequence: AbisSequence | None = None

    def start(
        self, model: DSQArm | BodyMesh, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator
    ) -> None:
        """Begin a sequence: frame 0's estimate is ``initial`` with the configured `InitialNoise` drawn from ``rng``
        (the paper's user-assisted alignment); after that the tracker sees images only. The arm is tracked by
        `ArmAbis`, a body by `tracker.abis.body_tracker.BodyAbis`."""
        if self._renderer is None:
            self._renderer = SceneRenderer(cameras[0].width, cameras[0].height)
        sequence = BodyAbis if isinstance(model, BodyMesh) else ArmAbis
        self._sequence = sequence(self.settings, model, cameras, initial, rng, self._renderer)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def step(self, observation: Observation) -> AbisResult:
        return self._sequence.step(observation)


class ArmAbis(AbisSequence):
    """One sequence of AbIS on the arm of deformable superquadrics (paper 1)."""

    def __init__(
        self,
        settings: AbisSettings,
        model: DSQArm,
        cameras: Sequence[Camera],
        initial: np.ndarray,
        rng: np.random.Generator,
        renderer: SceneRenderer,
    ) -> None:
        super().__init__(
            settings,
            model.part_names,
            cameras,
            initial_estimate(model, initial, settings.initial_noise, rng),
            Pairs.empty(),
        )
        self.model, self._renderer = model, renderer
        self._textures = [cv2.cvtColor(texture, cv2.COLOR_RGB2GRAY).astype(np.float32) for texture in model.textures]
        self._sample_offsets = np.arange(len(model.parts)) * len(model.sample_grid.eta)  # part -> its first row

    def _visibility(self) -> tuple[dict[str, DepthLabels | None], dict[str, VisibleSamples], np.ndarray, np.ndarray]:
        """Per view the z-buffer and the grid samples it sees; every sample's point; the parts' world transforms."""
        samples = self.model.sample_points(self._estimate)
        if self.settings.selection == "zbuffer":
            zbuffers = self._renderer.render_depth_labels(self.cameras, self.model.zbuffer_meshes(self._estimate))
            visible = {c.name: visible_samples(c, zbuffers[c.name], samples) for c in self.cameras}
        else:  # no model image at all: the back-face test alone
            zbuffers = dict.fromkeys(camera.name for camera in self.cameras)
            normals = self._sample_normals()
            visible = {c.name: facing_samples(c, samples, normals) for c in self.cameras}
        return zbuffers, visible, np.concatenate(samples), self.model.world_transforms(self._estimate)

    def _sample_normals(self) -> list[np.ndarray]:
        """Each part's outward normals at its grid samples, for the estimate."""
        world, grid = self.model.world_transforms(self._estimate), self.model.sample_grid
        normals = []
        for part in range(len(self.model.parts)):

            def surface(eta, omega, part=part):
                return self.model.part_points(self._estimate, part, eta, omega, world)

            normals.append(outward_normals(surface, grid.eta, grid.omega, world[part][:3, 3]))
        return normals

    def _fit(self, features: Mapping[str, FeatureFrame]) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
        """Fit every part top-down against the current pairs; a failure leaves the previous estimate."""
        estimate = self._estimate.copy()
        n_parts = len(estimate)
        cost, iterations = np.zeros(n_parts), np.zeros(n_parts, int)
        sigmas = None if self.settings.prior is None else self.settings.prior.vector()
        for part in self.model.tree.topdown_order():
            parent = self.model.tree.parents[part]
            views = []
            for camera in self.cameras:
                pairs = self._pairs[camera.name]
                mine = pairs.parts == part
                observed = feature_rows(features[camera.name], pairs.feature_ids[mine])
                views.append(ViewPairs(camera, pairs.eta[mine], pairs.omega[mine], observed))
            world = self.model.world_transforms(estimate)
            prior = None if sigmas is None else Prior(reference=self._estimate[part], sigmas=sigmas)
            problem = PartProblem(
                views,
                None if parent is None else world[parent],
                None if parent is None else pole_point(estimate[parent], top=True),
                prior,
            )
            fitted = fit_part(estimate[part], problem, self.settings.fit)
            if not np.isfinite(fitted.params).all():
                return self._estimate, cost, iterations, f"non-finite parameters fitting part {part + 1}"
            estimate[part] = fitted.params
            estimate = self.model.connect(estimate)  # children follow the part's new pose
            cost[part], iterations[part] = fitted.cost, fitted.iterations
        return estimate, cost, iterations, None

    def _upkeep(
        self,
        camera: Camera,
        features: FeatureFrame,
        zbuffer: DepthLabels | None,
        visible: VisibleSamples,
        motion: np.ndarray | None,
        world: np.ndarray,
        counts: np.ndarray,
    ) -> np.ndarray:
        """``world``: the estimate's part -> world transforms; new and due pairs are anchored to the model's
        texture against the view's image (the feature tracker's own grey)."""
        n_parts = len(self.model.parts)
        gray = features.gray.astype(np.float32)
        pairs = self._pairs[camera.name]
        seen, uv = np.zeros(len(pairs), bool), np.zeros((len(pairs), 2))
        by_zbuffer = self.settings.selection == "zbuffer"
        for part in range(n_parts):
            mine = pairs.parts == part
            points = self.model.part_points(self._estimate, part, pairs.eta[mine], pairs.omega[mine], world)
            seen[mine], uv[mine] = (
                visible_mask(camera, zbuffer, part, points) if by_zbuffer else in_image(camera, points)
            )
        if by_zbuffer:  # the model image also predicts the pairs another part's edge is about to cover
            seen[seen] = ~reached_by_other_parts(
                uv[seen],
                pairs.parts[seen],
                motion[self._sample_offsets[pairs.parts[seen]] + pairs.samples[seen]],
                visible,
                motion[self._sample_offsets[visible.part] + visible.sample],
                self.settings.occlusion_margin_px,
                self.settings.features.window_px,
            )
        pairs, discarded = discard(pairs, seen, uv, features, self.settings.max_residual_px, counts)
        unpaired = ~np.isin(features.ids, pairs.feature_ids) & ~np.isin(features.ids, discarded)
        # Only features inside a part's region (away from silhouettes and occlusion edges, whose corners are no
        # material point of either side) pair, and only with samples of that part.
        grid = self.model.sample_grid
        new = Pairs.empty()
        if by_zbuffer:
            edges = occlusion_edges(zbuffer.labels, self.settings.occlusion_margin_px)
            interior = np.where(edges, 0, interior_labels(zbuffer.labels, self.settings.boundary_margin_px))
            pixel = np.rint(features.points).astype(int)
            region = interior[pixel[:, 1], pixel[:, 0]]
            for part in range(n_parts):
                candidates = unpaired & (region == part + 1)
                own = visible.part == part
                new = new.extend(
                    pair_features(
                        features.ids[candidates],
                        features.points[candidates],
                        VisibleSamples(visible.part[own], visible.sample[own], visible.uv[own]),
                        self.settings.pairing_radius_px,
                        grid.eta,
                        grid.omega,
                        taken=pairs,
                    )
                )
        else:  # bottom-up: any unpaired feature with the nearest facing sample of any part
            new = pair_features(
                features.ids[unpaired],
                features.points[unpaired],
                visible,
                self.settings.pairing_radius_px,
                grid.eta,
                grid.omega,
                taken=pairs,
            )
        keep = np.zeros(len(new), bool)
        for part in np.unique(new.parts):  # move each new pair's point exactly under its feature
            mine = new.parts == part

            def surface(eta, omega, part=part):
                return self.model.part_points(self._estimate, part, eta, omega, world)

            new.eta[mine], new.omega[mine], distance = refine_surface_coordinates(
                surface, camera, new.eta[mine], new.omega[mine], feature_rows(features, new.feature_ids[mine])
            )
            keep[mine] = distance <= self.settings.refined_tolerance_px
        new = new.subset(keep)
        counts[:, NEW] = new.count_by_part(n_parts)
        held = pairs.extend(new)
        if self.settings.anchor is not None:  # the material point each feature shows, by the model's texture:
            # every new pair, and the others in turn (by feature id), against the features' drift
            is_new = np.r_[np.zeros(len(pairs), bool), np.ones(len(new), bool)]
            every = self.settings.reanchor_every
            due = is_new | ((held.feature_ids % every == self._frame % every) if every else False)
            self._anchor(held, due, is_new, camera, features, gray, world)
        self._pairs[camera.name] = held
        return discarded

    def _anchor(
        self,
        pairs: Pairs,
        due: np.ndarray,
        search: np.ndarray,
        camera: Camera,
        features: FeatureFrame,
        gray: np.ndarray,
        world: np.ndarray,
    ) -> None:
        """Move the ``due`` pairs' surface coordinates (in place) to the material point their feature shows, as
        matched against the model's texture around where the estimate puts each pair (`tracker.abis.anchoring`;
        ``search``: over whole pixels first, for new pairs)."""
        for part in np.unique(pairs.parts[due]):
            mine = np.flatnonzero(due & (pairs.parts == part))

            def surface(eta, omega, part=part):
                return self.model.part_points(self._estimate, part, eta, omega, world)

            # The observed patch around the feature against the texture around the pair's point, as the estimate
            # maps it: the match is in the material, whatever the estimate's offset in the image.
            jacobian = pixel_jacobian(surface, camera, pairs.eta[mine], pairs.omega[mine])
            offsets, _ = texture_offsets(
                gray,
                feature_rows(features, pairs.feature_ids[mine]),
                pairs.eta[mine],
                pairs.omega[mine],
                jacobian,
                self._textures[part],
                self.settings.anchor,
                search[mine],
            )
            pairs.eta[mine] = np.clip(
                pairs.eta[mine] + offsets[:, 0], -np.pi / 2 + POLE_MARGIN_RAD, np.pi / 2 - POLE_MARGIN_RAD
            )  # as `refine_surface_coordinates` keeps them
            omega = pairs.omega[mine] + offsets[:, 1]
            pairs.omega[mine] = np.where(np.abs(omega) > np.pi, (omega + np.pi) % (2 * np.pi) - np.pi, omega)
