"""AbIS on the skinned body: the mesh's pairs (rays against faces), a body part's fitting problem, the part tree."""

import numpy as np
import pytest

from tracker.abis.body_fitting import (
    BodyPartProblem,
    MeshViewPairs,
    carried_parts,
    part_joints,
    part_parents,
    topdown_parts,
)
from tracker.abis.fitting import FitSettings, PixelProblem, Prior, fit_part
from tracker.abis.mesh_pairs import MeshPairs, ray_hits
from tracker.geometry.rigs import View, cameras
from tracker.models.body_skeleton import PART_NAMES, POSE_SIZE
from tracker.motion.posture import arms_pose

RIG = cameras(
    views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9))), width=640, height=480, focal_px=840.0
)


def _naive_ray_hits(camera, pixels, vertices, faces):
    """Each ray against each triangle, one at a time, by solving origin + t d = a + u (b - a) + v (c - a)."""
    hit, barycentric = np.full(len(pixels), -1), np.zeros((len(pixels), 3))
    for row, (u_px, v_px) in enumerate(pixels):
        direction = camera.rotation @ np.array([(u_px - camera.cx) / camera.fx, (v_px - camera.cy) / camera.fy, 1.0])
        best = np.inf
        for index, (a, b, c) in enumerate(vertices[faces]):
            matrix = np.column_stack([direction, a - b, a - c])
            if abs(np.linalg.det(matrix)) < 1e-12:
                continue
            t, u, v = np.linalg.solve(matrix, a - camera.position)
            if u >= 0 and v >= 0 and u + v <= 1 and 0 < t < best:
                best, hit[row], barycentric[row] = t, index, (1 - u - v, u, v)
    return hit, barycentric


def test_rays_meet_the_nearest_face_under_each_pixel_as_a_naive_search_finds_it(body):
    camera = RIG[0]
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-30.0)
    vertices = body.posed_vertices(pose)
    faces = body.faces[np.flatnonzero(body.face_parts == PART_NAMES.index("torso"))]
    centre = camera.project(vertices[faces].mean(axis=(0, 1))[None])[0][0]
    pixels = centre + np.random.default_rng(0).uniform(-60, 60, (40, 2))  # some on the torso, some beside it
    hit, barycentric = ray_hits(camera, pixels, vertices, faces)
    naive_hit, naive_barycentric = _naive_ray_hits(camera, pixels, vertices, faces)
    np.testing.assert_array_equal(hit, naive_hit)
    np.testing.assert_allclose(barycentric, naive_barycentric, atol=1e-9)
    assert 5 < (hit >= 0).sum() < len(pixels)  # both cases are exercised
    found = hit >= 0
    points = MeshPairs(
        np.arange(found.sum()), np.zeros(found.sum(), int), np.zeros(found.sum(), int), hit[found], barycentric[found]
    ).points(vertices, faces)
    np.testing.assert_allclose(camera.project(points)[0], pixels[found], atol=1e-6)  # the point is under its pixel


