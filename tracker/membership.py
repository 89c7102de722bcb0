"""Exact membership of whole numbers: `members` is ``np.isin(values, among)`` for integer arrays, by one sort of
``among`` and a binary search. AbIS's bookkeeping asks it a few dozen times a frame, of a few hundred feature ids
or sample keys each, where numpy's own isin (which sorts both arrays together) costs several times as much."""

from __future__ import annotations

import numpy as np


def members(values: np.ndarray, among: np.ndarray) -> np.ndarray:
    """``(len(values),)`` bool: which of the integers ``values`` are in ``among`` (any shapes, flattened: as
    ``np.isin(values, among).ravel()``)."""
    values, among = np.ravel(values), np.sort(np.ravel(among))
    if len(among) == 0:
        return np.zeros(len(values), bool)
    at = np.minimum(np.searchsorted(among, values), len(among) - 1)
    return among[at] == values
