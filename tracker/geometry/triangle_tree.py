"""Each point's nearest triangle of a mesh, exactly: a bounding-volume hierarchy over the triangles, in compiled
loops.

The tree's shape splits the triangles at the median of their boxes' centres along the centres' longest extent, until
`LEAF_TRIANGLES` or fewer are left. It is made once for a set of faces, from the first mesh asked about, and kept
(the last `SHAPES_KEPT` sets): each mesh gets its own boxes, every node's around its triangles, in one pass. A
point's search visits the nearer nodes first and skips a node whose box is farther than the nearest triangle found,
so any shape gives the same answer, exactly: of triangles at the same distance, the first (lowest index). The
distance to a triangle is to Ericson's closest point on it (Real-Time Collision Detection, 5.1.5), computed as
`tracker.geometry.surface_distance.point_triangle_distance` computes it, so the distance found is the smallest of
that function's over every triangle, to the bit. A triangle with a corner that is not finite is never the nearest.
"""

from __future__ import annotations

import numba
import numpy as np

LEAF_TRIANGLES = 4


def nearest_triangles(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` ``(n, 3)``: the index of its nearest triangle of the mesh (``vertices`` ``(V, 3)``,
    ``faces`` ``(F, 3)``) and the distance to it; -1 and NaN for a point not finite, or a mesh with no finite
    triangle."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    corners = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64)[faces])
    lower, upper = _triangle_boxes(corners)
    key = faces.tobytes()
    shape = _SHAPES.pop(key, None) or _split(lower, upper, LEAF_TRIANGLES)
    _SHAPES[key] = shape  # the most recent last
    for older in list(_SHAPES)[:-SHAPES_KEPT]:
        _SHAPES.pop(older, None)
    order, child, first, last = shape
    return _search(points, corners, order, *_refit(lower, upper, *shape), child, first, last)


SHAPES_KEPT = 8  # the face sets whose tree shape is kept (the arm's evaluation asks about six meshes of one a frame)
_SHAPES: dict[bytes, tuple[np.ndarray, ...]] = {}


@numba.njit(cache=True, nogil=True)
def _triangle_boxes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's box, ``lower`` and ``upper`` ``(F, 3)``; a triangle with a corner not finite has none
    (``lower`` inf, ``upper`` -inf: it widens no box)."""
    lower, upper = np.empty((len(corners), 3)), np.empty((len(corners), 3))
    for t in range(len(corners)):
        finite = True
        for axis in range(3):
            a, b, c = corners[t, 0, axis], corners[t, 1, axis], corners[t, 2, axis]
            lower[t, axis], upper[t, axis] = min(a, b, c), max(a, b, c)
            finite &= np.isfinite(a) and np.isfinite(b) and np.isfinite(c)
        if not finite:
            lower[t], upper[t] = np.inf, -np.inf
    return lower, upper


def _split(lower: np.ndarray, upper: np.ndarray, leaf_triangles: int):
    """The tree's shape over triangles with boxes ``lower``, ``upper``: the triangles in the leaves' order, and per
    node its first child (-1: a leaf; the second is next to it) and its range of that order. A node comes before its
    children. (Made once for a set of faces: plain numpy, no compiled loop to wait for.)"""
    centres = lower + upper  # doubled; a triangle with a corner not finite has none
    order = np.arange(len(lower))
    nodes = max(2 * len(order), 1)
    child, first, last = np.full(nodes, -1), np.zeros(nodes, np.int64), np.zeros(nodes, np.int64)
    last[0], made, pending = len(order), 1, [0]
    while pending:
        node = pending.pop()
        begin, end = first[node], last[node]
        if end - begin <= leaf_triangles:
            continue
        mine = centres[order[begin:end]]
        finite = np.isfinite(mine).all(axis=1)
        spread = np.ptp(mine[finite], axis=0) if finite.any() else np.zeros(3)
        order[begin:end] = order[begin:end][np.argsort(mine[:, np.argmax(spread)], kind="stable")]
        middle = (begin + end) // 2
        child[node] = made
        first[made], last[made], first[made + 1], last[made + 1] = begin, middle, middle, end
        pending += [made, made + 1]
        made += 2
    return order, child[:made], first[:made], last[:made]


@numba.njit(cache=True, nogil=True)
def _refit(lower: np.ndarray, upper: np.ndarray, order, child, first, last) -> tuple[np.ndarray, np.ndarray]:
    """Each node's box around its triangles' (``lower``, ``upper``), children before their parent."""
    node_lower, node_upper = np.empty((len(child), 3)), np.empty((len(child), 3))
    for node in range(len(child) - 1, -1, -1):
        node_lower[node], node_upper[node] = np.inf, -np.inf
        if child[node] < 0:
            for t in order[first[node] : last[node]]:
                for axis in range(3):
                    node_lower[node, axis] = min(node_lower[node, axis], lower[t, axis])
                    node_upper[node, axis] = max(node_upper[node, axis], upper[t, axis])
        else:
            for c in (child[node], child[node] + 1):
                for axis in range(3):
                    node_lower[node, axis] = min(node_lower[node, axis], node_lower[c, axis])
                    node_upper[node, axis] = max(node_upper[node, axis], node_upper[c, axis])
    return node_lower, node_upper


@numba.njit(cache=True, nogil=True, error_model="numpy")  # a sliver's division by 0: NaN, never the nearest
def _search(points, corners, order, lower, upper, child, first, last):
    nearest = np.full(len(points), -1)
    distances = np.full(len(points), np.nan)
    stack = np.empty(2 * len(child) + 1, np.int64)
    for k in range(len(points)):
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        best, depth = np.inf, 0
        if len(order) and np.isfinite(px) and np.isfinite(py) and np.isfinite(pz):
            stack[0], depth = 0, 1
        while depth:
            depth -= 1
            node = stack[depth]
            if _box_distance2(px, py, pz, lower[node], upper[node]) > best:
                continue
            if child[node] < 0:
                for t in order[first[node] : last[node]]:
                    x, y, z = _closest_on_triangle(px, py, pz, corners[t])
                    dx, dy, dz = px - x, py - y, pz - z
                    distance = (dx * dx + dy * dy) + dz * dz  # as np.linalg.norm adds the squares
                    if distance < best or (distance == best and t < nearest[k]):
                        best, nearest[k] = distance, t
                continue
            near, far = child[node], child[node] + 1
            if _box_distance2(px, py, pz, lower[far], upper[far]) < _box_distance2(
                px, py, pz, lower[near], upper[near]
            ):
                near, far = far, near
            stack[depth], stack[depth + 1] = far, near  # the nearer popped first
            depth += 2
        if nearest[k] >= 0:
            distances[k] = np.sqrt(best)
    return nearest, distances


@numba.njit(cache=True, nogil=True, inline="always")
def _box_distance2(px, py, pz, lower, upper) -> float:
    """The squared distance from the point to the box (0 inside it)."""
    gx = max(lower[0] - px, 0.0, px - upper[0])
    gy = max(lower[1] - py, 0.0, py - upper[1])
    gz = max(lower[2] - pz, 0.0, pz - upper[2])
    return gx * gx + gy * gy + gz * gz


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _closest_on_triangle(px, py, pz, triangle) -> tuple[float, float, float]:
    """Ericson's closest point on ``triangle`` ``(3, 3)`` (corners a, b, c) to the point (his regions in his order),
    as `tracker.geometry.surface_distance.point_triangle_distance` computes it, to the bit: its dot products' order
    (`_dot3`), its quotients and sums."""
    ax, ay, az = triangle[0, 0], triangle[0, 1], triangle[0, 2]
    bx, by, bz = triangle[1, 0], triangle[1, 1], triangle[1, 2]
    cx, cy, cz = triangle[2, 0], triangle[2, 1], triangle[2, 2]
    abx, aby, abz, acx, acy, acz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1, d2 = _dot3(abx, aby, abz, apx, apy, apz), _dot3(acx, acy, acz, apx, apy, apz)
    if d1 <= 0 and d2 <= 0:
        return ax, ay, az
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3, d4 = _dot3(abx, aby, abz, bpx, bpy, bpz), _dot3(acx, acy, acz, bpx, bpy, bpz)
    if d3 >= 0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        s = d1 / (d1 - d3)
        return ax + s * abx, ay + s * aby, az + s * abz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5, d6 = _dot3(abx, aby, abz, cpx, cpy, cpz), _dot3(acx, acy, acz, cpx, cpy, cpz)
    if d6 >= 0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        s = d2 / (d2 - d6)
        return ax + s * acx, ay + s * acy, az + s * acz
    va = d3 * d6 - d5 * d4
    if va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
    denominator = va + vb + vc
    v, w = vb / denominator, vc / denominator
    return ax + v * abx + w * acx, ay + v * aby + w * acy, az + v * abz + w * acz


@numba.njit(cache=True, nogil=True, inline="always")
def _dot3(ux, uy, uz, vx, vy, vz) -> float:
    """A dot product added as `tracker.geometry.surface_distance.dot3` adds it: x, z, then y."""
    return (ux * vx + uz * vz) + uy * vy
