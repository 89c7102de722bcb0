"""Eq 10's sigma in the cost's own units: the three costs measure on different scales (XOR a fraction of the window,
wXOR pixels of depth, nwXOR in between) and each level of the tree has its own resolution, so the filter's sigma
at a level is ``likelihood_sigma`` times the cost's typical step between neighbouring samples there: the median,
over `CALIBRATION_SAMPLES` samples taken as observations, of the distance to their nearest other sample
(`neighbour_scale`). It is computed once per sample set, cost and resolution, and cached with the set.
"""

from __future__ import annotations

import numpy as np

from tracker.tbf.costs import Cost
from tracker.tbf.samples import PoseSampleSet
from tracker.tbf.scoring import ObservationScorer

CALIBRATION_SAMPLES = 200
SAME_SILHOUETTE = 1e-9  # a distance this small is rounding: the two silhouettes are the same


def neighbour_scale(
    samples: PoseSampleSet, cost: Cost, resolution: tuple[int, int], count: int = CALIBRATION_SAMPLES
) -> float:
    """The median distance (with ``cost``, at ``resolution``) from a sample's silhouette, taken as the
    observation, to the nearest other sample's; over ``count`` samples picked evenly through the set (one view's)."""
    stack = samples.silhouettes(resolution)
    u0, v0, u1, v1 = stack.window
    full = np.zeros((v1, u1), bool)
    nearest = []
    for index in np.unique(np.linspace(0, len(samples) - 1, min(count, len(samples))).astype(int)):
        full[v0:v1, u0:u1] = stack.mask(index)
        if not full.any():
            continue
        distances = ObservationScorer(cost, full, stack.window).scores(stack)
        distances[index] = np.inf
        distances[distances <= SAME_SILHOUETTE] = np.inf  # identical silhouettes (up to rounding) are no step
        if np.isfinite(distances).any():
            nearest.append(distances.min())
    if not nearest:
        raise ValueError("no two samples' silhouettes differ: the sample set cannot be told apart")
    return float(np.median(nearest))


def neighbour_step(samples: PoseSampleSet, cost: Cost, resolution: tuple[int, int]) -> float:
    """`neighbour_scale` of one view's sample set, from its cache of derived values (computed there once)."""
    key = f"neighbour_scale {cost_identity(cost)} {'x'.join(map(str, resolution))} {CALIBRATION_SAMPLES}"
    return samples.derived(key, lambda: neighbour_scale(samples, cost, resolution))


def cost_identity(cost: Cost) -> str:
    """A cost's name and settings (a configured registered cost), or its function's qualified name."""
    settings = getattr(cost, "settings", {})
    return getattr(cost, "name", getattr(cost, "__qualname__", repr(cost))) + "".join(
        f" {k}={v!r}" for k, v in sorted(settings.items())
    )
