"""AbIS on paper 1's arm of deformable superquadrics: how its sequence fits, sees and keeps pairs
(`tracker.abis.frame_steps.AbisSequence` runs the frame loop every model shares).

Samples are each part's grid of surface coordinates (eta, omega); a pair is a feature and its own surface
coordinates, refined to lie exactly under the feature when it forms and anchored to the material point the feature
shows (`tracker.abis.anchoring`): every new pair, and the others in turn every ``reanchor_every`` frames, against the
feature tracker's drift. Parts are fitted top-down, each against its own pairs (eq 8), a child from its freshly
fitted parent's top pole. Frame 0 is the initial pose with noise on the root position, every rotation and every
scale (`initial_estimate`: the paper aligns the model with a user's help).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence

import cv2
import numpy as np

from tracker.abis.anchoring import observed_patches, texture_offsets
from tracker.abis.correspondences import (
    POLE_MARGIN_RAD,
    Pairs,
    PixelsAt,
    pair_features,
    pixel_jacobian,
    refine_surface_coordinates,
    surface_pixels,
    surface_points,
)
from tracker.abis.fitting import Prior, fit_part
from tracker.abis.frame_steps import AbisSequence, feature_rows
from tracker.abis.part_problem import PartProblem, ViewPairs
from tracker.abis.settings import AbisSettings, InitialNoise
from tracker.abis.visibility import VisibleSamples, outward_normals
from tracker.geometry.cameras import Camera
from tracker.models.dsq import PARAM_INDEX, pole_point
from tracker.models.dsq_arm import DSQArm
from tracker.observe.features import FeatureFrame
from tracker.render.offscreen import DepthLabels, SceneRenderer


def initial_estimate(arm: DSQArm, initial: np.ndarray, noise: InitialNoise, rng: np.random.Generator) -> np.ndarray:
    """The frame-0 estimate: the ``initial`` parameters with noise on the root position, every rotation and every
    scale."""
    estimate = np.array(initial, dtype=np.float64)
    estimate[0, PARAM_INDEX["c1"] : PARAM_INDEX["c3"] + 1] += rng.normal(0, noise.translation_m, 3)
    estimate[:, PARAM_INDEX["r1"] : PARAM_INDEX["r3"] + 1] += rng.normal(0, noise.rotation_rad, (len(estimate), 3))
    estimate[:, PARAM_INDEX["a"]] *= 1 + rng.normal(0, noise.scale_fraction, len(estimate))
    return arm.connect(estimate)


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

    def _surface(self, part: int, world: np.ndarray) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """Part ``part``'s surface on the estimate: surface coordinates -> world points (``world``: the parts'
        world transforms)."""

        def surface(eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
            return self.model.part_points(self._estimate, part, eta, omega, world)

        return surface

    def _visibility(
        self,
    ) -> tuple[Mapping[str, DepthLabels | None], dict[str, VisibleSamples], np.ndarray, np.ndarray]:
        """Per view the z-buffer and the grid samples it sees; every sample's point; the parts' world transforms."""
        samples = self.model.sample_points(self._estimate)
        zbuffers = self.selection.zbuffers(
            self.cameras,
            lambda: self._renderer.render_depth_labels(self.cameras, self.model.zbuffer_meshes(self._estimate)),
        )
        normals = functools.cache(self._sample_normals)
        visible = {c.name: self.selection.visible(c, zbuffers[c.name], samples, normals) for c in self.cameras}
        return zbuffers, visible, np.concatenate(samples), self.model.world_transforms(self._estimate)

    def _sample_normals(self) -> list[np.ndarray]:
        """Each part's outward normals at its grid samples, for the estimate."""
        world, grid = self.model.world_transforms(self._estimate), self.model.sample_grid
        return [
            outward_normals(self._surface(part, world), grid.eta, grid.omega, world[part][:3, 3])
            for part in range(len(self.model.parts))
        ]

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

    def _pair_points(self, pairs: Pairs, world: np.ndarray) -> np.ndarray:
        """The pairs' surface points on the estimate, part by part (``world``: the parts' world transforms)."""
        return surface_points(self._surfaces(world), pairs.parts, pairs.eta, pairs.omega)

    def _sample_motion(self, parts: np.ndarray, samples: np.ndarray, motion: np.ndarray) -> np.ndarray:
        return motion[self._sample_offsets[parts] + samples]  # the grid samples, part after part

    def _new_pairs(
        self,
        camera: Camera,
        features: FeatureFrame,
        unpaired: np.ndarray,
        regions: np.ndarray | None,
        visible: VisibleSamples,
        pairs: Pairs,
        world: np.ndarray,
    ) -> Pairs:
        """Each unpaired feature with the nearest visible grid sample of its region's part (any part's, without
        regions) not taken, at the sample's surface coordinates (`_settled` moves them under the feature)."""
        grid = self.model.sample_grid
        return pair_features(  # without regions, bottom-up: any unpaired feature with the nearest facing sample
            features.ids[unpaired],
            features.points[unpaired],
            visible,
            self.settings.pairing_radius_px,
            grid.eta,
            grid.omega,
            taken=pairs,
            feature_parts=None if regions is None else regions[unpaired],  # only with samples of the region's part
        )

    def _settled(
        self, matched: Mapping[str, Pairs], features: Mapping[str, FeatureFrame], world: np.ndarray
    ) -> dict[str, Pairs]:
        """Every view's new pairs, each point moved exactly under its feature (all views and parts in one batch);
        those that do not come within ``refined_tolerance_px`` of it are dropped."""
        names = [camera.name for camera in self.cameras]  # a pair's view: its camera's index
        new = Pairs.joined([matched[name] for name in names])
        if len(new) == 0:
            return dict(matched)
        views = np.repeat(np.arange(len(names)), [len(matched[name]) for name in names])
        targets = np.concatenate([feature_rows(features[name], matched[name].feature_ids) for name in names])
        new.eta[:], new.omega[:], distance = refine_surface_coordinates(
            self._pixels_at(new.parts, views, world), new.eta, new.omega, targets
        )
        keep = distance <= self.settings.refined_tolerance_px
        return {name: new.subset(keep & (views == index)) for index, name in enumerate(names)}

    def _held(
        self,
        features: Mapping[str, FeatureFrame],
        kept: Mapping[str, Pairs],
        new: Mapping[str, Pairs],
        world: np.ndarray,
    ) -> dict[str, Pairs]:
        """The kept and new pairs; with ``anchor``, every new pair and the others in turn (by feature id) anchored
        to the material point its feature shows, by the model's texture, against the features' drift."""
        held = {name: pairs.extend(new[name]) for name, pairs in kept.items()}
        if self.settings.anchor is not None:
            every, due, search = self.settings.reanchor_every, {}, {}
            for name, pairs in held.items():
                search[name] = np.r_[np.zeros(len(kept[name]), bool), np.ones(len(new[name]), bool)]
                due[name] = search[name] | ((pairs.feature_ids % every == self._frame % every) if every else False)
            self._anchor(held, due, search, features, world)
        return held

    def _pixels_at(self, parts: np.ndarray, views: np.ndarray, world: np.ndarray) -> PixelsAt:
        """Pixels of points on the estimate's ``parts`` seen by the cameras ``views`` (indices, ``(n,)`` each)."""
        return surface_pixels(self._surfaces(world), self.cameras, parts, views)

    def _surfaces(self, world: np.ndarray) -> list[Callable[[np.ndarray, np.ndarray], np.ndarray]]:
        """Every part's surface on the estimate (`_surface`), in part order."""
        return [self._surface(part, world) for part in range(len(self.model.parts))]

    def _anchor(
        self,
        pairs: Mapping[str, Pairs],
        due: Mapping[str, np.ndarray],
        search: Mapping[str, np.ndarray],
        features: Mapping[str, FeatureFrame],
        world: np.ndarray,
    ) -> None:
        """Move every view's ``due`` pairs' surface coordinates (in place) to the material point their feature shows,
        as matched against the model's texture around where the estimate puts each pair (`tracker.abis.anchoring`;
        ``search``: over whole pixels first, for new pairs). All views' pairs in one batch."""
        names = [camera.name for camera in self.cameras]  # a pair's view: its camera's index
        mine = {name: np.flatnonzero(due[name]) for name in names}
        if not any(len(rows) for rows in mine.values()):
            return
        parts = np.concatenate([pairs[name].parts[mine[name]] for name in names])
        eta = np.concatenate([pairs[name].eta[mine[name]] for name in names])
        omega = np.concatenate([pairs[name].omega[mine[name]] for name in names])
        views = np.repeat(np.arange(len(names)), [len(mine[name]) for name in names])
        # The observed patch around the feature against the texture around the pair's point, as the estimate maps
        # it: the match is in the material, whatever the estimate's offset in the image.
        patches = np.concatenate(
            [
                observed_patches(
                    features[name].gray.astype(np.float32),  # the feature tracker's own grey
                    feature_rows(features[name], pairs[name].feature_ids[mine[name]]),
                    self.settings.anchor,
                )
                for name in names
            ]
        )
        offsets, _ = texture_offsets(
            patches,
            eta,
            omega,
            pixel_jacobian(self._pixels_at(parts, views, world), eta, omega),
            self._textures,
            self.settings.anchor,
            np.concatenate([search[name][mine[name]] for name in names]),
            texture_of=parts,
        )
        # Kept in range as `refine_surface_coordinates` keeps them.
        eta = np.clip(eta + offsets[:, 0], -np.pi / 2 + POLE_MARGIN_RAD, np.pi / 2 - POLE_MARGIN_RAD)
        omega = omega + offsets[:, 1]
        omega = np.where(np.abs(omega) > np.pi, (omega + np.pi) % (2 * np.pi) - np.pi, omega)
        for index, name in enumerate(names):
            pairs[name].eta[mine[name]], pairs[name].omega[mine[name]] = eta[views == index], omega[views == index]
