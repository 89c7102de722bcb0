"""Scoring one observed silhouette against many model silhouettes at once, exactly as `tracker.tbf.costs` defines
the distance.

Because a cost's weights d_P depend on the observation P only, the distance is affine in the model silhouette Q's
pixels: ``d = (c + sum_x a(x) Q(x)) / N_W`` with ``a = d_P (1 - 2P)`` and ``c = sum d_P P``. `ObservationScorer`
computes ``a`` and ``c`` once per observation and scores any number of model silhouettes at once. A model silhouette
is stored as its runs of inside pixels along the window's pixels in row-major order (`SilhouetteRuns`), so with
``A`` the prefix sum of ``a`` the sum over Q is ``sum over runs [s, e) of A(e) - A(s)``: two reads per run (a few
hundred per silhouette at 320x240) instead of one per inside pixel (thousands). Where many silhouettes are scored
at every frame (a tree's top level), their runs are kept as a sparse matrix with -1 at each run's start and +1 at
its end (`RunBoundaries`), and the sums are one sparse product with A, faster than gathering A at the runs and
adding them up per silhouette, for twice the memory of the runs (the same sums, to rounding). A silhouette
moved by whole pixels first (each sample scored on its own spot: `tracker.tbf.filter.TreeFilter`) is scored from the
same runs, moved (`SilhouetteRuns.shifted_sums`, `ShiftedRunBoundaries`: the product read row by row in a compiled
loop, for the rows asked only).

The loops over runs and pixels are compiled (numba) and kept in numba's cache on disk, from which a process's first
call of each loads it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from scipy import sparse

from tracker.tbf.costs import Cost, Window, window_pixels, window_weights


def run_index_type(largest: int) -> type:
    """The narrowest unsigned integers that hold runs' pixel indices up to ``largest`` (a window's pixel count: an
    end, exclusive, can be it): 2 bytes up to 65,535 (every level's window at the presets' resolutions), else 4. A
    level's scoring reads each asked silhouette's runs from memory rather than cache (a frame asks for a few thousand
    of tens of thousands): half the bytes, and half the sample set's memory for them."""
    return np.uint16 if largest <= np.iinfo(np.uint16).max else np.uint32


