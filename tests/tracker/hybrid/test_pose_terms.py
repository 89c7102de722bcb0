"""The compiled pass over one pose (`tracker.hybrid.pose_terms`) against the numpy pipeline it replaces, written
out here step by step (the body's bone chain and skinning, each camera's projection, the field's reading, the
nearest outline vertex by brute force), and its outline against the definition."""

import numpy as np
import pytest

from tracker.hybrid.feature_pairs import ViewPairs
from tracker.hybrid.pose_terms import UNSEEN_PX, FrameViews, normal_equations, pose_terms, residual_rows
from tracker.hybrid.silhouette_fit import SilhouetteFit
from tracker.hybrid.view_field import ViewField
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.models.pose_kernels import bone_chain
from tracker.tbf.pose_sets import arm_grid

from .test_silhouette_fit import RIG, perturbed, silhouettes, some_pairs


@pytest.fixture(scope="module")
def poses(body):
    pose = arm_grid(body, [50.0], [30.0], [20.0], [10.0], yaw_deg=-90.0)[0]
    tiny = perturbed(pose)
    tiny[3 + 3 * JOINT_INDEX["LeftLeg"] : 6 + 3 * JOINT_INDEX["LeftLeg"]] = [1e-10, 0.0, 0.0]  # Rodrigues' series
    return [pose, perturbed(pose), tiny]


def numpy_terms(body, fit, pose, fields, pairs):
    """What the fit computed before the compiled pass, as numpy computes it."""
    rotations, heads = body.bone_transforms(pose)
    points = body.posed_vertices(pose, transforms=(rotations, heads))
    blended = np.einsum("vj,jab->vab", body.weights, rotations)
    normals = np.einsum("vab,vb->va", blended, fit.rest_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    views = []
    for view, view_pairs in zip(fields, pairs, strict=True):
        camera = view.camera
        uv = np.nan_to_num(camera.project(points)[0], nan=UNSEEN_PX)
        outside, gradient = view.sample(uv[fit.region])
        rays = points - camera.position
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        dot = np.abs((normals * rays).sum(axis=1))
        outline = dot < fit.settings.outline_cos
        on_outline = np.flatnonzero(outline)
        distances = ((view.edge[:, None, :] - uv[on_outline][None]) ** 2).sum(axis=2)
        cover_vertices = on_outline[np.argmin(distances, axis=1)]
        cover = ((uv[cover_vertices] - view.edge) * view.edge_normals).sum(axis=1)
        on_body = np.einsum("kc,kcd->kd", view_pairs.barycentric, points[body.faces[view_pairs.faces]])
        seen = np.nan_to_num(camera.project(on_body)[0], nan=UNSEEN_PX) - view_pairs.pixels
        views.append(
            dict(uv=uv, outside=outside, gradient=gradient, dot=dot, distances=distances, cover=cover, seen=seen)
        )
    return rotations, heads, points, views


def test_the_compiled_pass_computes_what_the_numpy_pipeline_does(body, poses, renderer):
    fit = SilhouetteFit(body, RIG)
    pairs = [some_pairs(body, poses[0], camera) for camera in RIG]
    fields = [
        ViewField(s, camera, 400) for s, camera in zip(silhouettes(renderer, body, poses[0], RIG), RIG, strict=True)
    ]
    views = FrameViews.of(fields, pairs, body.faces)
    for pose in poses:
        found = pose_terms(body, fit.rest_normals, pose, views, fit.region, fit.settings.outline_cos)
        rotations, heads, points, expected = numpy_terms(body, fit, pose, fields, pairs)
        np.testing.assert_allclose(found.rotations, rotations, rtol=0, atol=1e-13)
        np.testing.assert_allclose(found.heads, heads, rtol=0, atol=1e-13)
        np.testing.assert_allclose(found.points, points, rtol=0, atol=1e-13)
        for k, view in enumerate(expected):
            np.testing.assert_allclose(found.outside[k], view["outside"], rtol=0, atol=1e-9)
            np.testing.assert_allclose(found.gradient[k], view["gradient"], rtol=0, atol=1e-9)
            clear = np.abs(view["dot"] - fit.settings.outline_cos) > 1e-9  # the same flags but at the threshold
            np.testing.assert_array_equal(found.outline[k][clear], (view["dot"] < fit.settings.outline_cos)[clear])
            assert 0.1 < found.outline[k].mean() < 0.6  # an outline, not all or nothing
            edges = slice(*views.edge_starts[k : k + 2])
            chosen = ((view["uv"][found.cover_vertices[edges]] - fields[k].edge) ** 2).sum(axis=1)
            np.testing.assert_allclose(chosen, view["distances"].min(axis=1), rtol=0, atol=1e-9)  # a nearest one
            np.testing.assert_allclose(found.cover[edges], view["cover"], rtol=0, atol=1e-6)
            np.testing.assert_allclose(found.seen[slice(*views.pair_starts[k : k + 2])], view["seen"], atol=1e-9)


def test_a_view_without_edge_or_outline_gives_no_cover(body, poses):
    """A view that lost the person has no edge points; every pixel of one behind its camera reads UNSEEN_PX."""
    fit = SilhouetteFit(body, RIG[:1])
    fields = [ViewField(np.zeros((240, 320), bool), RIG[0], 400)]
    views = FrameViews.of(fields, [ViewPairs.empty()], body.faces)
    found = pose_terms(body, fit.rest_normals, poses[0], views, fit.region, fit.settings.outline_cos)
    assert found.cover_vertices.shape == (0,) and found.seen.shape == (0, 2)
    assert not found.outside.any() and not found.gradient.any()


def test_the_bone_chain_is_the_bodys(body, poses):
    for pose in poses:
        rotations, heads = bone_chain(pose, body.parents, body.rest_heads, body.t_pose_alignment)
        expected = body.bone_transforms(pose)
        np.testing.assert_allclose(rotations, expected[0], rtol=0, atol=1e-14)
        np.testing.assert_allclose(heads, expected[1], rtol=0, atol=1e-14)


def test_the_normal_equations_are_the_rows_product(body, poses, renderer):
    """`normal_equations` (each residual over the columns that move it, one triangle) against ``J^T W J`` and
    ``J^T W r`` of the whole rows (`residual_rows`), with the skin's pairs and weights of every size."""
    fit = SilhouetteFit(body, RIG)
    pairs = [some_pairs(body, poses[0], camera) for camera in RIG]
    fields = [
        ViewField(s, camera, 400) for s, camera in zip(silhouettes(renderer, body, poses[0], RIG), RIG, strict=True)
    ]
    views = FrameViews.of(fields, pairs, body.faces)
    rng = np.random.default_rng(6)
    for pose in poses:
        found = pose_terms(body, fit.rest_normals, pose, views, fit.region, fit.settings.outline_cos)
        rows = residual_rows(body, pose, found, views, fit.region, fit._joints)
        values, weights = rng.normal(0, 5, len(rows)), rng.uniform(0.01, 2.0, len(rows))
        hessian, gradient = normal_equations(body, pose, found, views, fit.region, fit._joints, values, weights)
        np.testing.assert_allclose(hessian, rows.T @ (rows * weights[:, None]), rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(gradient, rows.T @ (weights * values), rtol=1e-9, atol=1e-6)
        assert np.array_equal(hessian, hessian.T) and (rows == 0).mean() > 0.3  # the skipped columns were zeros