def test_rays_tried_against_the_faces_nearest_their_pixels_meet_the_front_face_of_the_whole_body(body):
    """With ``nearest``, the same hits as every face tried (the naive search), over the whole body: the arms cross
    in front of the torso, so many rays pass several layers."""
    camera = RIG[0]
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-30.0)
    vertices = body.posed_vertices(pose)
    inside = np.flatnonzero(np.isfinite(camera.project(vertices)[0]).all(axis=1))
    pixels = camera.project(vertices[inside[:: len(inside) // 30]])[0] + 0.3  # on the body, beside a vertex
    hit, barycentric = ray_hits(camera, pixels, vertices, body.faces, nearest=64)
    naive_hit, naive_barycentric = _naive_ray_hits(camera, pixels, vertices, body.faces)
    np.testing.assert_array_equal(hit, naive_hit)
    np.testing.assert_allclose(barycentric, naive_barycentric, atol=1e-9)
    assert (hit >= 0).mean() > 0.75  # some beside the outline miss


def test_the_part_tree_runs_from_the_pelvis_and_each_part_carries_its_limb(body):
    parents = part_parents(body.parents)
    name = dict(enumerate(PART_NAMES))
    by_name = {name[part]: None if parent is None else name[parent] for part, parent in enumerate(parents)}
    assert [part for part, parent in by_name.items() if parent is None] == ["pelvis"]
    assert by_name["torso"] == "pelvis" and by_name["head"] == "torso" and by_name["left_upper_arm"] == "torso"
    assert by_name["right_hand"] == "right_forearm" and by_name["left_foot"] == "left_shin"
    order = [name[part] for part in topdown_parts(parents)]
    assert sorted(order) == sorted(PART_NAMES) and order[0] == "pelvis"
    assert all(order.index(by_name[part]) < order.index(part) for part in order if by_name[part] is not None)
    carried = {name[part] for part in carried_parts(parents, PART_NAMES.index("right_upper_arm"))}
    assert carried == {"right_upper_arm", "right_forearm", "right_hand"}
    assert len(carried_parts(parents, PART_NAMES.index("pelvis"))) == len(PART_NAMES)
    assert sum(len(joints) for joints in part_joints()) <= (POSE_SIZE - 3) // 3  # every joint in at most one part


def _pairs_on(body, pose, part, rng):
    """Each view's pairs on ``part``: random points of its faces and their pixels at ``pose``."""
    faces = np.flatnonzero(body.face_parts == part)
    views = []
    for camera in RIG:
        chosen = rng.choice(faces, 12, replace=False)
        barycentric = rng.dirichlet(np.ones(3), 12)
        corners = body.faces[chosen]
        points = np.einsum("mc,mcd->md", barycentric, body.posed_vertices(pose)[corners])
        views.append(MeshViewPairs(camera, corners, barycentric, camera.project(points)[0]))
    return views


def test_a_body_parts_pixel_jacobian_matches_central_differences(body):
    """The problem's Jacobian (skinned vertices' analytic one, blended by barycentric weights, projected) against
    central differences of its own residuals, for the root part (position too) and a forearm; with the prior rows."""
    rng = np.random.default_rng(1)
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-30.0)
    pose[3:] += rng.normal(0.0, 0.1, POSE_SIZE - 3)
    settings = FitSettings(huber_px=None)  # plain squares: the Jacobian is the residuals' own
    parents = part_parents(body.parents)
    for part in (PART_NAMES.index("pelvis"), PART_NAMES.index("right_forearm")):
        prior = Prior(reference=pose + rng.normal(0.0, 0.02, POSE_SIZE), sigmas=np.full(POSE_SIZE, 0.1))
        problem = BodyPartProblem(
            body, _pairs_on(body, pose, part, rng), part_joints()[part], parents[part] is None, prior
        )
        q = pose + rng.normal(0.0, 0.03, POSE_SIZE)
        analytic = problem.evaluate(q, settings).jacobian
        numeric = np.zeros_like(analytic)
        for column, entry in enumerate(problem.free):
            step = np.zeros(POSE_SIZE)
            step[entry] = 1e-6
            plus, minus = (problem.evaluate(q + sign * step, settings).vector for sign in (1, -1))
            numeric[:, column] = (plus - minus) / 2e-6
        np.testing.assert_allclose(analytic, numeric, atol=1e-4 * np.abs(numeric).max())
        assert np.abs(numeric).max() > 10  # pixels per radian: not a vacuous comparison


def test_a_body_parts_compiled_points_and_jacobian_are_the_numpy_pipelines(body):
    """The problem's pair points and their Jacobian (one compiled pass each) against `BodyMesh.posed_vertices` and
    `vertex_jacobian` blended by the pairs' barycentric weights, to rounding: the root part (its position's
    columns too) and a forearm's two joints."""
    from tracker.models.skinning_jacobian import vertex_jacobian

    rng = np.random.default_rng(3)
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-30.0)
    pose[3:] += rng.normal(0.0, 0.3, POSE_SIZE - 3)
    for part, root in ((PART_NAMES.index("pelvis"), True), (PART_NAMES.index("right_forearm"), False)):
        views = _pairs_on(body, pose, part, rng)
        problem = BodyPartProblem(body, views, part_joints()[part], root)
        corners = np.concatenate([view.corners for view in views])
        barycentric = np.concatenate([view.barycentric for view in views])
        points, jacobian = problem.points(pose)
        expected = np.einsum("mc,mcd->md", barycentric, body.posed_vertices(pose)[corners])
        np.testing.assert_allclose(points, expected, rtol=0, atol=1e-12)
        of_vertices = vertex_jacobian(body, pose, corners.ravel(), part_joints()[part])
        of_vertices = of_vertices.reshape(*corners.shape, 3, -1)[..., slice(0 if root else 3, None)]
        expected = np.einsum("mc,mcdk->mdk", barycentric, of_vertices)
        np.testing.assert_allclose(jacobian(), expected, rtol=0, atol=1e-12)
        assert np.abs(expected).max() > 0.1  # metres per radian: not a vacuous comparison
        # The residuals, their cost and weights, and the pixel rows: the compiled passes against the generic
        # pipeline (`PixelProblem.pixel_terms`: the points projected by each camera), plain and robust.
        q = pose + rng.normal(0.0, 0.05, POSE_SIZE)
        middle = float(np.median(np.linalg.norm(PixelProblem.pixel_terms(problem, q, None)[0], axis=1)))
        for huber_px in (None, middle):  # robust: half the pairs beyond the threshold
            compiled, generic = problem.pixel_terms(q, huber_px), PixelProblem.pixel_terms(problem, q, huber_px)
            np.testing.assert_allclose(compiled[0], generic[0], rtol=0, atol=1e-9)  # pixels
            assert compiled[1] == pytest.approx(generic[1], rel=1e-12) and generic[1] > 1.0
            np.testing.assert_allclose(compiled[2], generic[2], rtol=1e-12)
            assert huber_px is None or 0 < (generic[2] < 1).sum() < len(generic[2])  # both sides of the threshold
            np.testing.assert_allclose(compiled[3](), generic[3](), rtol=0, atol=1e-9 * np.abs(generic[3]()).max())


def test_fitting_a_part_brings_back_its_pose_from_its_pairs(body):
    """Pairs made at a pose, the part's joints then disturbed by 0.15 rad: Levenberg-Marquardt over the part's own
    entries returns to the pose (the other entries untouched)."""
    rng = np.random.default_rng(2)
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-30.0)
    part = PART_NAMES.index("left_upper_arm")
    problem = BodyPartProblem(body, _pairs_on(body, pose, part, rng), part_joints()[part], root=False)
    start = pose.copy()
    start[problem.free] += rng.normal(0.0, 0.15, len(problem.free))
    fitted = fit_part(start, problem, FitSettings(huber_px=None))
    np.testing.assert_allclose(fitted.params[problem.free], pose[problem.free], atol=1e-4)
    others = np.setdiff1d(np.arange(POSE_SIZE), problem.free)
    np.testing.assert_array_equal(fitted.params[others], start[others])
    assert fitted.cost < 1e-6


