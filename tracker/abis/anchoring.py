"""Anchoring pairs to the model's texture: which material point a paired feature really shows.

A new pair's surface point starts as the point of the *estimate* under the feature (`refine_surface_coordinates`):
wherever the estimate is off, the pair takes that error with it, the next fit keeps it, and errors accumulate into
drift. The model carries its texture, so the estimate can synthesise what the neighbourhood of that point should
look like: the texture, mapped through the estimate's local projection (the 2x2 Jacobian of pixels in eta and
omega) around the point. Matching the observed patch against that synthesised one (normalised cross-correlation,
blind to the shading's gain and offset) gives the pixel offset at which the estimate shows the feature's material
point; the pair is anchored there instead. A weak match, or one at the edge of the search, leaves the pair as it
was. A pair carried over is anchored again from time to time: a tracked feature slides off its material point as
the surface turns and deforms under it, and the pair would carry that drift too.

Texture convention (`tracker.models.dsq.mesh_topology`, as the renderer samples it): columns run with
``u = (omega + pi) / 2pi``, rows with ``1 - v``, ``v = (eta + pi/2) / pi`` (row 0 is the top pole, eta = pi/2).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import cv2
import numpy as np

from tracker.bilinear import bilinear
from tracker.ranges import Range

Score = Annotated[float, Range(-1.0, 1.0)]
HalfSide = Annotated[int, Range(1, 20)]
SUBPIXEL_ITERATIONS = 2  # Gauss-Newton steps on the shift after the whole-pixel search (a new pair)
REFINE_ITERATIONS = 1  # ... and from no shift (a pair anchored before: its feature moved a fraction of a pixel)


@dataclass(frozen=True)
class AnchorSettings:
    """Texture matching of pairs: the matched window, how far a new pair's material point may lie from where the
    estimate puts it, and the weakest correlation trusted."""

    half_window_px: HalfSide = 5  # the matched patch is (2h + 1) pixels square
    search_px: HalfSide = 4  # offsets up to this many pixels each way
    min_score: Score = 0.8  # normalised cross-correlation at the best offset


def observed_patches(observed_gray: np.ndarray, points: np.ndarray, settings: AnchorSettings) -> np.ndarray:
    """The ``(n, 2h + 1, 2h + 1)`` float64 patches of ``observed_gray`` (float32 grey) around ``points`` ``(n, 2)``,
    sampled at their sub-pixel positions: what `texture_offsets` matches."""
    side = 2 * settings.half_window_px + 1
    if len(points) == 0:
        return np.empty((0, side, side))
    return np.stack([cv2.getRectSubPix(observed_gray, (side, side), (float(x), float(y))) for x, y in points]).astype(
        np.float64
    )


def texture_offsets(
    patches: np.ndarray,
    eta: np.ndarray,
    omega: np.ndarray,
    jacobian: np.ndarray,
    textures: Sequence[np.ndarray],
    settings: AnchorSettings,
    search: bool | np.ndarray = True,
    texture_of: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """For features seen as ``patches`` (`observed_patches`, of any views) over the surface coordinates ``eta``,
    ``omega`` ``(n,)`` of the estimate, whose pixels move by ``jacobian`` ``(n, 2, 2)`` (d(u, v) / d(eta, omega)):
    the offsets ``(n, 2)`` in (eta, omega) to the material point the observed patch shows, and which matches were
    trusted ``(n,)``. ``textures`` are float32 grey images; ``texture_of`` ``(n,)``: each point's texture (None:
    the first). ``search`` (one for all, or ``(n,)``): look over whole pixels first (a new pair); without, only
    refine from no offset (a pair anchored before, whose feature drifts by a fraction of a pixel per frame)."""
    n = len(patches)
    h, r = settings.half_window_px, settings.search_px
    offsets, trusted = np.zeros((n, 2)), np.zeros(n, bool)
    usable = np.abs(np.linalg.det(jacobian)) > 1e-9 if n else np.zeros(0, bool)
    chosen = np.flatnonzero(usable)
    if len(chosen) == 0:
        return offsets, trusted
    to_surface = np.linalg.inv(jacobian[chosen])  # pixels -> (eta, omega)
    texture_of = np.zeros(n, int) if texture_of is None else np.asarray(texture_of)
    synthesise = _Synthesiser(textures, texture_of[chosen], eta[chosen], omega[chosen], to_surface)
    patches = patches[chosen]
    shift = np.zeros((len(chosen), 2))
    searched = np.flatnonzero(np.broadcast_to(search, (n,))[chosen])
    if len(searched):  # whole pixels: the best normalised cross-correlation over the search window
        around = _Synthesiser(
            textures, texture_of[chosen[searched]], eta[chosen[searched]], omega[chosen[searched]], to_surface[searched]
        )
        windows = np.lib.stride_tricks.sliding_window_view(
            around(shift[searched], h + r), (2 * h + 1, 2 * h + 1), axis=(1, 2)
        )  # (k, 2r + 1, 2r + 1, 2h + 1, 2h + 1)
        scores = _correlation(windows, patches[searched, None, None]).reshape(len(searched), -1)
        row, column = np.divmod(np.argmax(scores, axis=1), 2 * r + 1)
        shift[searched] = np.column_stack([column - r, row - r])
        # Gauss-Newton on the shift, with a gain and an offset for the shading: the searched ones first ...
        for _ in range(SUBPIXEL_ITERATIONS - REFINE_ITERATIONS):
            shift[searched] += _gauss_newton_step(around, shift[searched], patches[searched], h)[0]
    for _ in range(REFINE_ITERATIONS):  # ... then all
        step, score = _gauss_newton_step(synthesise, shift, patches, h)  # score: before the last step
        shift += step
    good = (score >= settings.min_score) & np.all(np.abs(shift) < r, axis=1)
    offsets[chosen[good]] = np.einsum("mij,mj->mi", to_surface[good], shift[good])
    trusted[chosen[good]] = True
    return offsets, trusted


class _Synthesiser:
    """The textures as the estimate shows them: ``(m, 2h + 1, 2h + 1)`` patches around each point's pixel plus a
    shift ``(m, 2)`` (pixels), through each point's affine map from pixels to (eta, omega), each from its texture
    (``texture_of``)."""

    def __init__(
        self,
        textures: Sequence[np.ndarray],
        texture_of: np.ndarray,
        eta: np.ndarray,
        omega: np.ndarray,
        to_surface: np.ndarray,
    ) -> None:
        self.textures, self.texture_of = textures, texture_of
        self.eta, self.omega, self.to_surface = eta, omega, to_surface
        shapes = np.array([texture.shape for texture in textures], dtype=np.float64).reshape(-1, 2)
        self.height, self.width = shapes[texture_of, 0, None], shapes[texture_of, 1, None]  # (m, 1): each point's

    def __call__(self, shift: np.ndarray, half: int) -> np.ndarray:
        steps = np.arange(2 * half + 1, dtype=np.float64) - half
        du, dv = np.meshgrid(steps, steps)  # columns u, rows v
        pixels = np.stack([du.ravel(), dv.ravel()])[None] + shift[:, :, None]  # (m, 2, side^2)
        repeat = len(shift) // len(self.eta)  # shifts may come stacked several times over the points
        to_surface = np.tile(self.to_surface, (repeat, 1, 1))
        surface = to_surface @ pixels
        height, width = np.tile(self.height, (repeat, 1)), np.tile(self.width, (repeat, 1))
        rows = (math.pi / 2 - np.tile(self.eta, repeat)[:, None] - surface[:, 0]) / math.pi * height - 0.5
        columns = (
            (np.tile(self.omega, repeat)[:, None] + surface[:, 1] + math.pi) / (2 * math.pi) * width - 0.5
        ) % width
        values = np.empty(rows.shape, np.result_type(*self.textures))  # map_coordinates keeps a texture's type
        texture_of = np.tile(self.texture_of, repeat)
        for index in np.unique(texture_of):
            mine = texture_of == index
            at = np.column_stack([columns[mine].ravel(), rows[mine].ravel()])  # (u, v)
            values[mine] = bilinear(self.textures[index][None], at)[:, 0].reshape(-1, rows.shape[1])
        return values.reshape(len(shift), 2 * half + 1, 2 * half + 1)


def _correlation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normalised cross-correlation over the last two axes (broadcast)."""
    a = a - a.mean(axis=(-2, -1), keepdims=True)
    b = b - b.mean(axis=(-2, -1), keepdims=True)
    energy = np.sum(a * a, axis=(-2, -1)) * np.sum(b * b, axis=(-2, -1))
    return np.sum(a * b, axis=(-2, -1)) / np.sqrt(np.maximum(energy, 1e-12))


