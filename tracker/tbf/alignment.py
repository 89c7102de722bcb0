"""The observed silhouette moved into the sample set's frame (`TbfSettings.align`).

Pose samples are postures in place: every sample's root stands over the same point, so every sample's feet land
in about the same place in the image. A person stands wherever he stands and steps about; unaligned, a few
pixels of offset outweigh the arm's whole contribution to the silhouette distance. ``align="feet"`` finds the
feet in the observed silhouette — the median column and the lowest row of its bottom `FEET_BAND` — and shifts the
silhouette by whole pixels onto the samples' typical feet (the median over `ANCHOR_SAMPLES` of them, kept with
the set). The estimate's root is moved back by the same shift, at the root's depth: a step seen by the camera is
tracked as a step.

``align="ground"`` (`GroundPlacement`) places the person on the floor by the calibrated camera. A reference sample
(the last estimate's: the nearest posture known) stands on the samples' spot, its feet where the ray through their
lowest rows meets the ground (P_ref). The ray through the person's feet meets the ground where he stands (P_o).
His silhouette is scaled about its feet by the ratio of their depths (``scale``) and moved onto the reference's
feet, as if he stood on the samples' spot (a person walking towards the camera grows in the image). The filter's
best sample is then moved across the image until its silhouette's centroid is the placed silhouette's; the pixel
its root then covers, taken back into the observed image, and ``scale`` times the sample root's depth give the
estimate's root (its height stays the sample's, whose feet are on the floor). The estimate is turned about the
vertical by the person's bearing from the camera against the sample's: off the camera's axis a person is seen
from the side by that angle. At a camera 0.9 m high and 4.5 m away one pixel row of the feet spans 5 cm of floor,
and the toes or the heels are lowest by the stance: the depth is the weak part. (Scaling by the silhouettes'
areas instead did worse: a wrong arm posture changes the area.)

From two or more calibrated views (`ViewsPlacement`) the person stands where the rays through his silhouettes'
centroids cross (his spot), and each sample where its own cross (`sample_spots`: a posture's spot moves with its
limbs, by centimetres between neighbouring postures; every spot at one height, as every sample stands on the
floor however high its centroid). His silhouettes are
scaled and moved as if he stood on a reference sample's spot (the last estimate's); the filter then scores each
sample moved by whole pixels from where each view sees its own spot to where it sees the reference's
(`spot_pixels`), as if he had been placed on that sample's spot, and the estimate is moved across the floor until
its spot is his.

A view that sees him cut by its image's border (not `wholly_in_view`: part of him out of it) sees a centroid pulled
into the image. When two views see him whole, his spot is where their rays cross; else every view's that sees him
(with the point of one such view's ray nearest his last spot instead, tried on the validation clip martial_09, he
was held where he had been while he walked along that view's ray, 15-20 cm off; every view's rays, a cut one among
them, were within a few cm). A view that lost him altogether gives no ray and no silhouette (None: the filter
leaves it out); with one view left, his spot is the point of its ray nearest his last spot. (A cut silhouette
completed, beyond where its image ended, by the last estimate's: tried on martial_09, the errors of the frames with
a cut view grew, 128.7 -> 142.1 mm for tree filtering from three cameras: the completion is as wrong as the last
estimate.)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from tracker.geometry.cameras import Camera, wholly_in_view
from tracker.models.body_skeleton import turned_about_vertical
from tracker.tbf.samples import LEVEL_RESOLUTIONS, PoseSampleSet, SampleViews
from tracker.tbf.scoring import SilhouetteStack

FEET_BAND = 0.06  # the bottom this fraction of a silhouette's height holds the feet
ANCHOR_SAMPLES = 200  # samples whose feet give the set's anchor, picked evenly through it


def silhouette_centroid(mask: np.ndarray) -> tuple[float, float] | None:
    """The mean ``(u, v)`` of a silhouette's pixels (None: empty), from whole-number sums of their coordinates (as
    the image moments m10, m01 over m00): the same bits as the mean of its pixels' coordinates, without listing
    them."""
    count, u_sum, v_sum = _coordinate_sums(np.ascontiguousarray(mask, dtype=bool))
    if count == 0:
        return None
    return u_sum / count, v_sum / count


@numba.njit(cache=True, nogil=True)
def _coordinate_sums(mask: np.ndarray) -> tuple[int, int, int]:
    """The number of a bool image's true pixels and the sums of their columns and of their rows."""
    count = u_sum = v_sum = 0
    for v in range(mask.shape[0]):
        for u in range(mask.shape[1]):
            if mask[v, u]:
                count += 1
                u_sum += u
                v_sum += v
    return count, u_sum, v_sum


