"""The pose tree of paper 2 (section 3): pose samples grouped level by level by silhouette distance.

Level 0 is one node holding every sample. A node S of level l-1 is split at level l (`_split`):
    1. its first representative is the member nearest the members' mean pose;
    2. while some member is farther than T_l from every representative, the one of those with the largest mean
       distance to the representatives becomes one too;
    3. every other member joins its nearest representative's node;
    4. each node's representative is re-picked as its member nearest the node's mean pose.
Distances at level l are XOR distances (eq 6, over the sample set's window) between the samples' silhouettes at
the level's resolution (`LEVEL_RESOLUTIONS`: coarse at the top); with several views (`SampleViews`), the mean of
the views' XOR distances, so that T_l keeps its meaning. XOR is symmetric, so the tree is one for every cost.
Poses are compared by their pose vectors (`tracker.models.body_mesh`) for "mean" and "nearest".

A `PoseTree` keeps, per level, each node's representative sample and parent node, and each sample's node; the
leaves are the last level's nodes and every sample is in exactly one of them.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from tracker.atomic import atomic_path, exclusive
from tracker.memo import DAMAGED_NPZ
from tracker.tbf import cache_manifest
from tracker.tbf.samples import LEVEL_RESOLUTIONS, PoseSampleSet, SampleViews
from tracker.tbf.scoring import SilhouetteStack

log = logging.getLogger(__name__)

_ARRAYS = ("representatives", "seeds", "parents", "node_of_sample")  # TreeLevel's arrays, in order


class Groups:
    """Items grouped by an index each (``group_of``, ``(items,)``, of ``groups`` groups): the items sorted by group,
    ascending within each, and where each group's run of them starts, so that a few groups' items are read without
    a pass over every item."""

    def __init__(self, group_of: np.ndarray, groups: int) -> None:
        self.order = np.argsort(group_of, kind="stable")
        self.ptr = np.r_[0, np.cumsum(np.bincount(group_of, minlength=groups))].astype(np.int64)

    def items(self, groups: np.ndarray) -> np.ndarray:
        """The items of ``groups`` (any order; repeats and indices past the last group count nothing), ascending."""
        return _grouped_items(self.order, self.ptr, np.asarray(groups, dtype=np.int64))

    def sums(self, weights: np.ndarray, groups: np.ndarray) -> np.ndarray:
        """Per group of ``groups`` (each one of this grouping's: `IndexError` otherwise), its items' ``weights``
        (float64) added one by one in ascending order from 0, as ``np.bincount(group_of, weights)`` adds them: the
        same bits."""
        return _grouped_sums(weights, self.order, self.ptr, np.asarray(groups, dtype=np.int64))


@numba.njit(cache=True, nogil=True)
def _grouped_items(order: np.ndarray, ptr: np.ndarray, groups: np.ndarray) -> np.ndarray:
    groups = np.unique(groups)
    groups = groups[(groups >= 0) & (groups < len(ptr) - 1)]
    count = 0
    for group in groups:
        count += ptr[group + 1] - ptr[group]
    items = np.empty(count, order.dtype)
    at = 0
    for group in groups:
        for j in range(ptr[group], ptr[group + 1]):
            items[at] = order[j]
            at += 1
    items.sort()
    return items


@numba.njit(cache=True, nogil=True)
def _grouped_sums(weights: np.ndarray, order: np.ndarray, ptr: np.ndarray, groups: np.ndarray) -> np.ndarray:
    sums = np.zeros(len(groups))
    for i in range(len(groups)):
        if groups[i] < 0 or groups[i] >= len(ptr) - 1:
            raise IndexError("a group the grouping does not hold")
        total = 0.0
        for j in range(ptr[groups[i]], ptr[groups[i] + 1]):
            total += weights[order[j]]
        sums[i] = total
    return sums


@dataclass(frozen=True, eq=False)
class TreeLevel:
    representatives: np.ndarray  # (nodes,) sample index of each node's representative (after step 4)
    seeds: np.ndarray  # (nodes,) the representative step 2 chose (each farther than T_l from the earlier ones)
    parents: np.ndarray  # (nodes,) node index in the level above (0 for level 1: the root)
    node_of_sample: np.ndarray  # (samples,) the node each sample belongs to at this level
    resolution: tuple[int, int]
    threshold: float

    def __len__(self) -> int:
        return len(self.representatives)

    @functools.cached_property
    def nodes_by_parent(self) -> Groups:
        return Groups(self.parents, int(self.parents.max(initial=-1)) + 1)

    @functools.cached_property
    def samples_by_node(self) -> Groups:
        return Groups(self.node_of_sample, len(self))

    def children_of(self, parents: np.ndarray) -> np.ndarray:
        """The nodes of this level whose parent is among ``parents``, ascending."""
        return self.nodes_by_parent.items(parents)

    def masses(self, weights: np.ndarray, nodes: np.ndarray | None = None) -> np.ndarray:
        """Per node (of ``nodes``; all for None), the sum of its samples' ``weights`` (float64; e.g. a prior's
        mass), each node's added in the samples' order: the bits of ``np.bincount(node_of_sample, weights)``, which
        gives them all."""
        if nodes is None:
            return np.bincount(self.node_of_sample, weights=weights, minlength=len(self))
        return self.samples_by_node.sums(weights, nodes)


@dataclass(frozen=True, eq=False)
class PoseTree:
    levels: tuple[TreeLevel, ...]
    key: str

    @property
    def node_counts(self) -> list[int]:
        return [len(level) for level in self.levels]

    def leaf_members(self, leaves: np.ndarray) -> np.ndarray:
        """The samples in ``leaves`` (nodes of the last level), ascending."""
        return self.levels[-1].samples_by_node.items(leaves)

    def prepare(self) -> PoseTree:
        """The tree with its groupings made (`TreeLevel.nodes_by_parent`, `samples_by_node`) and their compiled
        loops loaded, which a search would otherwise do at its first frame."""
        for level in self.levels:
            level.children_of(np.zeros(0, np.int64))
            level.masses(np.zeros(len(level.node_of_sample)), np.arange(1))
        return self


def tree_key(samples: PoseSampleSet | SampleViews, thresholds: tuple[float, ...], resolutions=LEVEL_RESOLUTIONS) -> str:
    text = json.dumps(
        {
            "samples": samples.key,
            "thresholds": list(map(float, thresholds)),
            "resolutions": [list(r) for r in resolutions],
            "format": 2,
        }
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def load_or_build_tree(
    samples: PoseSampleSet | SampleViews, thresholds: tuple[float, ...], resolutions=LEVEL_RESOLUTIONS
) -> PoseTree:
    """The tree of ``samples`` with T_l = ``thresholds`` (one per level): from the folder of the (first view's)
    cached set when its manifest vouches for it (`tracker.tbf.cache_manifest`), else built and kept there."""
    if len(thresholds) != len(resolutions):
        raise ValueError(f"{len(thresholds)} thresholds for {len(resolutions)} levels")
    key = tree_key(samples, thresholds, resolutions)
    folder = SampleViews.of(samples).sets[0].folder
    if folder is None:  # a set kept in memory only
        return _build_logged(samples, thresholds, resolutions, key)
    file_name = f"tree-{key}.npz"
    with exclusive(folder.parent / f".{folder.name}.{file_name}.lock"):  # parallel jobs of a sweep build it once
        try:
            path = cache_manifest.checked_file(folder, file_name)
            if path is not None:
                return _load(path, key, len(samples), thresholds, resolutions)
        except DAMAGED_NPZ as problem:
            log.warning("tree cache %s is damaged (%s): rebuilding it", folder / file_name, problem)
        tree = _build_logged(samples, thresholds, resolutions, key)
        with atomic_path(folder / file_name) as temporary, open(temporary, "wb") as file:
            np.savez(
                file,
                key=key,
                **{f"{name}_{k}": getattr(level, name) for k, level in enumerate(tree.levels) for name in _ARRAYS},
            )
        cache_manifest.add_file(folder, file_name)
        return tree


def _build_logged(samples: PoseSampleSet, thresholds, resolutions, key: str) -> PoseTree:
    start = time.perf_counter()
    tree = build_tree(samples, thresholds, resolutions, key)
    log.info("built a pose tree of %s nodes per level in %.1f s", tree.node_counts, time.perf_counter() - start)
    return tree


def build_tree(
    samples: PoseSampleSet | SampleViews, thresholds: tuple[float, ...], resolutions=LEVEL_RESOLUTIONS, key: str = ""
) -> PoseTree:
    samples = SampleViews.of(samples)
    node_of_sample = np.zeros(len(samples), dtype=np.int64)  # level 0: one node
    levels = []
    for threshold, resolution in zip(thresholds, resolutions, strict=True):
        levels.append(_build_level(samples, _level_bits(samples, resolution), node_of_sample, threshold, resolution))
        node_of_sample = levels[-1].node_of_sample
    return PoseTree(tuple(levels), key)


def _level_bits(samples: SampleViews, resolution: tuple[int, int]) -> tuple[list[np.ndarray], list[int]]:
    """Per view, every sample's silhouette at ``resolution`` as packed bit rows (`_packed_bits`), and its pixels."""
    stacks = samples.silhouettes(resolution)
    return [_packed_bits(stack) for stack in stacks], [int(np.prod(stack.shape)) for stack in stacks]


def _build_level(
    samples: SampleViews,
    bits: tuple[list[np.ndarray], list[int]],
    node_of_sample: np.ndarray,
    threshold: float,
    resolution: tuple[int, int],
) -> TreeLevel:
    """The level below the nodes ``node_of_sample``: each node split at T_l = ``threshold`` (steps 1-4), the
    silhouettes' distances from ``bits`` (`_level_bits` of ``resolution``)."""
    poses = np.asarray(samples.poses)
    masks, pixels = bits
    representatives, seeds, parents = [], [], []
    assignment = np.empty(len(poses), dtype=np.int64)
    for parent in range(node_of_sample.max() + 1):
        members = np.flatnonzero(node_of_sample == parent)
        reps, first_reps, nearest = _split(poses[members], [view[members] for view in masks], pixels, threshold)
        assignment[members] = len(representatives) + nearest
        representatives.extend(members[reps])
        seeds.extend(members[first_reps])
        parents.extend([parent] * len(reps))
    return TreeLevel(
        np.array(representatives), np.array(seeds), np.array(parents), assignment, tuple(resolution), float(threshold)
    )


SHARE_BISECTIONS = 16  # halvings of each threshold's bracket (in log space: ~0.1 % of the bracket's ratio)
_THRESHOLD_BRACKET = (1e-5, 1.0)  # T_l is a fraction of the window's pixels


def thresholds_for_shares(
    samples: PoseSampleSet | SampleViews, shares: tuple[float, ...], resolutions=LEVEL_RESOLUTIONS
) -> tuple[float, ...]:
    """T_l per level, top down, such that level l holds about ``shares[l]`` of the samples as nodes (the paper's
    3,417 samples gave 693 / 3,013 / 3,318 nodes: shares 0.20 / 0.88 / 0.97): each by bisection (more nodes for a
    smaller T_l), below the levels already chosen. Kept with the sample set (`PoseSampleSet.derived`)."""
    samples = SampleViews.of(samples)
    chosen: list[float] = []
    node_of_sample = np.zeros(len(samples), dtype=np.int64)
    for share, resolution in zip(shares, resolutions, strict=True):
        name = f"tree_threshold share={list(shares)} level={len(chosen) + 1}"
        bits = _level_bits(samples, resolution)  # decoded once for the bisection's every try

        def bisect(parents=node_of_sample, share=share, resolution=resolution, bits=bits) -> float:
            low, high = np.log(_THRESHOLD_BRACKET[0]), np.log(_THRESHOLD_BRACKET[1])
            for _ in range(SHARE_BISECTIONS):
                middle = (low + high) / 2
                nodes = len(_build_level(samples, bits, parents, float(np.exp(middle)), resolution))
                low, high = (middle, high) if nodes > share * len(samples) else (low, middle)
            return float(np.exp(high))

        chosen.append(samples.derived(name, bisect))
        node_of_sample = _build_level(samples, bits, node_of_sample, chosen[-1], resolution).node_of_sample
    return tuple(chosen)


def _split(poses, masks, pixels, threshold) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps 1-4 for one node's members (``masks``, ``pixels``: per view): representative member indices (after
    step 4, and as step 2 chose them), and each member's node 0..k-1."""
    first = int(np.argmin(np.linalg.norm(poses - poses.mean(axis=0), axis=1)))
    seeds, nearest_rep = _seeds(tuple(masks), np.array(pixels, dtype=np.int64), first, float(threshold))
    nearest_rep[seeds] = np.arange(len(seeds))  # a representative is in its own node
    reps_array = seeds.copy()
    for node in range(len(seeds)):  # step 4: the member nearest the node's mean
        members = np.flatnonzero(nearest_rep == node)
        centre = poses[members].mean(axis=0)
        reps_array[node] = members[np.argmin(np.linalg.norm(poses[members] - centre, axis=1))]
    return reps_array, seeds, nearest_rep


