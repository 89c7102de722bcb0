"""A synthetic sequence: the scene's truth motion -> rendered views, frame by frame, with per-stage timings.

`simulate` is the loop every run drives; a tracker sees only each `RenderedFrame`'s observation. It logs nothing:
results go to whoever iterates (the recording and the tables in `experiments`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence

import numba
import numpy as np

from tracker.geometry.cameras import Camera, wholly_in_view
from tracker.protocol import Model, RenderedFrame, Scene
from tracker.render.nuisance import SensorNuisance
from tracker.render.offscreen import RenderedView, SceneRenderer


def simulate(
    model: Model,
    scene: Scene,
    cameras: Sequence[Camera],
    renderer: SceneRenderer,
    frames: int,
    nuisance: SensorNuisance | None = None,
    rng: np.random.Generator | None = None,
) -> Iterator[RenderedFrame]:
    """Yield frames ``0 .. frames - 1`` of the ``scene``'s motion of ``model``, rendered from every camera; with a
    ``nuisance`` (and its ``rng``) the RGB images are what a real camera would give (depth and labels stay exact)."""
    n_parts = len(model.part_names)
    for frame in range(frames):
        start = time.perf_counter()
        truth = scene.params(model, frame)
        meshes = model.surface_meshes(truth)
        posed = time.perf_counter()
        views = renderer.render(cameras, meshes)
        if nuisance is not None:
            views = {
                name: RenderedView(nuisance.apply(view.rgb, frame, rng), view.depth, view.labels)
                for name, view in views.items()
            }
        rendered = time.perf_counter()
        yield RenderedFrame(
            frame=frame,
            truth=truth,
            meshes=meshes,
            views=views,
            visible_px={name: label_areas(view.labels, n_parts) for name, view in views.items()},
            in_view={name: wholly_in_view(view.labels) for name, view in views.items()},
            timings_ms={"pose": 1e3 * (posed - start), "render": 1e3 * (rendered - posed)},
        )


def background_frames(
    cameras: Sequence[Camera],
    renderer: SceneRenderer,
    count: int,
    nuisance: SensorNuisance | None,
    rng: np.random.Generator | None,
) -> dict[str, np.ndarray]:
    """Per camera ``(count, h, w, 3)`` images of the empty scene (frames -count .. -1): what a background model
    learns from before the subject walks in."""
    empty = renderer.render(cameras, [])
    return {
        name: np.stack(
            [view.rgb if nuisance is None else nuisance.apply(view.rgb, frame, rng) for frame in range(-count, 0)]
        )
        for name, view in empty.items()
    }


def label_areas(labels: np.ndarray, n_parts: int) -> np.ndarray:
    """``(n_parts,)`` pixel counts of labels 1..n_parts in a label image (paper 2's A_j, eq 3); ``(n, n_parts)`` for
    ``(n, h, w)`` images."""
    labels = np.asarray(labels)
    images = np.ascontiguousarray(labels.reshape(-1, labels.shape[-2] * labels.shape[-1]))
    counts = _label_counts(images, n_parts)
    return counts[0] if labels.ndim == 2 else counts


@numba.njit(cache=True, nogil=True)
def _label_counts(images: np.ndarray, n_parts: int) -> np.ndarray:
    """`label_areas` of ``(n, pixels)`` label images: ``(n, n_parts)``, the pixels of labels 1..n_parts (a label
    beyond them is none of theirs)."""
    counts = np.zeros((len(images), n_parts + 1), np.int64)
    for i in range(len(images)):
        for label in images[i]:
            if label <= n_parts:
                counts[i, label] += 1
    return counts[:, 1:]