def feet_anchor(mask: np.ndarray) -> tuple[float, float] | None:
    """``(u, v)`` pixels of the feet in a ``(h, w)`` bool silhouette (None when it is empty)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        return None
    band = max(1, int(round(FEET_BAND * (rows[-1] - rows[0] + 1))))
    columns = np.flatnonzero(mask[rows[-1] - band + 1 : rows[-1] + 1].any(axis=0))
    return float(np.median(columns)), float(rows[-1])


def sample_anchors(samples: PoseSampleSet) -> np.ndarray:
    """``(n, 2)``: each sample's anchor ``(u, v)`` at the finest resolution (full-image pixels): its silhouette's
    centroid column over its lowest row. A person and his mirror image through the plane facing the camera look
    alike in one silhouette, but put their nearer foot, lowest in the image, at opposite sides: anchored on his feet's
    column, a silhouette placed on one sample's anchor looks like that sample's side. The centroid's column does not
    take a side. (A sample the window does not show: the samples' mean anchor.)"""
    stack = samples.silhouettes(LEVEL_RESOLUTIONS[-1])
    (_, width), (u0, v0, u1, v1), runs = stack.shape, stack.window, stack.runs
    centroids, seen = stack_centroids(stack)
    last = np.maximum(runs.ptr[1:] - 1, 0)  # each silhouette's last run, in row-major order: its lowest row's
    anchors = np.stack([centroids[:, 0], (np.asarray(runs.ends)[last] - 1) // width + v0], axis=1).astype(np.float64)
    anchors[~seen] = anchors[seen].mean(axis=0) if seen.any() else [(u0 + u1) / 2, v1 - 1]
    return anchors


def stack_centroids(stack: SilhouetteStack) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 2)`` each silhouette's centroid ``(u, v)`` in full-image pixels of its resolution, from the sums of its
    runs, and ``(n,)`` whether it has any pixel; an empty one gets the mean centroid of all the pixels (the window's
    centre when every one is empty)."""
    u0, v0, u1, v1 = stack.window
    columns, rows = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    count = stack.runs.sums(np.ones(columns.size))
    sums = np.stack([stack.runs.sums(columns.ravel()), stack.runs.sums(rows.ravel())], axis=1)
    seen = count > 0
    sums[~seen] = (sums[seen].sum(axis=0) / count[seen].sum()) if seen.any() else [(u0 + u1) / 2, (v0 + v1) / 2]
    return sums / np.where(seen, count, 1.0)[:, None], seen


def samples_anchor(samples: PoseSampleSet) -> tuple[float, float]:
    """The samples' typical feet ``(u, v)`` at the finest resolution (full-image pixels), kept with the set."""
    resolution = LEVEL_RESOLUTIONS[-1]

    def anchor(axis: int) -> float:
        stack = samples.silhouettes(resolution)
        u0, v0 = stack.window[:2]
        picked = np.unique(np.linspace(0, len(samples) - 1, min(ANCHOR_SAMPLES, len(samples))).astype(int))
        anchors = [feet_anchor(stack.mask(index)) for index in picked]
        return float(np.median([a[axis] for a in anchors if a is not None])) + (u0, v0)[axis]

    return (
        samples.derived(f"feet anchor u {ANCHOR_SAMPLES}", lambda: anchor(0)),
        samples.derived(f"feet anchor v {ANCHOR_SAMPLES}", lambda: anchor(1)),
    )


def shifted(mask: np.ndarray, du: int, dv: int) -> np.ndarray:
    """``mask`` moved ``du`` pixels right and ``dv`` down; what leaves the image is lost, what enters is empty."""
    out = np.zeros_like(mask)
    h, w = mask.shape
    src_v, dst_v = slice(max(-dv, 0), min(h - dv, h)), slice(max(dv, 0), min(h + dv, h))
    src_u, dst_u = slice(max(-du, 0), min(w - du, w)), slice(max(du, 0), min(w + du, w))
    out[dst_v, dst_u] = mask[src_v, src_u]
    return out


def world_offset(camera: Camera, point: np.ndarray, du: float, dv: float) -> np.ndarray:
    """The world displacement (m) parallel to the image plane that moves ``point``'s projection by ``(du, dv)``
    pixels, at ``point``'s depth."""
    depth = camera.world_to_camera(np.asarray(point, dtype=np.float64)[None])[0, 2]
    return camera.rotation @ np.array([du * depth / camera.fx, dv * depth / camera.fy, 0.0])


def ground_point(camera: Camera, u: float, v: float) -> np.ndarray | None:
    """Where the ray through pixel ``(u, v)`` meets the ground z = 0 (None when it never does)."""
    ray = camera.rotation @ np.array([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0])
    if ray[2] >= 0 or camera.position[2] <= 0:
        return None
    return camera.position - camera.position[2] / ray[2] * ray


def scaled_onto(mask: np.ndarray, scale: float, source: Sequence[float], target: Sequence[float]) -> np.ndarray:
    """``mask`` scaled by ``scale`` about pixel ``source`` and moved so that ``source`` lands on ``target`` (bilinear,
    inside where at least half covered)."""
    (u, v), (a, b) = source, target
    warp = np.array([[scale, 0.0, a - scale * u], [0.0, scale, b - scale * v]])
    return cv2.warpAffine(mask.astype(np.float32), warp, mask.shape[::-1], flags=cv2.INTER_LINEAR) >= 0.5


@dataclass(frozen=True)
class Placement:
    """One frame's placement of the observed person: his silhouette in the samples' frame."""

    silhouette: np.ndarray
    scale: float  # the silhouette's magnification into the samples' frame
    feet: tuple[float, float]  # the observed feet's pixel (finest level; with anchors, the anchor's) ...
    reference_feet: tuple[float, float]  # ... and the reference's they were moved onto

    def to_observed(self, pixel: np.ndarray) -> np.ndarray:
        """A pixel of the placed silhouette back in the observed image (finest level)."""
        return (np.asarray(pixel, dtype=np.float64) - self.reference_feet) / self.scale + self.feet


class GroundPlacement:
    """``align="ground"`` (see the module docstring) for ``camera`` and a sample set. The feet the silhouette is
    moved onto are those of the last estimate's sample (``reference``; at first the sample nearest the initial
    pose): the feet's lowest rows are the toes or the heels by how the body stands and turns, so the spot they
    give moves by a foot's length with the posture, and the last estimate is the nearest posture known. With
    ``anchors`` (`sample_anchors`), the silhouette's centroid column over its feet's lowest row is moved onto the
    reference's anchor instead, and the filter scores every sample as if it had been moved onto the sample's own."""

    def __init__(
        self, camera: Camera, samples: PoseSampleSet, reference: int, anchors: np.ndarray | None = None
    ) -> None:
        self.camera, self.samples, self.reference, self.anchors = camera, samples, reference, anchors
        self.stack = samples.silhouettes(LEVEL_RESOLUTIONS[-1])
        self.pixel = camera.width / LEVEL_RESOLUTIONS[-1][0]  # camera pixels per pixel of the finest level
        self._feet: dict[int, tuple[tuple[float, float], np.ndarray | None]] = {}
        self._centroids: dict[int, tuple[float, float] | None] = {}

    def feet(self, sample: int) -> tuple[tuple[float, float], np.ndarray | None]:
        """A sample's feet: their pixel ``(u, v)`` at the finest level and where they meet the ground (None: above
        the horizon). Every sample is in view (the window holds them all), so every one has feet."""
        if sample not in self._feet:
            u0, v0 = self.stack.window[:2]
            u, v = feet_anchor(self.stack.mask(sample))
            pixel = (u + u0, v + v0)
            self._feet[sample] = pixel, ground_point(self.camera, *(self.pixel * np.asarray(pixel)))
        return self._feet[sample]

    def centroid(self, sample: int) -> tuple[float, float] | None:
        """A sample's silhouette centroid ``(u, v)`` in its window's pixels at the finest level (None: empty)."""
        if sample not in self._centroids:
            self._centroids[sample] = silhouette_centroid(self.stack.mask(sample))
        return self._centroids[sample]

    def place(self, observed: np.ndarray) -> Placement | None:
        """The observed silhouette (finest level) scaled and moved onto the reference sample's feet (None: nobody
        in view, the feet cut by the image's bottom edge, or either's feet above the horizon)."""
        feet = feet_anchor(observed)
        if feet is None or feet[1] >= observed.shape[0] - 1:
            return None
        ground = ground_point(self.camera, *(self.pixel * np.asarray(feet)))
        (a, b), reference_ground = self.feet(self.reference)
        if ground is None or reference_ground is None:
            return None
        depths = self.camera.world_to_camera(np.array([ground, reference_ground]))[:, 2]
        scale = float(depths[0] / depths[1])
        if self.anchors is not None:
            feet = (silhouette_centroid(observed)[0], feet[1])
            a, b = map(float, self.anchors[self.reference])
        return Placement(scaled_onto(observed, scale, feet, (a, b)), scale, feet, (a, b))

    def pose(self, sample: int, placement: Placement) -> np.ndarray:
        """The estimate: sample ``sample`` placed where the observed silhouette says (see the module docstring);
        it becomes the next frame's reference."""
        self.reference = sample
        pose = np.asarray(self.samples.poses[sample], dtype=np.float64).copy()
        u0, v0 = self.stack.window[:2]
        centroid, placed = self.centroid(sample), silhouette_centroid(placement.silhouette)
        if centroid is None or placed is None:
            return pose
        # The sample's silhouette moved onto the placed one's centroid: where its root then is, seen back in the
        # observed image, on the ray through that pixel at the depth the placement's scale says.
        shift = np.array([placed[0] - centroid[0] - u0, placed[1] - centroid[1] - v0])
        root_pixel, root_depth = self.camera.project(pose[None, :3])
        seen = self.pixel * placement.to_observed(root_pixel[0] / self.pixel + shift)
        ray = np.array([(seen[0] - self.camera.cx) / self.camera.fx, (seen[1] - self.camera.cy) / self.camera.fy, 1.0])
        root = self.camera.position + self.camera.rotation @ (placement.scale * root_depth[0] * ray)
        pose = turned_about_vertical(pose, self._bearing(root) - self._bearing(pose[:3]))
        pose[:2] = root[:2]  # the height stays the sample's: its feet are on the floor
        return pose

    def _bearing(self, point: np.ndarray) -> float:
        """The direction (radians about the vertical) from the camera to a point."""
        offset = point - self.camera.position
        return float(np.arctan2(offset[1], offset[0]))


def nearest_to_rays(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The point nearest (least squares) to every ray ``origins[k] + t directions[k]``: ``sum_k (I - d_k d_k^T)``
    solved against ``sum_k (I - d_k d_k^T) o_k``; for ``(n, k, 3)`` bundles of rays, ``(n, 3)``. Needs two rays
    that are not parallel."""
    directions = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    projectors = np.eye(3) - directions[..., :, None] * directions[..., None, :]
    right = np.einsum("...kij,...kj->...i", projectors, np.broadcast_to(origins, directions.shape))
    return np.linalg.solve(projectors.sum(axis=-3), right[..., None])[..., 0]


def centroid_rays(cameras: Sequence[Camera], centroids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each view's ray through its silhouette's centroid, ``centroids`` ``(..., views, 2)`` in finest-level
    pixels: the cameras' positions ``(views, 3)`` and the directions ``(..., views, 3)``."""
    pixels = np.array([camera.width / LEVEL_RESOLUTIONS[-1][0] for camera in cameras])[:, None]
    full = centroids * pixels  # in the camera's own pixels
    intrinsics = np.array([(camera.cx, camera.cy, camera.fx, camera.fy) for camera in cameras])
    local = np.stack(
        [
            (full[..., 0] - intrinsics[:, 0]) / intrinsics[:, 2],
            (full[..., 1] - intrinsics[:, 1]) / intrinsics[:, 3],
            np.ones(full.shape[:-1]),
        ],
        axis=-1,
    )
    rotations = np.stack([camera.rotation for camera in cameras])
    return np.array([camera.position for camera in cameras]), np.einsum("kab,...kb->...ka", rotations, local)


def sample_spots(cameras: Sequence[Camera], samples: SampleViews) -> np.ndarray:
    """``(n, 3)``: each sample's spot, where on the floor it stands: where its views' centroid rays cross (the
    samples' roots stand over one point, but a posture's spot moves with its limbs: arms raised to one side move it
    that way), brought to one height, the crossings' median. How high the crossing lies is how high the posture's
    centroid is (a squat's is lower than a stand's); every sample stands on the floor, so a sample moved onto the
    reference's spot must move across the image, not up or down it. At its own height, a sample would be lifted or
    lowered to the reference's centroid: on a clip that squats (indian_14), the squatting sample nearest the truth
    11 pixels off the floor at 320x240, its distance in each view three to four times that on the floor."""
    # a sample a view does not see at all: the mean centroid (its silhouette is empty anyway)
    centroids = [stack_centroids(stack)[0] for stack in samples.silhouettes(LEVEL_RESOLUTIONS[-1])]
    spots = nearest_to_rays(*centroid_rays(cameras, np.stack(centroids, axis=1)))
    spots[:, 2] = np.median(spots[:, 2])
    return spots


def spot_pixels(cameras: Sequence[Camera], spots: np.ndarray, resolution: tuple[int, int]) -> np.ndarray:
    """``(n, views, 2)``: where each view sees each of ``spots`` ``(n, 3)``, in pixels of ``resolution``. A sample
    is scored as if it stood where the observation is placed: moved by the reference's pixel minus its own
    (`tracker.tbf.filter.TreeFilter`)."""
    seen = []
    for camera in cameras:
        uv, _ = camera.project(spots)
        seen.append(uv * (resolution[0] / camera.width))
    return np.stack(seen, axis=1)


class ViewsPlacement:
    """``align="ground"`` from two or more calibrated views (see the module docstring). ``reference``: the sample
    whose spot the observation is placed on (the last estimate's; at first the initial prior's); ``spots``: every
    sample's (`sample_spots`)."""

    def __init__(
        self, cameras: Sequence[Camera], samples: SampleViews, reference: int, spots: np.ndarray | None = None
    ) -> None:
        self.cameras, self.samples, self.reference = tuple(cameras), samples, reference
        self.spots = sample_spots(self.cameras, samples) if spots is None else spots
        self.pixels = [camera.width / LEVEL_RESOLUTIONS[-1][0] for camera in self.cameras]
        self.last_spot: np.ndarray | None = None  # where the person stood at the last frame placed

    def spot(self, sample: int) -> np.ndarray:
        """Where a sample stands (`sample_spots`)."""
        return self.spots[sample]

    def place(self, observed: Sequence[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray] | None:
        """Each view's silhouette (finest level) as if the person stood on the reference's spot (None for a view
        that lost him), and his offset from it across the floor (None: no view sees him)."""
        centroids = []
        for mask in observed:
            centroid = silhouette_centroid(mask)
            centroids.append(np.full(2, np.nan) if centroid is None else np.array(centroid))
        seen = ~np.isnan(np.array(centroids)[:, 0])
        spot = self.spot(self.reference)
        whole = np.array([wholly_in_view(mask) for mask in observed])
        person = self.person_spot(centroid_rays(self.cameras, np.array(centroids)), whole, seen)
        if person is None:
            return None
        self.last_spot = person
        offset = np.array([*(self.last_spot - spot)[:2], 0.0])
        placed = []
        for view, (camera, pixel, mask) in enumerate(zip(self.cameras, self.pixels, observed, strict=True)):
            (there, here), depths = camera.project(np.array([spot + offset, spot]))
            scale = float(depths[0] / depths[1])
            placed.append(scaled_onto(mask, scale, there / pixel, here / pixel) if seen[view] else None)
        return placed, offset

    def person_spot(
        self, rays: tuple[np.ndarray, np.ndarray], whole: np.ndarray, seen: np.ndarray
    ) -> np.ndarray | None:
        """Where the person stands, from each view's centroid ``rays``: the crossing of the views that see him
        ``whole`` when two do, else of those that see some of him (``seen``), or the point of the one such view's
        ray nearest his last spot (see the module docstring); None when no view sees him."""
        origins, directions = rays
        usable = whole if whole.sum() >= 2 else seen
        if usable.sum() >= 2:
            return nearest_to_rays(origins[usable], directions[usable])
        if usable.sum() == 1 and self.last_spot is not None:
            (origin,), (direction,) = origins[usable], directions[usable]
            return origin + direction * ((self.last_spot - origin) @ direction) / (direction @ direction)
        return None

    def pose(self, sample: int, offset: np.ndarray) -> np.ndarray:
        """The estimate: sample ``sample`` moved across the floor until its spot is the person's (``offset`` from
        the reference's spot, as `place` gave it); it becomes the next reference."""
        own = self.spot(self.reference) - self.spot(sample)
        self.reference = sample
        pose = np.asarray(self.samples.poses[sample], dtype=np.float64).copy()
        pose[:2] += offset[:2] + own[:2]  # his height: the sample's
        return pose