def _packed_bits(stack: SilhouetteStack) -> np.ndarray:
    """The stack's silhouettes as ``(n, words)`` uint64 bit rows (zero-padded), for XOR by popcount: their runs set
    straight into the bytes ``np.packbits`` would give their images (its bit order), no image made."""
    runs, pixels = stack.runs, int(np.prod(stack.shape))
    return _packed_runs(runs.starts, runs.ends, runs.ptr, -(-pixels // 64) * 8).view(np.uint64)


@numba.njit(cache=True, nogil=True)
def _packed_runs(starts: np.ndarray, ends: np.ndarray, ptr: np.ndarray, row_bytes: int) -> np.ndarray:
    """``(n, row_bytes)`` uint8: each silhouette's runs as bits, pixel p at byte ``p // 8``, bit ``7 - p % 8``."""
    packed = np.zeros((len(ptr) - 1, row_bytes), np.uint8)
    for i in range(len(ptr) - 1):
        row = packed[i]
        for r in range(ptr[i], ptr[i + 1]):
            pixel, end = np.int64(starts[r]), np.int64(ends[r])
            while pixel < end and pixel & 7:  # bit by bit to a byte's start
                row[pixel >> 3] |= np.uint8(0x80 >> (pixel & 7))
                pixel += 1
            while pixel + 8 <= end:  # then whole bytes
                row[pixel >> 3] = 0xFF
                pixel += 8
            while pixel < end:  # then the bits left
                row[pixel >> 3] |= np.uint8(0x80 >> (pixel & 7))
                pixel += 1
    return packed


@numba.njit(cache=True, nogil=True)
def _seeds(masks: tuple, pixels: np.ndarray, first: int, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Steps 2-3 for one node's members, from member ``first``: each new seed is the member farthest on average from
    the seeds so far among those farther than ``threshold`` from every one, until none is. The seeds in order, and
    each member's nearest seed (its index among them). A distance is the XOR distance (eq 6): the differing pixels
    over the window's (``pixels``), the mean over the views (``masks``: per view, the members' bit rows)."""
    count = len(masks[0])
    nearest_distance = np.full(count, np.inf)
    nearest_seed = np.zeros(count, np.int64)
    total_distance = np.zeros(count)
    taken = np.zeros(count, np.bool_)
    seeds = np.empty(count, np.int64)
    found, candidate = 0, first
    while candidate >= 0:
        seeds[found], taken[candidate] = candidate, True
        found += 1
        distance = _differing_bits(masks[0], candidate) / pixels[0]
        for view in range(1, len(masks)):
            distance = distance + _differing_bits(masks[view], candidate) / pixels[view]
        distance = distance / len(masks)
        candidate, farthest = -1, -np.inf
        for i in range(count):
            if distance[i] < nearest_distance[i]:
                nearest_distance[i], nearest_seed[i] = distance[i], found - 1
            total_distance[i] += distance[i]
            # the first member of the largest mean distance, among those still farther than T_l from every seed
            if nearest_distance[i] > threshold and not taken[i] and total_distance[i] / found > farthest:
                candidate, farthest = i, total_distance[i] / found
    return seeds[:found].copy(), nearest_seed


# Masks of a 64-bit word's bits in pairs, fours and eights, and a byte of ones in each byte: a population count by
# halves (that LLVM compiles to the processor's own instruction where it has one).
_PAIRS, _FOURS, _EIGHTS, _BYTES = (
    np.uint64(m) for m in (0x5555555555555555, 0x3333333333333333, 0x0F0F0F0F0F0F0F0F, 0x0101010101010101)
)


@numba.njit(cache=True, nogil=True)
def _differing_bits(rows: np.ndarray, index: int) -> np.ndarray:
    """``(n,)`` int64: how many bits each of the ``(n, words)`` uint64 bit rows differs from row ``index`` in (its XOR's
    population count), in one pass over the rows."""
    one = rows[index]
    counts = np.empty(len(rows), np.int64)
    for i in range(len(rows)):
        total = 0
        for w in range(rows.shape[1]):
            x = rows[i, w] ^ one[w]
            x = x - ((x >> np.uint64(1)) & _PAIRS)
            x = (x & _FOURS) + ((x >> np.uint64(2)) & _FOURS)
            x = (x + (x >> np.uint64(4))) & _EIGHTS
            total += (x * _BYTES) >> np.uint64(56)
        counts[i] = total
    return counts


def _load(path: Path, key: str, samples: int, thresholds, resolutions) -> PoseTree:
    with np.load(path) as data:
        if str(data["key"]) != key:
            raise ValueError("its key does not match")
        levels = []
        for k, (threshold, resolution) in enumerate(zip(thresholds, resolutions, strict=True)):
            level = TreeLevel(*(data[f"{name}_{k}"] for name in _ARRAYS), tuple(resolution), float(threshold))
            if len(level.node_of_sample) != samples or level.node_of_sample.max() >= len(level):
                raise ValueError("its levels do not fit the sample set")
            levels.append(level)
    return PoseTree(tuple(levels), key)
