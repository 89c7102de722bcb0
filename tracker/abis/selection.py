"""How AbIS selects model points by the model's image (paper 1, steps 3-4), and the ablation without it: one
interface, two strategies, chosen by ``tracker.selection`` (`selection_of`).

A strategy says whether the estimate is rendered (`zbuffers`), which samples a view sees (`visible`), which pairs
are still seen after the fit and where they project (`seen`), and which part's region holds each feature
(`regions`: where a new pair may form).
    `ModelImage` (``zbuffer``, the paper's): a z-buffer render of the estimate decides; a pair is also dropped
                 when another part's edge is about to reach it, and a feature pairs only inside a part's region,
                 away from silhouettes and occlusion edges (`tracker.abis.visibility`).
    `BackFaces`  (``none``): no model image at all; a sample counts when it faces the camera, a pair while its
                 point projects inside the image, and a feature may pair with any part, as bottom-up tracking would.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from tracker.abis.settings import AbisSettings
from tracker.abis.visibility import (
    VisibleSamples,
    facing_samples,
    in_image,
    reached_by_other_parts,
    region_labels_at,
    visible_mask,
    visible_samples,
)
from tracker.geometry.cameras import Camera
from tracker.render.offscreen import DepthLabels


class ModelImage:
    """Selection by the z-buffer render of the estimate (``selection=zbuffer``)."""

    uses_model_image = True

    def __init__(self, settings: AbisSettings) -> None:
        self.settings = settings

    def zbuffers(
        self, cameras: Sequence[Camera], render: Callable[[], Mapping[str, DepthLabels]]
    ) -> Mapping[str, DepthLabels]:
        """Per view the estimate's z-buffer and label image (``render`` draws them)."""
        return render()

    def visible(
        self,
        camera: Camera,
        zbuffer: DepthLabels,
        samples: Sequence[np.ndarray],
        normals: Callable[[], Sequence[np.ndarray]],
    ) -> VisibleSamples:
        """Each part's samples (world points, part by part) that the view's z-buffer shows."""
        return visible_samples(camera, zbuffer, samples)

    def seen(
        self,
        camera: Camera,
        zbuffer: DepthLabels,
        parts: np.ndarray,
        points: np.ndarray,
        motion: np.ndarray,
        visible: VisibleSamples,
        visible_motion: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Which pairs (their ``parts`` and world ``points``, moving ``motion`` px a frame) the view still sees,
        and their pixels: visible in the z-buffer, and no other part's visible sample (moving ``visible_motion``)
        about to reach them."""
        seen, uv = visible_mask(camera, zbuffer, parts, points)
        seen[seen] = ~reached_by_other_parts(
            uv[seen],
            parts[seen],
            motion[seen],
            visible,
            visible_motion,
            self.settings.occlusion_margin_px,
            self.settings.features.window_px,
        )
        return seen, uv

    def regions(self, zbuffer: DepthLabels, points: np.ndarray) -> np.ndarray:
        """Per feature at ``points`` ``(n, 2)``, the part whose region holds it (-1: none): a part's label away
        from its silhouette and from where another part meets it, whose corners are no material point of either."""
        pixel = np.rint(points).astype(int)
        settings = self.settings
        labels = region_labels_at(
            zbuffer.labels, pixel[:, 1], pixel[:, 0], settings.occlusion_margin_px, settings.boundary_margin_px
        )
        return labels.astype(int) - 1


class BackFaces:
    """No model image (``selection=none``, the ablation): the back-face test alone, blind to other parts."""

    uses_model_image = False

    def zbuffers(self, cameras: Sequence[Camera], render: Callable[[], Mapping[str, DepthLabels]]) -> dict[str, None]:
        """Nothing rendered: no view has a z-buffer."""
        return dict.fromkeys(camera.name for camera in cameras)

    def visible(
        self,
        camera: Camera,
        zbuffer: None,
        samples: Sequence[np.ndarray],
        normals: Callable[[], Sequence[np.ndarray]],
    ) -> VisibleSamples:
        """Each part's samples that project inside the image with their outward normals (part by part, from
        ``normals``) toward the camera."""
        return facing_samples(camera, samples, normals())

    def seen(
        self,
        camera: Camera,
        zbuffer: None,
        parts: np.ndarray,
        points: np.ndarray,
        motion: None,
        visible: VisibleSamples,
        visible_motion: None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pairs whose point projects inside the image, and their pixels: nothing is discarded for occlusion."""
        return in_image(camera, points)

    def regions(self, zbuffer: None, points: np.ndarray) -> None:
        """No region: a feature may pair with any part."""
        return None


Selection = ModelImage | BackFaces


def selection_of(settings: AbisSettings) -> Selection:
    """The strategy ``settings.selection`` names."""
    return ModelImage(settings) if settings.selection == "zbuffer" else BackFaces()
