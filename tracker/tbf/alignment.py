"""The observed silhouette moved into the sample set's frame (`TbfSettings.align`).

Pose samples are postures in place: every sample's root stands over the same point, so every sample's feet land
in about the same place in the image. A person stands wherever he stands and steps about; unaligned, a few
pixels of offset outweigh the arm's whole contribution to the silhouette distance. ``align="feet"`` finds the
feet in the observed silhouette — the median column and the lowest row of its bottom `FEET_BAND` — and shifts the
silhouette by whole pixels onto the samples' typical feet (the median over `ANCHOR_SAMPLES` of them, kept with
the set). The estimate's root is moved back by the same shift, at the root's depth: a step seen by the camera is
tracked as a step.
"""

from __future__ import annotations

import numpy as np

from tracker.geometry.cameras import Camera
from tracker.tbf.samples import LEVEL_RESOLUTIONS, PoseSampleSet

FEET_BAND = 0.06  # the bottom this fraction of a silhouette's height holds the feet
ANCHOR_SAMPLES = 200  # samples whose feet give the set's anchor, picked evenly through it


def feet_anchor(mask: np.ndarray) -> tuple[float, float] | None:
    """``(u, v)`` pixels of the feet in a ``(h, w)`` bool silhouette (None when it is empty)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        return None
    band = max(1, int(round(FEET_BAND * (rows[-1] - rows[0] + 1))))
    columns = np.flatnonzero(mask[rows[-1] - band + 1 : rows[-1] + 1].any(axis=0))
    return float(np.median(columns)), float(rows[-1])


def samples_anchor(samples: PoseSampleSet) -> tuple[float, float]:
    """The samples' typical feet ``(u, v)`` at the finest resolution (full-image pixels), kept with the set."""
    resolution = LEVEL_RESOLUTIONS[-1]

    def anchor(axis: int) -> float:
        stack = samples.silhouettes(resolution)
        u0, v0 = stack.window[:2]
        picked = np.unique(np.linspace(0, len(samples) - 1, min(ANCHOR_SAMPLES, len(samples))).astype(int))
        anchors = [feet_anchor(stack.mask(index)) for index in picked]
        return float(np.median([a[axis] for a in anchors if a is not None])) + (u0, v0)[axis]

    return (samples.derived(f"feet anchor u {ANCHOR_SAMPLES}", lambda: anchor(0)),
            samples.derived(f"feet anchor v {ANCHOR_SAMPLES}", lambda: anchor(1)))  # fmt: skip


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
