"""One pose's silhouette and feature residuals in one compiled pass: what `tracker.hybrid.silhouette_fit` asks of
every pose it tries, 25-50 poses a frame.

The pass is the numpy pipeline's arithmetic, pose by pose: the bone chain (`BodyMesh.bone_transforms`, compiled in
`tracker.models.pose_kernels` with the levers and axes the Jacobian takes), linear-blend skinning over each vertex's
few bones (`BodyMesh.posed_vertices`), the outline (each vertex whose skinned unit normal is within ``outline_cos``
of square to a camera's ray), and per view the vertices' pixels (`Camera.project`; behind the camera, -1000 px), the
field at the region's vertices (`ViewField.sample`), the outline vertex nearest each edge point
(`tracker.geometry.nearest_points`) with its cover residual, and the feature pairs' residuals. A second pass gives
the residuals' Jacobian rows (`residual_rows`), or the Gauss-Newton system they make (`normal_equations`). On a body
of ~2,000 vertices each step is a few microseconds of arithmetic; as numpy calls (~60 a pose) they took ten times as
long. Sums run in another order than numpy's BLAS products, so the numbers agree with the numpy pipeline to
rounding, not to the bit (`tests/tracker/hybrid`).

`FrameViews` packs one frame's views (cameras, fields, edges, pairs) into flat arrays, each view's rows from
``starts[view]`` to ``starts[view + 1]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from tracker.bilinear import bilinear
from tracker.geometry.nearest_points import nearest_points_compiled
from tracker.hybrid.feature_pairs import ViewPairs
from tracker.hybrid.view_field import ViewField
from tracker.models.body_mesh import BodyMesh
from tracker.models.pose_kernels import add_vertex_levers, bone_chain, bone_offsets, joint_axes
from tracker.tol import MIN_DEPTH_M

UNSEEN_PX = -1e3  # the pixel of a point behind a camera (the numpy pipeline's nan_to_num)


@dataclass(frozen=True, eq=False)
class FrameViews:
    """One frame's views as the compiled pass reads them. Per view ``(views, ...)``: the camera's ``positions``,
    ``rotations`` (world to camera: p_cam = (p - position) @ rotation), ``intrinsics`` (fx, fy, cx, cy),
    ``image_sizes`` (width, height); its field (`ViewField`: outside distance and gradient) in ``fields`` ``(views,
    3, h, w)`` (each view's window at the top left, its ``field_shapes`` (h, w)), the window's ``offsets`` (u, v).
    The views' ``edges`` and ``edge_normals`` ``(E, 2)`` one after another (``edge_starts`` ``(views + 1,)``), and
    their feature pairs: ``pair_corners`` ``(P, 3)`` vertex indices, ``pair_barycentric`` ``(P, 3)``,
    ``pair_pixels`` ``(P, 2)`` (``pair_starts``)."""

    positions: np.ndarray
    rotations: np.ndarray
    intrinsics: np.ndarray
    image_sizes: np.ndarray
    fields: np.ndarray
    field_shapes: np.ndarray
    offsets: np.ndarray
    edges: np.ndarray
    edge_normals: np.ndarray
    edge_starts: np.ndarray
    pair_corners: np.ndarray
    pair_barycentric: np.ndarray
    pair_pixels: np.ndarray
    pair_starts: np.ndarray

    @classmethod
    def of(cls, fields: Sequence[ViewField], pairs: Sequence[ViewPairs], faces: np.ndarray) -> FrameViews:
        cameras = [view.camera for view in fields]
        shapes = np.array([view.outside.shape for view in fields], dtype=np.int64).reshape(-1, 2)
        packed = np.zeros((len(fields), 3, *shapes.max(axis=0, initial=1)))
        for k, view in enumerate(fields):
            packed[k, :, : shapes[k, 0], : shapes[k, 1]] = view.sampled

        def starts(sizes: Sequence[int]) -> np.ndarray:
            return np.r_[0, np.cumsum(sizes, dtype=np.int64)].astype(np.int64)

        def joined(arrays: Sequence[np.ndarray], width: int, dtype=np.float64) -> np.ndarray:
            return np.ascontiguousarray(np.concatenate([np.empty((0, width), dtype), *arrays]).astype(dtype))

        return cls(
            positions=np.array([camera.position for camera in cameras], dtype=np.float64).reshape(-1, 3),
            rotations=np.array([camera.rotation for camera in cameras], dtype=np.float64).reshape(-1, 3, 3),
            intrinsics=np.array([[c.fx, c.fy, c.cx, c.cy] for c in cameras], dtype=np.float64).reshape(-1, 4),
            image_sizes=np.array([view.image_size for view in fields], dtype=np.float64).reshape(-1, 2),
            fields=packed,
            field_shapes=shapes,
            offsets=np.array([view.offset for view in fields], dtype=np.float64).reshape(-1, 2),
            edges=joined([view.edge for view in fields], 2),
            edge_normals=joined([view.edge_normals for view in fields], 2),
            edge_starts=starts([len(view.edge) for view in fields]),
            pair_corners=joined([faces[p.faces] for p in pairs], 3, np.int64),
            pair_barycentric=joined([p.barycentric for p in pairs], 3),
            pair_pixels=joined([p.pixels for p in pairs], 2),
            pair_starts=starts([len(p) for p in pairs]),
        )


class PoseTerms(NamedTuple):
    """What `pose_terms` makes of one pose: its bones' ``rotations`` ``(J, 3, 3)`` and ``heads`` ``(J, 3)``, its
    skinned ``points`` ``(V, 3)``; per view the region vertices' ``outside`` distances ``(views, R)`` and their
    ``gradient`` ``(views, R, 2)``; per edge point (`FrameViews.edges`) the outline vertex nearest it in the image,
    ``cover_vertices`` ``(E,)`` (-1: the view has no outline vertex), and its ``cover`` residual; per pair its
    ``seen`` pixel less its feature's, ``(P, 2)``; and each view's ``outline`` ``(views, V)`` bool."""

    rotations: np.ndarray
    heads: np.ndarray
    points: np.ndarray
    outside: np.ndarray
    gradient: np.ndarray
    cover_vertices: np.ndarray
    cover: np.ndarray
    seen: np.ndarray
    outline: np.ndarray


def pose_terms(
    body: BodyMesh,
    rest_normals: np.ndarray,
    pose: np.ndarray,
    views: FrameViews,
    region: np.ndarray,
    outline_cos: float,
) -> PoseTerms:
    """`PoseTerms` of ``pose`` seen by ``views``: the ``region`` vertices' field readings and every view's cover
    (outline: a vertex whose skinned unit normal, from ``rest_normals``, is within ``outline_cos`` of square to the
    camera's ray)."""
    weights = body.sparse_weights
    return PoseTerms(
        *_pose_terms(
            np.ascontiguousarray(pose, dtype=np.float64),
            body.parents,
            body.rest_heads,
            body.t_pose_alignment,
            weights.indptr,
            weights.indices,
            weights.data,
            body.rest_vertices,
            rest_normals,
            views.positions,
            views.rotations,
            views.intrinsics,
            views.image_sizes,
            views.fields,
            views.field_shapes,
            views.offsets,
            views.edges,
            views.edge_normals,
            views.edge_starts,
            views.pair_corners,
            views.pair_barycentric,
            views.pair_pixels,
            views.pair_starts,
            region,
            outline_cos,
        )
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")  # a point on a camera's centre: NaN, not on the outline
def _pose_terms(
    pose,
    parents,
    rest_heads,
    alignment,
    indptr,
    indices,
    weights,
    rest,
    rest_normals,
    positions,
    camera_rotations,
    intrinsics,
    image_sizes,
    fields,
    field_shapes,
    offsets,
    edges,
    edge_normals,
    edge_starts,
    pair_corners,
    pair_barycentric,
    pair_pixels,
    pair_starts,
    region,
    outline_cos,
):
    """`pose_terms`' pass, from the body's and the views' arrays."""
    rotations, heads = bone_chain(pose, parents, rest_heads, alignment)
    vertices, views = len(rest), len(positions)
    offsets_bone = bone_offsets(rotations, heads, rest_heads)  # bone b carries x to R_b x + o_b
    points, normals = np.zeros((vertices, 3)), np.zeros((vertices, 3))
    for v in range(vertices):
        x, n = rest[v], rest_normals[v]
        for entry in range(indptr[v], indptr[v + 1]):
            bone, weight = indices[entry], weights[entry]
            for a in range(3):
                r = rotations[bone, a]
                points[v, a] += weight * (r[0] * x[0] + r[1] * x[1] + r[2] * x[2] + offsets_bone[bone, a])
                normals[v, a] += weight * (r[0] * n[0] + r[1] * n[1] + r[2] * n[2])
        length = max(np.sqrt(normals[v, 0] ** 2 + normals[v, 1] ** 2 + normals[v, 2] ** 2), 1e-12)
        for a in range(3):
            normals[v, a] /= length

    outside, gradient = np.zeros((views, len(region))), np.zeros((views, len(region), 2))
    cover_vertices, cover = np.full(len(edges), -1, np.int64), np.zeros(len(edges))
    seen = np.empty((len(pair_corners), 2))
    uv = np.empty((vertices, 2))
    outline, on_outline = np.zeros((views, vertices), np.bool_), np.empty(vertices, np.int64)
    local = np.empty((len(region), 2))
    for view in range(views):
        fx, fy, cx, cy = intrinsics[view, 0], intrinsics[view, 1], intrinsics[view, 2], intrinsics[view, 3]
        turn, at = camera_rotations[view], positions[view]
        width, height = image_sizes[view, 0], image_sizes[view, 1]
        count = 0
        for v in range(vertices):
            rx, ry, rz = points[v, 0] - at[0], points[v, 1] - at[1], points[v, 2] - at[2]
            z = rx * turn[0, 2] + ry * turn[1, 2] + rz * turn[2, 2]
            if z > MIN_DEPTH_M:
                uv[v, 0] = fx * (rx * turn[0, 0] + ry * turn[1, 0] + rz * turn[2, 0]) / z + cx
                uv[v, 1] = fy * (rx * turn[0, 1] + ry * turn[1, 1] + rz * turn[2, 1]) / z + cy
            else:
                uv[v, 0] = uv[v, 1] = UNSEEN_PX
            distance = np.sqrt(rx * rx + ry * ry + rz * rz)
            if abs(normals[v, 0] * rx + normals[v, 1] * ry + normals[v, 2] * rz) / distance < outline_cos:
                outline[view, v] = True
                on_outline[count] = v
                count += 1
        for k in range(len(region)):
            local[k, 0] = uv[region[k], 0] - offsets[view, 0]
            local[k, 1] = uv[region[k], 1] - offsets[view, 1]
        sampled = bilinear(fields[view, :, : field_shapes[view, 0], : field_shapes[view, 1]], local)
        for k in range(len(region)):
            u, w = uv[region[k], 0], uv[region[k], 1]
            if not (u < -0.5 or w < -0.5 or u > width - 0.5 or w > height - 0.5):
                outside[view, k] = sampled[k, 0]
                gradient[view, k, 0], gradient[view, k, 1] = sampled[k, 1], sampled[k, 2]
        first, last = edge_starts[view], edge_starts[view + 1]
        if count > 0 and last > first:
            nearest = _nearest_outline(uv, on_outline[:count], edges[first:last])
            for e in range(first, last):
                vertex = nearest[e - first]
                cover_vertices[e] = vertex
                cover[e] = (uv[vertex, 0] - edges[e, 0]) * edge_normals[e, 0] + (
                    uv[vertex, 1] - edges[e, 1]
                ) * edge_normals[e, 1]
        for p in range(pair_starts[view], pair_starts[view + 1]):
            blended = np.zeros(3)
            for c in range(3):
                corner = pair_corners[p, c]
                for a in range(3):
                    blended[a] += pair_barycentric[p, c] * points[corner, a]
            rx, ry, rz = blended[0] - at[0], blended[1] - at[1], blended[2] - at[2]
            z = rx * turn[0, 2] + ry * turn[1, 2] + rz * turn[2, 2]
            if z > MIN_DEPTH_M:
                seen[p, 0] = fx * (rx * turn[0, 0] + ry * turn[1, 0] + rz * turn[2, 0]) / z + cx - pair_pixels[p, 0]
                seen[p, 1] = fy * (rx * turn[0, 1] + ry * turn[1, 1] + rz * turn[2, 1]) / z + cy - pair_pixels[p, 1]
            else:
                seen[p, 0], seen[p, 1] = UNSEEN_PX - pair_pixels[p, 0], UNSEEN_PX - pair_pixels[p, 1]
    return rotations, heads, points, outside, gradient, cover_vertices, cover, seen, outline


@numba.njit(cache=True, nogil=True)
def _nearest_outline(uv: np.ndarray, outline: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """For each ``edge`` point, the vertex of ``outline`` (indices into ``uv``) nearest it in the image."""
    points = np.empty((len(outline), 2))
    for k in range(len(outline)):
        points[k] = uv[outline[k]]
    return outline[nearest_points_compiled(points, np.ascontiguousarray(edge))]


def residual_rows(
    body: BodyMesh, pose: np.ndarray, found: PoseTerms, views: FrameViews, region: np.ndarray, joints: np.ndarray
) -> np.ndarray:
    """``(N, 3 + 3 K)``: the derivatives of every residual of ``pose`` (`pose_terms`' ``found``, in the fit's order:
    per view the region's, the cover's, then each pair's u and v) by the root's position and the rotation vectors
    of ``joints`` (K). A residual ``d . pixel`` of a point on the body (a vertex, or a pair's blend of a face's
    corners) has, with g the pixel direction d pulled back to the world (``J_proj^T d``,
    `tracker.geometry.cameras.projection_jacobian`), the root's columns the point's weight sum times g, and a joint's
    column c ``g . (a_c x L) = a_c . (L x g)`` (`tracker.models.skinning_jacobian`: a_c the world axis the rotation
    vector's component c turns about, L the point's lever about the joint): a scalar triple product per joint."""
    return _rows_or_normal_equations(body, pose, found, views, region, joints, np.empty(0), np.empty(0))[0]


def normal_equations(
    body: BodyMesh,
    pose: np.ndarray,
    found: PoseTerms,
    views: FrameViews,
    region: np.ndarray,
    joints: np.ndarray,
    values: np.ndarray,
    weights: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``J^T W J`` ``(C, C)`` and ``J^T W r`` ``(C,)`` of the rows J (`residual_rows`), the residuals ``values`` r
    and their ``weights`` W ``(N,)``, without the rows: each residual's product is taken over the columns that move
    it (the root's, and the joints above its bones: a hand's point is moved by 8 of 21 joints, a foot's by 4), and
    over one triangle of the symmetric product."""
    return _rows_or_normal_equations(body, pose, found, views, region, joints, values, weights)[1:]


def _rows_or_normal_equations(body, pose, found, views, region, joints, values, weights):
    skinning = body.sparse_weights
    return _residual_rows(
        np.ascontiguousarray(pose, dtype=np.float64),
        found.rotations,
        found.heads,
        body.rest_heads,
        body.t_pose_alignment,
        np.asarray(joints, dtype=np.int64),
        np.ascontiguousarray(body.descendants[joints].T),
        skinning.indptr,
        skinning.indices,
        skinning.data,
        body.rest_vertices,
        found.points,
        views.positions,
        views.rotations,
        views.intrinsics,
        region,
        found.gradient,
        found.cover_vertices,
        views.edge_normals,
        views.edge_starts,
        views.pair_corners,
        views.pair_barycentric,
        views.pair_starts,
        np.ascontiguousarray(values, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64),
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")  # a point on the camera's plane: inf, as numpy gives
def _residual_rows(
    pose,
    rotations,
    heads,
    rest_heads,
    alignment,
    joints,
    below,
    indptr,
    indices,
    weights,
    rest,
    points,
    positions,
    camera_rotations,
    intrinsics,
    region,
    gradient,
    cover_vertices,
    edge_normals,
    edge_starts,
    pair_corners,
    pair_barycentric,
    pair_starts,
    values,
    residual_weights,
):
    """`residual_rows` (``values`` empty), or `normal_equations`: the rows, or the product and gradient."""
    views, count = len(positions), len(joints)
    offsets = bone_offsets(rotations, heads, rest_heads)
    axes = joint_axes(pose, rotations, alignment, joints)
    joint_heads = np.empty((count, 3))
    for k in range(count):
        joint_heads[k] = heads[joints[k]]
    size = 0
    for view in range(views):
        first, last = edge_starts[view], edge_starts[view + 1]
        covered = last - first if last > first and cover_vertices[first] >= 0 else 0
        size += len(region) + covered + 2 * (pair_starts[view + 1] - pair_starts[view])
    columns, accumulate = 3 + 3 * count, len(values) > 0
    rows = np.empty((0 if accumulate else size, columns))
    product, pulled = np.zeros((columns, columns)), np.zeros(columns)  # J^T W J, J^T W r
    levers, point, g = np.empty(1 + 3 * count), np.empty(3), np.empty(3)
    reached, starts_of, line = np.zeros(count, np.bool_), np.empty(count + 1, np.int64), np.empty(columns)
    row = 0
    for view in range(views):
        fx, fy, turn, at = intrinsics[view, 0], intrinsics[view, 1], camera_rotations[view], positions[view]
        first, last = edge_starts[view], edge_starts[view + 1]
        covered = last - first if last > first and cover_vertices[first] >= 0 else 0
        residuals = len(region) + covered + (pair_starts[view + 1] - pair_starts[view])  # a pair: two rows
        for r in range(residuals):
            levers[:] = 0.0
            point[:] = 0.0
            reached[:] = False
            if r < len(region) + covered:  # a vertex
                vertex = region[r] if r < len(region) else cover_vertices[first + r - len(region)]
                add_vertex_levers(
                    vertex, 1.0, rest, indptr, indices, weights, rotations, offsets, joint_heads, below, levers, reached
                )
                point[:] = points[vertex]
            else:  # a pair's point, blended of its face's corners
                pair = pair_starts[view] + r - len(region) - covered
                for c in range(3):
                    share, vertex = pair_barycentric[pair, c], pair_corners[pair, c]
                    add_vertex_levers(
                        vertex,
                        share,
                        rest,
                        indptr,
                        indices,
                        weights,
                        rotations,
                        offsets,
                        joint_heads,
                        below,
                        levers,
                        reached,
                    )
                    for a in range(3):
                        point[a] += share * points[vertex, a]
            rx, ry, rz = point[0] - at[0], point[1] - at[1], point[2] - at[2]
            x = rx * turn[0, 0] + ry * turn[1, 0] + rz * turn[2, 0]
            y = rx * turn[0, 1] + ry * turn[1, 1] + rz * turn[2, 1]
            z = rx * turn[0, 2] + ry * turn[1, 2] + rz * turn[2, 2]
            for direction in range(1 if r < len(region) + covered else 2):
                if r < len(region):
                    du_weight, dv_weight = gradient[view, r, 0], gradient[view, r, 1]
                elif r < len(region) + covered:
                    e = first + r - len(region)
                    du_weight, dv_weight = edge_normals[e, 0], edge_normals[e, 1]
                else:
                    du_weight, dv_weight = (1.0, 0.0) if direction == 0 else (0.0, 1.0)
                blocks = 1  # the root's columns, then those of each joint that moves the point: 3 each
                starts_of[0] = 0
                for b in range(3):  # g = J_proj^T d, J_proj as `projection_jacobian` has it (axes: turn^T)
                    du = fx * (turn[b, 0] * z - x * turn[b, 2]) / z**2
                    dv = fy * (turn[b, 1] * z - y * turn[b, 2]) / z**2
                    g[b] = du_weight * du + dv_weight * dv
                    line[b] = levers[0] * g[b]
                for k in range(count):
                    if not reached[k]:  # its lever is 0
                        continue
                    lever = levers[1 + 3 * k : 4 + 3 * k]
                    turn0 = lever[1] * g[2] - lever[2] * g[1]  # L x g
                    turn1 = lever[2] * g[0] - lever[0] * g[2]
                    turn2 = lever[0] * g[1] - lever[1] * g[0]
                    for c in range(3):
                        line[3 + 3 * k + c] = axes[k, c, 0] * turn0 + axes[k, c, 1] * turn1 + axes[k, c, 2] * turn2
                    starts_of[blocks] = 3 + 3 * k
                    blocks += 1
                if not accumulate:
                    rows[row] = 0.0
                    for i in range(blocks):
                        for c in range(3):
                            rows[row, starts_of[i] + c] = line[starts_of[i] + c]
                else:  # the upper triangle, block by block over the columns that move the residual
                    weight = residual_weights[row]
                    for i in range(blocks):
                        a = starts_of[i]
                        w0, w1, w2 = weight * line[a], weight * line[a + 1], weight * line[a + 2]
                        pulled[a] += w0 * values[row]
                        pulled[a + 1] += w1 * values[row]
                        pulled[a + 2] += w2 * values[row]
                        for j in range(i, blocks):
                            c = starts_of[j]
                            l0, l1, l2 = line[c], line[c + 1], line[c + 2]
                            product[a, c] += w0 * l0
                            product[a, c + 1] += w0 * l1
                            product[a, c + 2] += w0 * l2
                            product[a + 1, c] += w1 * l0
                            product[a + 1, c + 1] += w1 * l1
                            product[a + 1, c + 2] += w1 * l2
                            product[a + 2, c] += w2 * l0
                            product[a + 2, c + 1] += w2 * l1
                            product[a + 2, c + 2] += w2 * l2
                row += 1
    for a in range(columns):  # the lower triangle from the upper (a diagonal block's own lower part too)
        for b in range(a):
            product[a, b] = product[b, a]
    return rows, product, pulled
