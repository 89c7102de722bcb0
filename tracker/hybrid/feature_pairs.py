"""The hybrid's feature pairs: paper 1's pairs of image features and points of the body's surface, renewed every
frame, for the fit to follow the textured skin where a silhouette cannot tell how a part turned.

Per view a `FeatureTracker` follows corners through the images (Shi-Tomasi, pyramidal Lucas-Kanade). Once a frame
is fitted, every live feature at least ``margin_px`` inside that view's observed silhouette is anchored to the
fitted body (`FeaturePairs.anchor`): to the face its viewing ray meets first (the front one: the estimate's own
occlusion decides what the view sees) at the hit's barycentric coordinates (`tracker.abis.mesh_pairs.ray_hits`).
The next frame, each anchored feature that was tracked makes a pair (`ViewPairs`): the anchor's point on the posed
body should project to where the feature is now. A corner on the silhouette's outline is the body against the
backdrop, no point of the skin (it slides along the outline as the body turns): hence the margin. A plain skin has
few corners inside its silhouette and makes few pairs; ``model.texture_seed`` textures it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from tracker.abis.mesh_pairs import ray_hits
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.observe.features import FeatureSettings, FeatureTracker
from tracker.ranges import NonNegative, Positive
from tracker.settings import validate
from tracker.threads import TwoEndedJobs

NEAREST_FACES = 64  # the faces each feature's ray is tried against (the nearest its pixel: `ray_hits`)


@dataclass(frozen=True)
class FeaturePairSettings:
    """How much the feature pairs count in the fit (``weight``: against one silhouette term; 0 leaves them out)
    and which features pair (at least ``margin_px`` inside the silhouette), their residuals Huber-robust beyond
    ``robust_px``."""

    # On the benchmark split's validation clips (100 frames each), with 3 cameras 1 did better than 0 on each clip
    # and than 4; with one camera 0 did better than 1 on 2 of 3 (experiment=hybrid_paper_scale sets 0).
    weight: NonNegative = 1.0
    robust_px: Positive = 2.0
    margin_px: NonNegative = 3.0
    features: FeatureSettings = field(default_factory=lambda: FeatureSettings(max_features=200))

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, eq=False)
class ViewPairs:
    """One view's pairs: ``faces`` ``(k,)`` rows of the body's faces, ``barycentric`` ``(k, 3)`` in each (the point
    on the body) and ``pixels`` ``(k, 2)`` where the point's feature is this frame."""

    faces: np.ndarray
    barycentric: np.ndarray
    pixels: np.ndarray

    @classmethod
    def empty(cls) -> ViewPairs:
        return cls(np.empty(0, np.int64), np.empty((0, 3)), np.empty((0, 2)))

    def __len__(self) -> int:
        return len(self.faces)


@dataclass(frozen=True, eq=False)
class _Anchors:
    """A view's features anchored to the body: their ids, faces and barycentric coordinates."""

    ids: np.ndarray
    faces: np.ndarray
    barycentric: np.ndarray


class FeaturePairs:
    """The features of ``cameras``' images, paired with the points of ``body`` under them one frame before."""

    def __init__(self, body: BodyMesh, cameras: Sequence[Camera], settings: FeaturePairSettings) -> None:
        self.body, self.cameras, self.settings = body, tuple(cameras), settings
        self.trackers = [FeatureTracker(settings.features) for _ in self.cameras]
        self.frames = [None] * len(self.cameras)
        self.anchors: list[_Anchors | None] = [None] * len(self.cameras)

    def pairs(self, images: Sequence[np.ndarray]) -> list[ViewPairs]:
        """This frame's pairs per view (``images``: RGB, in the cameras' order): each tracked feature with an
        anchor, at its new pixel. The views are shared with the worker threads (OpenCV's tracking frees the GIL)."""
        if len(images) != len(self.trackers):
            raise ValueError(f"{len(images)} images for {len(self.trackers)} views")
        return TwoEndedJobs(
            [functools.partial(self._view_pairs, view, image) for view, image in enumerate(images)]
        ).results()

    def _view_pairs(self, view: int, image: np.ndarray) -> ViewPairs:
        frame = self.frames[view] = self.trackers[view].step(image)
        anchors = self.anchors[view]
        if anchors is None:
            return ViewPairs.empty()
        _, here, there = np.intersect1d(frame.ids[frame.tracked], anchors.ids, return_indices=True)
        return ViewPairs(anchors.faces[there], anchors.barycentric[there], frame.points[frame.tracked][here])

    def anchor(self, pose: np.ndarray, inside_px: Sequence) -> None:
        """Anchor this frame's live features to the body posed as ``pose``: those at least ``margin_px`` inside
        the silhouette (``inside_px``: per view, a function of pixels ``(n, 2)`` giving their distance inside it).
        The views are shared with the worker threads (the rays' compiled loop frees the GIL)."""
        vertices = self.body.posed_vertices(pose)
        TwoEndedJobs(
            [functools.partial(self._view_anchors, view, vertices, inside_px[view]) for view in range(len(self.frames))]
        ).results()

    def _view_anchors(self, view: int, vertices: np.ndarray, inside_px: Callable[[np.ndarray], np.ndarray]) -> None:
        frame = self.frames[view]
        if frame is None:
            return
        kept = inside_px(frame.points) >= max(self.settings.margin_px, 1e-9)
        faces, barycentric = ray_hits(self.cameras[view], frame.points[kept], vertices, self.body.faces, NEAREST_FACES)
        hit = faces >= 0
        self.anchors[view] = _Anchors(frame.ids[kept][hit], faces[hit], barycentric[hit])

    def forget(self) -> None:
        """No anchors: a frame without a fitted pose makes no pairs the next frame."""
        self.anchors = [None] * len(self.cameras)