@dataclass(frozen=True, eq=False)
class SilhouetteRuns:
    """Many silhouettes of one window as runs of inside pixels: silhouette i's runs are ``ptr[i]:ptr[i + 1]``,
    run r covering the window's pixels ``starts[r]:ends[r]`` in row-major order."""

    starts: np.ndarray  # (runs,) `run_index_type` where made here (a set stored before holds int32)
    ends: np.ndarray  # (runs,) of the same type, exclusive
    ptr: np.ndarray  # (n + 1,) int64
    _extents: dict[int, np.ndarray] = field(default_factory=dict, init=False, repr=False)  # `extents` by width

    @classmethod
    def from_masks(
        cls, masks: np.ndarray, block: int = 1024, *, frame: tuple[int, int] = (0, 0), down_columns: bool = False
    ) -> SilhouetteRuns:
        """From ``(n, h, w)`` silhouettes (bool, or labels: inside where nonzero), ``block`` at a time; each framed by
        ``frame`` ``(v, u)`` pixels of outside on either side (as ``np.pad`` would frame it), and read down the framed
        image's columns instead of along its rows with ``down_columns`` (as its transpose's rows)."""
        masks = np.asarray(masks)
        index = run_index_type((masks.shape[1] + 2 * frame[0]) * (masks.shape[2] + 2 * frame[1]))
        starts, ends, counts = [np.zeros(0, index)], [np.zeros(0, index)], [np.zeros(0, np.int64)]
        for first in range(0, len(masks), block):
            inside = np.not_equal(masks[first : first + block], 0)
            if down_columns:  # the transposed images' rows
                inside = np.ascontiguousarray(inside.transpose(0, 2, 1))
            found_starts, found_ends, found_counts = _inside_runs(inside, *(frame[::-1] if down_columns else frame))
            starts.append(found_starts.astype(index))
            ends.append(found_ends.astype(index))
            counts.append(found_counts)
        ptr = np.r_[0, np.cumsum(np.concatenate(counts))].astype(np.int64)
        return cls(np.concatenate(starts), np.concatenate(ends), ptr)

    def __len__(self) -> int:
        return len(self.ptr) - 1

    def sums(self, values: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Per silhouette (or per silhouette of ``rows``), the sum of ``values`` (one per window pixel, row-major)
        over its pixels."""
        prefix = np.empty(len(values) + 1)
        prefix[0] = 0.0
        np.cumsum(values, out=prefix[1:])
        if rows is None:  # each silhouette's runs added in order from 0, as np.bincount would add them: its bits
            return _run_sums(prefix, self.starts, self.ends, self.ptr)
        index, owner = self.runs_of(rows)
        return np.bincount(owner, weights=prefix[self.ends[index]] - prefix[self.starts[index]], minlength=len(rows))

    def shifted_sums(self, values: np.ndarray, width: int, rows: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """As `sums` over silhouettes ``rows`` of a window ``width`` pixels wide, each moved by its whole-pixel
        ``shifts`` ``(len(rows), 2)`` ``(du, dv)`` first: pixels moved out of the window count nothing.

        Every moved run is cut into its pieces along the window's rows, and each piece's part within the window
        reads two of the window's prefix sums (`_moved_run_sums`); a piece moved wholly out of the window reads
        the same sum twice (0)."""
        prefix = np.empty(len(values) + 1)
        prefix[0] = 0.0
        np.cumsum(values, out=prefix[1:])
        rows = np.ascontiguousarray(rows, dtype=np.int64)  # one compiled signature for every caller
        shifts = np.asarray(shifts, dtype=np.int64)
        extents = self.extents(width)
        return _moved_run_sums(
            prefix, self.starts, self.ends, self.ptr, extents, rows, shifts[:, 0], shifts[:, 1], width
        )

    def extents(self, width: int) -> np.ndarray:
        """``(n, 4)`` int64: per silhouette of a window ``width`` pixels wide, the first and last row its runs cover,
        the first column and the end of the last column (exclusive, at most ``width``); a silhouette with no runs,
        or with a run that goes on into the next row, has -1 for its last row. Made at the first call for a width,
        then kept."""
        if width not in self._extents:
            self._extents[width] = _run_extents(self.starts, self.ends, self.ptr, width)
        return self._extents[width]

    def masks(self, shape: tuple[int, int], rows: np.ndarray | None = None) -> np.ndarray:
        """Silhouettes ``rows`` (all by default) as ``(len(rows), h, w)`` bool images of ``shape`` ``(h, w)``: the
        inverse of `from_masks`."""
        rows = np.arange(len(self)) if rows is None else np.asarray(rows, dtype=np.int64).reshape(-1)
        return _painted(self.starts, self.ends, self.ptr, rows, shape[0] * shape[1]).reshape(len(rows), *shape)

    def subset(self, rows: np.ndarray) -> SilhouetteRuns:
        """The runs of silhouettes ``rows``, in that order (e.g. a tree level's representatives by node)."""
        index, owner = self.runs_of(rows)
        counts = np.bincount(owner, minlength=len(rows))
        return SilhouetteRuns(self.starts[index], self.ends[index], np.r_[0, np.cumsum(counts)].astype(np.int64))

    def runs_of(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The run indices of silhouettes ``rows``, and for each the position in ``rows`` it belongs to."""
        rows = np.asarray(rows, dtype=np.int64)
        first, counts = self.ptr[rows], self.ptr[rows + 1] - self.ptr[rows]
        owner = np.repeat(np.arange(len(rows)), counts)
        return np.arange(len(owner)) + np.repeat(first - (np.cumsum(counts) - counts), counts), owner


class RunBoundaries:
    """Silhouettes' runs as a sparse ``(n, pixels + 1)`` matrix B: row i holds -1 at each of silhouette i's runs'
    starts and +1 at their ends, so that ``B @ A``, A the prefix sum of per-pixel values (``A[0] = 0``), is each
    silhouette's sum of the values over its pixels. Runs go along the image's rows or down its columns, whichever
    gives fewer (a standing person's silhouettes: a third fewer down the columns)."""

    def __init__(self, images: np.ndarray, frame: tuple[int, int] = (0, 0)) -> None:
        """From ``(n, h, w)`` silhouettes (bool, or labels: inside where nonzero), each framed by ``frame`` ``(v, u)``
        pixels of outside on either side (the images it sums over are ``(h + 2 v, w + 2 u)``)."""
        images = np.asarray(images)
        self.shape = (images.shape[1] + 2 * frame[0], images.shape[2] + 2 * frame[1])
        along_rows, down_columns = (
            SilhouetteRuns.from_masks(images, frame=frame),
            SilhouetteRuns.from_masks(images, frame=frame, down_columns=True),
        )
        self.by_columns = len(down_columns.starts) < len(along_rows.starts)
        runs = down_columns if self.by_columns else along_rows
        columns = np.empty(2 * len(runs.starts), np.int32)
        columns[0::2], columns[1::2] = runs.starts, runs.ends  # a silhouette's runs are ordered and never touch
        signs = np.empty(len(columns))
        signs[0::2], signs[1::2] = -1.0, 1.0
        pixels = self.shape[0] * self.shape[1]
        self.matrix = sparse.csr_matrix((signs, columns, 2 * runs.ptr), shape=(len(runs), pixels + 1))
        self.sums(np.zeros(pixels), np.zeros(0, np.int64))  # `sums`' compiled loop loaded here, not at frame 0

    def __len__(self) -> int:
        return self.matrix.shape[0]

    def sums(self, values: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """As `SilhouetteRuns.sums` (``values``: one per pixel, row-major)."""
        return self.summed(values)(rows)

    def summed(self, values: np.ndarray) -> Callable[[np.ndarray | None], np.ndarray]:
        """`sums` of ``values`` for any rows asked (all for None), their prefix sums made once."""
        if self.by_columns:
            values = np.asarray(values).reshape(self.shape).T.ravel()
        prefix = np.empty(len(values) + 1)
        prefix[0] = 0.0
        np.cumsum(values, out=prefix[1:])
        indptr, indices = _csr_arrays(self.matrix)

        def sums(rows: np.ndarray | None = None) -> np.ndarray:
            if rows is None:
                return self.matrix @ prefix
            rows = np.ascontiguousarray(rows, dtype=np.int64)  # the rows asked alone, with scipy's product's bits
            return _signed_sums(indptr, indices, prefix, rows)

        return sums


class ShiftedRunBoundaries:
    """`RunBoundaries` of silhouettes each moved, frame by frame, by whole pixels: silhouette i by ``reference -
    pixels[i]`` for the frame's ``reference`` pixel (each sample scored as if it stood where the observation was
    placed: `tracker.tbf.filter.TreeFilter`'s spot pixels). The window is framed by the pixels' spread, so that
    no shift takes a silhouette out of it; along the flattened frame a move by ``reference - pixels[i]`` adds
    ``flat(reference) - flat(pixels[i])`` to every index, so each row's boundaries are stored already moved by
    ``-flat(pixels[i])``, and a frame's sums are the product with the prefix sums slid by ``flat(reference)``."""

    def __init__(self, images: np.ndarray, pixels: np.ndarray) -> None:
        """From ``(n, h, w)`` silhouettes and their ``(n, 2)`` int pixels ``(u, v)``."""
        images, pixels = np.asarray(images), np.asarray(pixels, dtype=np.int64).reshape(-1, 2)
        self.shape = images.shape[1:]
        self.low = pixels.min(axis=0) if len(pixels) else np.zeros(2, np.int64)
        spread = pixels.max(axis=0) - self.low if len(pixels) else np.zeros(2, np.int64)
        self.margin = (int(spread[0]), int(spread[1]))  # (u, v)
        mu, mv = self.margin
        framed = RunBoundaries(images, frame=(mv, mu))
        self.by_columns = framed.by_columns
        self.framed_shape = (self.shape[0] + 2 * mv, self.shape[1] + 2 * mu)
        moved = self.flat(pixels - self.low)  # >= 0
        self.reach = int(moved.max()) if len(moved) else 0  # the farthest a row's boundaries were moved back
        matrix = framed.matrix
        indices = (matrix.indices - np.repeat(moved, np.diff(matrix.indptr)) + self.reach).astype(matrix.indices.dtype)
        self.matrix = sparse.csr_matrix(
            (matrix.data, indices, matrix.indptr), shape=(matrix.shape[0], matrix.shape[1] + self.reach)
        )

    def flat(self, pixels: np.ndarray) -> np.ndarray:
        """Whole-pixel moves ``(..., 2)`` ``(du, dv)`` as moves along the flattened frame (its rows, or columns)."""
        height, width = self.framed_shape
        pixels = np.asarray(pixels, dtype=np.int64)
        return pixels[..., 0] * height + pixels[..., 1] if self.by_columns else pixels[..., 1] * width + pixels[..., 0]

    def __len__(self) -> int:
        return self.matrix.shape[0]

    def sums(self, values: np.ndarray, reference: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Per silhouette (or per silhouette of ``rows``), the sum of ``values`` (one per pixel of the window,
        row-major) over its pixels once moved by ``reference`` minus its own pixel; ``reference`` within the pixels'
        range (a sample's)."""
        return self.summed(values, reference)(rows)

    def summed(self, values: np.ndarray, reference: np.ndarray) -> Callable[[np.ndarray | None], np.ndarray]:
        """`sums` of ``values`` at ``reference`` for any rows asked (all for None), their prefix sums made once."""
        mu, mv = self.margin
        values = np.asarray(values)
        framed = np.zeros(self.framed_shape, values.dtype)  # the values framed by zeros (as np.pad, without its cost)
        framed[mv : mv + self.shape[0], mu : mu + self.shape[1]] = values.reshape(self.shape)
        flat = (framed.T if self.by_columns else framed).ravel()
        # prefix[reach + j] is the sum of the first j values; held flat beyond both ends
        prefix = np.zeros(len(flat) + 1 + 2 * self.reach)
        np.cumsum(flat, out=prefix[self.reach + 1 : self.reach + 1 + len(flat)])
        prefix[self.reach + 1 + len(flat) :] = prefix[self.reach + len(flat)]
        reference = np.asarray(reference, dtype=np.int64)
        if np.any(reference < self.low) or np.any(reference > self.low + self.margin):
            raise ValueError(f"reference pixel {reference.tolist()} is outside the silhouettes' pixels")
        start = int(self.flat(reference - self.low))
        slid = prefix[start : start + self.matrix.shape[1]]
        indptr, indices = _csr_arrays(self.matrix)

        def sums(rows: np.ndarray | None = None) -> np.ndarray:
            rows = np.arange(len(self), dtype=np.int64) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
            return _signed_sums(indptr, indices, slid, rows)

        return sums


@dataclass(frozen=True, eq=False)
class SilhouetteStack:
    """Many model silhouettes of one resolution, cropped to a window ``(u0, v0, u1, v1)``, kept as their ``runs`` of
    inside pixels (what scoring reads; a few kB each where an image took tens): `mask` and `masks` give them back as
    ``(v1 - v0, u1 - u0)`` bool images."""

    window: Window
    runs: SilhouetteRuns

    @classmethod
    def of(cls, images: np.ndarray, window: Window) -> SilhouetteStack:
        """From ``(n, v1 - v0, u1 - u0)`` silhouettes (bool, or labels: inside where nonzero)."""
        return cls(window, SilhouetteRuns.from_masks(images))

    @classmethod
    def crop(cls, silhouettes: np.ndarray, window: Window) -> SilhouetteStack:
        u0, v0, u1, v1 = window
        return cls.of(np.asarray(silhouettes, bool)[:, v0:v1, u0:u1], window)

    @property
    def shape(self) -> tuple[int, int]:
        """``(h, w)`` of every silhouette: the window's."""
        u0, v0, u1, v1 = self.window
        return v1 - v0, u1 - u0

    def __len__(self) -> int:
        return len(self.runs)

    def mask(self, index: int) -> np.ndarray:
        """Silhouette ``index`` as ``(v1 - v0, u1 - u0)`` bool."""
        return self.runs.masks(self.shape, np.array([index]))[0]

    def masks(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Silhouettes ``rows`` (all by default) as ``(len(rows), v1 - v0, u1 - u0)`` bool."""
        return self.runs.masks(self.shape, rows)


class ObservationScorer:
    """One observed silhouette's distance to many model silhouettes: ``scores(stack)`` equals
    `silhouette_distance` for every member (to rounding), from the stack's runs."""

    def __init__(self, cost: str | Cost, observed: np.ndarray, window: Window, **settings: Any) -> None:
        u0, v0, u1, v1 = window
        self.window = window
        self.weights = window_weights(cost, observed, window, **settings)  # d_P over the window
        inside = np.asarray(observed, bool)[v0:v1, u0:u1]
        self._slope = np.negative(self.weights, out=self.weights.copy(), where=inside).ravel()  # a = d_P (1 - 2P)
        self._constant = float(self.weights[inside].sum())
        self._pixels = window_pixels(window)

    def scores(self, stack: SilhouetteStack, rows: np.ndarray | None = None) -> np.ndarray:
        """The distance to every silhouette of ``stack`` (or to those of ``rows``)."""
        if tuple(stack.window) != tuple(self.window):
            raise ValueError(f"the stack's window {stack.window} is not the scorer's {self.window}")
        return self.scores_of_runs(stack.runs, rows)

    def scores_of_runs(self, runs: SilhouetteRuns | RunBoundaries, rows: np.ndarray | None = None) -> np.ndarray:
        """The same for silhouettes given by their runs over the scorer's window (or their `RunBoundaries`)."""
        return (self._constant + runs.sums(self._slope, rows)) / self._pixels

    def scores_of_shifted(self, runs: SilhouetteRuns, rows: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """The distance to silhouettes ``rows`` of ``runs``, each moved by its ``(du, dv)`` of ``shifts`` first."""
        width = self.window[2] - self.window[0]
        return (self._constant + runs.shifted_sums(self._slope, width, rows, shifts)) / self._pixels

    def scores_of_placed(
        self, boundaries: ShiftedRunBoundaries, reference: np.ndarray, rows: np.ndarray | None = None
    ) -> np.ndarray:
        """The distance to every silhouette of ``boundaries`` (or to those of ``rows``), each moved by ``reference``
        minus its own pixel."""
        return self.scoring(boundaries, reference)(rows)

    def scoring(
        self, boundaries: RunBoundaries | ShiftedRunBoundaries, reference: np.ndarray | None = None
    ) -> Callable[[np.ndarray | None], np.ndarray]:
        """`scores_of_runs` of ``boundaries`` (`scores_of_placed` with a ``reference``) for any rows asked (all for
        None): the observation's prefix sums made once, for rows asked in turns."""
        sums = boundaries.summed(self._slope) if reference is None else boundaries.summed(self._slope, reference)
        return lambda rows=None: (self._constant + sums(rows)) / self._pixels


def _csr_arrays(matrix: sparse.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """A CSR matrix's row pointers as int64 and its column indices as unsigned, as `_signed_sums` reads them."""
    indices = matrix.indices.view(np.uint32 if matrix.indices.dtype == np.int32 else np.uint64)
    return matrix.indptr.astype(np.int64, copy=False), indices


@numba.njit(cache=True, nogil=True)
def _signed_sums(indptr: np.ndarray, indices: np.ndarray, prefix: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """`ShiftedRunBoundaries.sums`'s loop, ``(matrix[rows] @ prefix)`` without the rows' copy: per row ``rows[i]`` of
    a CSR structure whose entries alternate -1 and +1 (a run's start, then its end), the sum of ``prefix`` at its
    entries so signed, added one by one in the entries' order from 0, as scipy's sparse product adds them (a product
    by -1 or +1 is exact): the same bits. The indices come unsigned: a signed index is checked for wrapping around
    at every read, which made this loop slower than scipy's."""
    sums = np.empty(len(rows))
    for i in range(len(rows)):
        total = 0.0
        for k in range(indptr[rows[i]], indptr[rows[i] + 1], 2):
            total -= prefix[indices[k]]
            total += prefix[indices[k + 1]]
        sums[i] = total
    return sums


@numba.njit(cache=True, nogil=True)
def _moved_run_sums(
    prefix: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    ptr: np.ndarray,
    extents: np.ndarray,
    rows: np.ndarray,
    du: np.ndarray,
    dv: np.ndarray,
    width: int,
) -> np.ndarray:
    """`SilhouetteRuns.shifted_sums`'s loop: per silhouette ``rows[i]``, the window's ``prefix`` sums read at each of
    its runs' pieces, one piece a row of the window it spans (a run can go on into the next row), each piece moved
    by ``(du[i], dv[i])`` and cut at the window's edges (`_window_index`). The pieces are summed in the order a
    weighted `np.bincount` over all of them would add them: every run's first piece, silhouette by silhouette, then
    every run's second, and so on. A silhouette that stays within the window once moved (by its ``extents``, with
    no run into the next row) has one piece a run, read at its ends moved along the flattened window: the same
    indices, without the cuts."""
    height = (len(prefix) - 1) // width
    sums = np.zeros(len(rows))
    wrapping = False
    for i in range(len(rows)):
        first, last = ptr[rows[i]], ptr[rows[i] + 1]
        if first == last:
            continue
        top, bottom, left, right = extents[rows[i]]
        if (
            bottom >= 0
            and top + dv[i] >= 0
            and bottom + dv[i] < height
            and left + du[i] >= 0
            and right + du[i] <= width
        ):
            move = dv[i] * width + du[i]
            total = 0.0
            for run in range(first, last):
                total += prefix[np.int64(ends[run]) + move] - prefix[np.int64(starts[run]) + move]
            sums[i] = total
            continue
        # a silhouette's runs come in the window's order: its first run's row divided out, the others' followed on
        # (a 64-bit division per run took a third of the loop's time)
        row = np.int64(starts[first]) // width
        row_start = row * width
        total = 0.0
        for run in range(first, last):
            start, end = np.int64(starts[run]), np.int64(ends[run])
            while start >= row_start + width:
                row_start += width
                row += 1
            if end > row_start + width:
                end, wrapping = row_start + width, True
            total += (
                prefix[_window_index(row + dv[i], end - row_start + du[i], width, height)]
                - prefix[_window_index(row + dv[i], start - row_start + du[i], width, height)]
            )
        sums[i] = total
    piece = 1
    while wrapping:  # the next piece of each run that goes on into another row
        wrapping = False
        for i in range(len(rows)):
            for run in range(ptr[rows[i]], ptr[rows[i] + 1]):
                row = np.int64(starts[run]) // width + piece
                start, end = row * width, np.int64(ends[run])
                if start >= end:
                    continue
                if end > start + width:
                    end, wrapping = start + width, True
                moved_row = row + dv[i]
                sums[i] += (
                    prefix[_window_index(moved_row, end - start + du[i], width, height)]
                    - prefix[_window_index(moved_row, du[i], width, height)]
                )
        piece += 1
    return sums


@numba.njit(cache=True, nogil=True)
def _run_extents(starts: np.ndarray, ends: np.ndarray, ptr: np.ndarray, width: int) -> np.ndarray:
    """`SilhouetteRuns.extents`."""
    extents = np.full((len(ptr) - 1, 4), -1, np.int64)
    for i in range(len(ptr) - 1):
        if ptr[i] == ptr[i + 1]:
            continue
        top, bottom, left, right = np.int64(starts[ptr[i]]) // width, np.int64(0), width, np.int64(0)
        for run in range(ptr[i], ptr[i + 1]):
            start, end = np.int64(starts[run]), np.int64(ends[run])
            row = start // width
            if end > (row + 1) * width:  # on into the next row
                bottom = np.int64(-1)
                break
            bottom = row
            left = min(left, start - row * width)
            right = max(right, end - row * width)
        extents[i] = top, bottom, left, right
    return extents


@numba.njit(cache=True, nogil=True, inline="always")
def _window_index(row: int, column: int, width: int, height: int) -> int:
    """The count of a window's pixels (row-major) before pixel ``(row, column)``, for any row and column: the
    window's edge where the pixel lies beyond it (0 above the window, all of it below)."""
    if row < 0:
        return 0
    if row >= height:
        return height * width
    return row * width + min(max(column, 0), width)


@numba.njit(cache=True, nogil=True)
def _inside_runs(inside: np.ndarray, frame_v: int, frame_u: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`SilhouetteRuns.from_masks`' scan of ``(n, h, w)`` bool silhouettes, each framed by ``frame_v`` rows and
    ``frame_u`` columns of outside on either side and flattened along its rows: every run's start and end
    (exclusive), and each silhouette's count of runs. Without a frame at the sides, a run goes on from a row's end
    into the next row's start where both are inside (as along the flattened image)."""
    n, height, width = inside.shape
    framed_width = width + 2 * frame_u
    most = height * ((width + 1) // 2 + 1)  # the runs a silhouette can hold at most
    counts = np.zeros(n, np.int64)
    starts, ends = np.empty(64 * n + most, np.int64), np.empty(64 * n + most, np.int64)
    run = 0
    for i in range(n):
        if run + most > len(starts):  # grown between the silhouettes only: the scan below then runs unhindered
            starts = np.concatenate((starts[:run], np.empty(run + most, np.int64)))
            ends = np.concatenate((ends[:run], np.empty(run + most, np.int64)))
        was_inside, before = False, run
        for v in range(height):
            first = (v + frame_v) * framed_width + frame_u  # the row's first pixel in the framed image
            row = inside[i, v]
            for u in range(width):
                here = row[u]
                if here != was_inside:
                    was_inside = here
                    if here:
                        starts[run] = first + u
                    else:
                        ends[run] = first + u
                        run += 1
            if was_inside and frame_u > 0:  # the frame after the row ends its run
                ends[run] = first + width
                run += 1
                was_inside = False
        if was_inside:  # a run to the last row's end: the frame's rows below, or the image's end, end it
            ends[run] = (height + frame_v) * framed_width
            run += 1
        counts[i] = run - before
    return starts[:run].copy(), ends[:run].copy(), counts


@numba.njit(cache=True, nogil=True)
def _run_sums(prefix: np.ndarray, starts: np.ndarray, ends: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """`SilhouetteRuns.sums` of every silhouette: per silhouette, ``prefix[end] - prefix[start]`` of each of its runs
    added in the runs' order from 0."""
    sums = np.zeros(len(ptr) - 1)
    for i in range(len(ptr) - 1):
        total = 0.0
        for r in range(ptr[i], ptr[i + 1]):
            total += prefix[ends[r]] - prefix[starts[r]]
        sums[i] = total
    return sums


@numba.njit(cache=True, nogil=True)
def _painted(starts: np.ndarray, ends: np.ndarray, ptr: np.ndarray, rows: np.ndarray, pixels: int) -> np.ndarray:
    """`SilhouetteRuns.masks`: ``(len(rows), pixels)`` bool, each row's silhouette's runs set."""
    images = np.zeros((len(rows), pixels), np.bool_)
    for j in range(len(rows)):
        for r in range(ptr[rows[j]], ptr[rows[j] + 1]):
            images[j, starts[r] : ends[r]] = True
    return images