def _gauss_newton_step(
    synthesise: _Synthesiser, shift: np.ndarray, patches: np.ndarray, h: int
) -> tuple[np.ndarray, np.ndarray]:
    """One step of the shift (m, 2) that best maps the synthesised patches, up to gain and offset, onto ``patches``,
    and their normalised cross-correlation at ``shift`` (m,); image derivatives by central differences of half a
    pixel, all five patches in one sampling."""
    m = len(shift)
    steps = ([0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5])
    value, u_plus, u_minus, v_plus, v_minus = synthesise(np.concatenate([shift + step for step in steps]), h).reshape(
        5, m, -1
    )
    observed = patches.reshape(m, -1)
    centred = value - value.mean(1, keepdims=True)
    gain = np.sum(centred * (observed - observed.mean(1, keepdims=True)), 1) / np.maximum(np.sum(centred**2, 1), 1e-9)
    offset = observed.mean(1) - gain * value.mean(1)
    rows = np.stack(
        [gain[:, None] * (u_plus - u_minus), gain[:, None] * (v_plus - v_minus), value, np.ones_like(value)], axis=2
    )  # (m, k, 4): d/d shift_u, d/d shift_v, d/d gain, d/d offset
    residual = gain[:, None] * value + offset[:, None] - observed
    normal = np.einsum("mki,mkj->mij", rows, rows) + 1e-6 * np.eye(4)
    step = -np.linalg.solve(normal, np.einsum("mki,mk->mi", rows, residual)[..., None])[..., 0]
    score = _correlation(value.reshape(patches.shape), patches)
    return np.clip(step[:, :2], -0.5, 0.5), score