@pytest.fixture(scope="module")
def body_run(tmp_path_factory):
    """6 frames of the body's arm swing by AbIS through the command line (with what its fit needs: 3 views at
    640x480, the textured skin)."""
    import json

    from tests.conftest import run_cli

    out = tmp_path_factory.mktemp("body_abis") / "out"
    needed = ("rig=body_multi_vga", "model.texture_seed=0")
    result = run_cli(out, "model=body_mesh", "tracker=abis", *needed, "frames=6", cwd=out.parent)
    assert result.returncode == 0, result.stderr
    return out, json.loads((out / "metrics.json").read_text())


def test_the_body_by_abis_follows_the_arm_swing_with_pairs_that_balance(body_run):
    import pandas as pd

    out, metrics = body_run
    assert metrics["status"] == "ok" and metrics["failed_frames"] == 0 and len(metrics["views"]) == 3
    assert metrics["mpjpe_mm"] < 20.0  # measured 7.8 mm: it starts at the truth (plus noise) and keeps it
    table = pd.read_parquet(out / "frames.parquet").sort_values(["part", "frame"])
    for _, rows in table.groupby("part"):
        pairs, tracked, lost = rows["pairs"].to_numpy(), rows["tracked"].to_numpy(), rows["lost"].to_numpy()
        np.testing.assert_array_equal(tracked[1:], pairs[:-1] - lost[1:])
        np.testing.assert_array_equal(
            pairs, tracked - rows["discarded_occlusion"] - rows["discarded_error"] + rows["new"]
        )
    per_part = table.groupby("part")["pairs"].mean()
    assert per_part["torso"] > 20 and per_part["head"] > 10  # the textured skin gives features to pair


def test_the_figures_of_a_body_abis_run_are_those_that_apply_to_it(body_run, tmp_path):
    """The views sheet, Fig 5's strip (the estimate on the subject's own mesh, which AbIS tracks) and the error per
    frame, with no floor (AbIS searches no dictionary); paper 1's figures are of the DSQ arm and are left out, and
    6 frames hold no complete swing."""
    import shutil

    import matplotlib.image

    from eval.figures import write_figures

    out = shutil.copytree(body_run[0], tmp_path / "run")
    written = write_figures(out)
    assert [path.name for path in written] == ["views.png", "fig5_strip.png", "error_against_floor.png"]
    assert all(matplotlib.image.imread(path).std() > 0.05 for path in written)  # drawn, not blank
