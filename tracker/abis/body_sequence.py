"""AbIS on the skinned body (``model=body_mesh tracker=abis``): paper 1's loop with a triangle mesh for the arm's
superquadrics.

The frame loop, its counts and the frame's result are every model's (`tracker.abis.frame_steps.AbisSequence`);
what the mesh changes:
- samples: each part's vertices (those of its faces, `BodyMesh.part_topology`); a z-buffer render of the
  estimate's part meshes (label k + 1) decides which a view sees, as for the arm;
- pairs: an unpaired feature inside a part's region of the label image pairs with that part at the point where
  its viewing ray meets the part's faces on the estimate (`tracker.abis.mesh_pairs`), exactly under the feature;
  its sample is the hit face's nearest corner, taken at most once per view. (The arm pairs with the nearest
  sample within ``pairing_radius_px``, then moves the point under the feature: the body's vertices, ~3 cm apart,
  are too sparse for that radius, 3-6 px apart at 320-640 px wide.)
- fitting: top-down over the part tree (pelvis, torso, head, arms, legs), each part's joints' rotation vectors,
  the pelvis also the root position (`tracker.abis.body_fitting`), with the prior's ``translation_m`` and
  ``rotation_rad`` per pose component, against the pairs of the part and of every part it carries. (The arm
  fits each part to its own pairs, eq 8. The body's root part, the pelvis, is a small region that the thighs'
  and the torso's occluding edges mostly cover: on the held-out clips (``experiment=abis_body``) it holds 0.0 and
  0.1 pairs a frame, so by its own pairs the root would never move.)
Not carried over: anchoring pairs to the texture (``tracker.anchor``, ``tracker.reanchor_every``: the arm's texture
is mapped in its surface coordinates) and frame 0's scale noise: the tracker models the subject's own mesh, as
paper 1 models the arm's known shape. Frame 0 is the initial pose with `InitialNoise`'s translation and rotation
noise on the root position and every rotation vector component.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.spatial import cKDTree

from tracker.abis.body_fitting import (
    BodyPartProblem,
    MeshViewPairs,
    carried_parts,
    part_joints,
    part_parents,
    pose_prior_sigmas,
    topdown_parts,
)
from tracker.abis.correspondences import sample_keys
from tracker.abis.fitting import Prior, fit_part
from tracker.abis.frame_steps import AbisSequence, feature_rows
from tracker.abis.mesh_pairs import MeshPairs, ray_hits
from tracker.abis.settings import AbisSettings, InitialNoise
from tracker.abis.visibility import VisibleSamples
from tracker.geometry.cameras import Camera
from tracker.membership import members
from tracker.models.body_mesh import BodyMesh
from tracker.observe.features import FeatureFrame
from tracker.render.mesh import vertex_normals
from tracker.render.offscreen import DepthLabels, SceneRenderer


def initial_body_estimate(initial: np.ndarray, noise: InitialNoise, rng: np.random.Generator) -> np.ndarray:
    """The frame-0 pose: ``initial`` with noise on the root position and on every rotation vector component."""
    estimate = np.array(initial, dtype=np.float64)
    estimate[:3] += rng.normal(0, noise.translation_m, 3)
    estimate[3:] += rng.normal(0, noise.rotation_rad, len(estimate) - 3)
    return estimate


class BodyAbis(AbisSequence):
    """One sequence of AbIS on a body: its parts' vertices as samples, pairs on its faces, its joints fitted."""

    def __init__(
        self,
        settings: AbisSettings,
        body: BodyMesh,
        cameras: Sequence[Camera],
        initial: np.ndarray,
        rng: np.random.Generator,
        renderer: SceneRenderer,
    ) -> None:
        super().__init__(
            settings,
            body.part_names,
            cameras,
            initial_body_estimate(initial, settings.initial_noise, rng),
            MeshPairs.empty(),
        )
        self.body, self._renderer = body, renderer
        self._part_vertices = [used for used, _ in body.part_topology]
        self._sample_vertex = np.concatenate(self._part_vertices)  # parts' samples one after another
        self._sample_offsets = np.cumsum([0] + [len(used) for used in self._part_vertices])[:-1]
        self._part_faces = [np.flatnonzero(body.face_parts == part) for part in range(len(body.part_names))]
        self._joints = part_joints()
        self._parents = part_parents(body.parents)
        self._order = topdown_parts(self._parents)
        self._carried = [carried_parts(self._parents, part) for part in range(len(self._parents))]
        prior = settings.prior
        self._sigmas = None if prior is None else pose_prior_sigmas(prior.translation_m, prior.rotation_rad)
        self._load_compiled()

    def _load_compiled(self) -> None:
        """The fit's and the pairing's compiled passes (numba) loaded now, on one pair of the first face: loaded at
        their first use they would add ~0.2 s to the first frames."""
        pairs = MeshViewPairs(self.cameras[0], self.body.faces[:1], np.full((1, 3), 1 / 3), np.zeros((1, 2)))
        problem = BodyPartProblem(self.body, [pairs], self._joints[self._order[0]], root=True)
        problem.evaluate(self._estimate, self.settings.fit).jacobian_of()
        ray_hits(self.cameras[0], np.zeros((1, 2)), self.body.rest_vertices, self.body.faces[:1])

    def _visibility(
        self,
    ) -> tuple[Mapping[str, DepthLabels | None], dict[str, VisibleSamples], np.ndarray, np.ndarray]:
        """Per view the z-buffer and the vertices it sees (named by vertex index); every vertex's point, which is
        also the posed body upkeep reads."""
        vertices = self.body.posed_vertices(self._estimate)
        samples = [vertices[used] for used in self._part_vertices]
        zbuffers = self.selection.zbuffers(
            self.cameras,
            lambda: self._renderer.render_depth_labels(self.cameras, self.body.label_meshes(vertices)),
        )

        @functools.cache
        def normals() -> list[np.ndarray]:
            every = vertex_normals(vertices, self.body.faces)
            return [every[used] for used in self._part_vertices]

        visible = {
            c.name: self._by_vertex(self.selection.visible(c, zbuffers[c.name], samples, normals)) for c in self.cameras
        }
        return zbuffers, visible, vertices, vertices

    def _by_vertex(self, visible: VisibleSamples) -> VisibleSamples:
        """``visible`` with each sample named by its vertex index (a part's samples are its vertices, in order)."""
        return VisibleSamples(
            visible.part, self._sample_vertex[self._sample_offsets[visible.part] + visible.sample], visible.uv
        )

    def _fit(self, features: Mapping[str, FeatureFrame]) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
        """Fit every part top-down against the current pairs; a failure leaves the previous estimate."""
        estimate = self._estimate.copy()
        n_parts = len(self.body.part_names)
        cost, iterations = np.zeros(n_parts), np.zeros(n_parts, int)
        prior = None if self._sigmas is None else Prior(reference=self._estimate, sigmas=self._sigmas)
        for part in self._order:
            views = []
            for camera in self.cameras:
                pairs = self._pairs[camera.name]
                mine = members(pairs.parts, self._carried[part])
                views.append(
                    MeshViewPairs(
                        camera,
                        pairs.corners(self.body.faces)[mine],
                        pairs.barycentric[mine],
                        feature_rows(features[camera.name], pairs.feature_ids[mine]),
                    )
                )
            problem = BodyPartProblem(self.body, views, self._joints[part], self._parents[part] is None, prior)
            fitted = fit_part(estimate, problem, self.settings.fit)
            if not np.isfinite(fitted.params).all():
                return self._estimate, cost, iterations, f"non-finite pose fitting {self.body.part_names[part]}"
            estimate = fitted.params
            cost[part], iterations[part] = fitted.cost, fitted.iterations
        return estimate, cost, iterations, None

    def _pair_points(self, pairs: MeshPairs, vertices: np.ndarray) -> np.ndarray:
        """The pairs' points on the estimate's posed ``vertices``: their faces at their barycentric coordinates."""
        return pairs.points(vertices, self.body.faces)

    def _sample_motion(self, parts: np.ndarray, samples: np.ndarray, motion: np.ndarray) -> np.ndarray:
        return motion[samples]  # a sample is named by its vertex

    def _new_pairs(
        self,
        camera: Camera,
        features: FeatureFrame,
        unpaired: np.ndarray,
        regions: np.ndarray | None,
        visible: VisibleSamples,
        pairs: MeshPairs,
        vertices: np.ndarray,
    ) -> MeshPairs:
        """Each unpaired feature on the part whose region holds it (without regions, the part of the nearest
        sample facing the camera, hidden or not), at the point under it (`_under_features`); a sample pairs once
        per view: the first feature takes it."""
        part_of = regions
        if part_of is None:
            nearest = cKDTree(visible.uv).query(features.points)[1] if len(visible) else None
            part_of = visible.part[nearest] if nearest is not None else np.full(len(features.ids), -1)
        offered = np.flatnonzero(unpaired & (part_of >= 0))
        new = self._under_features(camera, vertices, features.ids[offered], features.points[offered], part_of[offered])
        keys = sample_keys(new.parts, new.samples)
        _, first = np.unique(keys, return_index=True)
        fresh = np.zeros(len(new), bool)
        fresh[first] = True
        return new.subset(fresh & ~members(keys, sample_keys(pairs.parts, pairs.samples)))

    def _under_features(
        self, camera: Camera, vertices: np.ndarray, feature_ids: np.ndarray, points: np.ndarray, parts: np.ndarray
    ) -> MeshPairs:
        """New pairs of features at ``points`` on ``parts``: each at the point of its part's surface under the
        feature, its sample the hit face's corner nearest that point (a ray that misses the part makes no pair)."""
        faces, barycentric = np.full(len(points), -1), np.zeros((len(points), 3))
        for part in np.unique(parts):
            mine = parts == part
            own = self._part_faces[part]
            hit, barycentric[mine] = ray_hits(camera, points[mine], vertices, self.body.faces[own])
            faces[mine] = np.where(hit >= 0, own[hit], -1)
        kept = faces >= 0
        faces, barycentric = faces[kept], barycentric[kept]
        seeds = self.body.faces[faces, np.argmax(barycentric, axis=1)]
        return MeshPairs(feature_ids[kept], parts[kept], seeds, faces, barycentric)
