"""The hybrid's silhouette fit: its analytic Jacobian against finite differences, and a perturbed pose recovered
from real renders of the body (OSMesa) by the fit alone."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.evaluation.body import joint_errors_mm
from tracker.geometry.cameras import wholly_in_view
from tracker.geometry.rigs import View, cameras
from tracker.hybrid.feature_pairs import FeaturePairs, FeaturePairSettings, ViewPairs
from tracker.hybrid.silhouette_fit import FitSettings, SilhouetteFit, mean_huber
from tracker.models.body_skeleton import JOINT_INDEX
from tracker.tbf.pose_sets import arm_grid

RIG = cameras(
    views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9)), View("oblique", (3.182, -3.182, 0.9)))
)


@pytest.fixture(scope="module")
def pose(body):
    return arm_grid(body, [50.0], [30.0], [20.0], [10.0], yaw_deg=-90.0)[0]


def silhouettes(renderer, body, pose, rig):
    views = renderer.render(rig, body.surface_meshes(pose))
    return [views[camera.name].labels > 0 for camera in rig]


def test_every_residuals_rows_are_the_derivative_of_its_point_projected(body, pose, renderer):
    """Every residual ``d . pixel`` of the fit (the region's vertices along the field's gradient, the cover's along
    the edge's normal, the pairs' points along u and v): its rows by the fitted parameters, from the joints'
    levers, against central differences of the skinning (`BodyMesh.posed_vertices`) and the projection
    (`Camera.project`), each residual's point and direction held as the pose gives them."""
    fit = SilhouetteFit(body, RIG)
    pairs = [some_pairs(body, pose, camera) for camera in RIG]
    fit.observe(silhouettes(renderer, body, perturbed(pose), RIG), pairs)
    terms, found = fit._kept_terms(pose[None])[0]
    rows = np.concatenate([term.rows for term in fit.residuals(pose)])
    cover = found.cover_vertices

    def pixels_along(moved):
        """Each residual's direction times its point's pixel at ``moved``, in the terms' order."""
        points, along = body.posed_vertices(moved), []
        for k, camera in enumerate(RIG):
            uv = camera.project(points)[0]
            edges = slice(*fit._views.edge_starts[k : k + 2])
            along += [(found.gradient[k] * uv[fit.region]).sum(1)]
            along += [(fit._views.edge_normals[edges] * uv[cover[edges]]).sum(1)]
            on_body = np.einsum("kc,kcd->kd", pairs[k].barycentric, points[body.faces[pairs[k].faces]])
            along += [camera.project(on_body)[0].ravel()]
        return np.concatenate(along)

    assert len(rows) == len(pixels_along(pose)) == sum(len(term.values) for term in terms)
    assert (cover >= 0).all() and all(len(term.values) for term in terms)  # every term has residuals
    step = 1e-6
    for column in (0, 2, 3, 5, 10, 40, len(fit.columns) - 1):  # the root's position, the root's and limbs' joints
        moved = pose.copy()
        moved[fit.columns[column]] += step
        numeric = (pixels_along(moved) - pixels_along(pose - (moved - pose))) / (2 * step)
        np.testing.assert_allclose(rows[:, column], numeric, rtol=1e-4, atol=1e-4)
    assert np.abs(rows).max() > 50  # the columns move pixels, the test is not of zeros


def perturbed(pose):
    start = pose.copy()
    start[:3] += [0.04, -0.03, 0.02]
    for joint, turn in (("RightArm", [0.0, 0.3, 0.0]), ("LeftForeArm", [0.25, 0.0, 0.0]), ("Hips", [0, 0, 0.12])):
        start[3 + 3 * JOINT_INDEX[joint] : 6 + 3 * JOINT_INDEX[joint]] += turn
    return start


@pytest.mark.parametrize("aside_m", [0.0, 1.6])
def test_the_fit_recovers_a_perturbed_pose_from_three_rendered_silhouettes(body, pose, renderer, aside_m):
    """Also with the person 1.6 m aside, cut by every view's border (with the border taken for his outline and
    points beyond the image pulled in, the fit ended at 19 / 17 mm here)."""
    pose = pose.copy()
    pose[0] += aside_m
    fit = SilhouetteFit(body, RIG, FitSettings(iterations=15))
    views = silhouettes(renderer, body, pose, RIG)
    assert all(not wholly_in_view(view) for view in views) == (aside_m > 0)  # aside: every view cuts him
    fit.observe(views)
    start = perturbed(pose)
    refined, cost = fit.refine(start)
    assert cost == fit.fit_cost(refined)  # the cost it returns is its pose's
    before, after = joint_errors_mm(body, pose, start), joint_errors_mm(body, pose, refined)
    assert fit.fit_cost(refined) < 0.2 * fit.fit_cost(start)
    assert after["absolute"] < 0.3 * before["absolute"] and after["aligned"] < 0.6 * before["aligned"], (before, after)


def test_a_view_that_lost_the_person_adds_nothing_to_the_fit(body, pose, renderer):
    """One of three views empty (the person out of its image): the fit and its cost are those of the other two."""
    views = silhouettes(renderer, body, pose, RIG)
    three, two = (
        SilhouetteFit(body, RIG, FitSettings(iterations=3)),
        SilhouetteFit(body, RIG[:2], FitSettings(iterations=3)),
    )
    three.observe([*views[:2], np.zeros_like(views[2])])
    two.observe(views[:2])
    start = perturbed(pose)
    (refined, cost), (expected, expected_cost) = three.refine(start), two.refine(start)
    np.testing.assert_array_equal(refined, expected)  # the empty view's residuals add exact zeros
    assert cost == expected_cost and np.abs(refined - start).max() > 1e-3


def test_the_held_joints_keep_the_candidates_rotations(body, pose, renderer):
    """The hip bones (held by default) keep the rotation the candidate has, even one no clip gives them; with
    nothing held the same fit turns them."""
    hips = [slice(3 + 3 * JOINT_INDEX[name], 6 + 3 * JOINT_INDEX[name]) for name in ("LHipJoint", "RHipJoint")]
    start = perturbed(pose)
    for where in hips:
        start[where] += [0.05, -0.1, 0.08]
    views = silhouettes(renderer, body, pose, RIG)
    settings = {None: FitSettings(iterations=5), (): FitSettings(iterations=5, held_joints=())}
    fits = {held: SilhouetteFit(body, RIG, these) for held, these in settings.items()}
    refined = {}
    for held, fit in fits.items():
        if held is None:
            assert fit.settings.held_joints == ("LHipJoint", "RHipJoint")  # the default
        fit.observe(views)
        refined[held], _ = fit.refine(start)
    for where in hips:
        assert np.array_equal(refined[None][where], start[where])
        assert np.abs(refined[()][where] - start[where]).max() > 1e-3
    assert np.abs(refined[None] - start).max() > 1e-2  # the other joints did move


def test_a_held_joint_must_be_a_fitted_one():
    with pytest.raises(ValueError, match=r"^held_joints\[0\]='LeftToeBase' is not allowed: allowed Hips, .*RightFoot$"):
        FitSettings(held_joints=("LeftToeBase",))


def test_from_one_view_the_fit_recovers_what_the_view_sees(body, pose, renderer):
    """One view cannot tell depth: the joints' pixels are recovered, not their distance from the camera."""
    camera = RIG[0]
    fit = SilhouetteFit(body, [camera], FitSettings(iterations=15))
    fit.observe(silhouettes(renderer, body, pose, [camera]))
    start = perturbed(pose)
    refined, cost = fit.refine(start)
    assert cost == fit.fit_cost(refined)  # the cost it returns is its pose's

    def pixel_error(estimate):
        return np.linalg.norm(
            camera.project(body.joint_positions(estimate))[0] - camera.project(body.joint_positions(pose))[0], axis=1
        ).mean()

    assert fit.fit_cost(refined) < 0.2 * fit.fit_cost(start)
    assert pixel_error(refined) < 0.4 * pixel_error(start), (pixel_error(start), pixel_error(refined))


def some_pairs(body, pose, camera, count=40, seed=0):
    """Pairs of random faces' points with pixels a few pixels off their projections."""
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(body.faces), count, replace=False)
    barycentric = rng.dirichlet(np.ones(3), count)
    points = np.einsum("kc,kcd->kd", barycentric, body.posed_vertices(pose)[body.faces[faces]])
    return ViewPairs(faces, barycentric, camera.project(points)[0] + rng.normal(0, 3, (count, 2)))


def test_the_feature_terms_jacobian_is_the_derivative_of_its_residuals(body, pose, renderer):
    fit = SilhouetteFit(body, RIG)
    fit.observe(silhouettes(renderer, body, pose, RIG), [some_pairs(body, pose, camera) for camera in RIG])
    terms = fit.residuals(pose)
    features = [term for term in terms if term.robust_px == fit.settings.features.robust_px]
    assert len(terms) == 3 * 3 and len(features) == 3 and all(len(term.values) == 80 for term in features)
    step = 1e-6
    for column in (0, 2, 3, 10, 40, len(fit.columns) - 1):
        moved = pose.copy()
        moved[fit.columns[column]] += step
        after = fit.residuals(moved, jacobian=False)
        before = fit.residuals(pose - (moved - pose), jacobian=False)
        for index in range(2, len(terms), 3):  # each view's feature term
            numeric = (after[index].values - before[index].values) / (2 * step)
            np.testing.assert_allclose(terms[index].rows[:, column], numeric, rtol=1e-4, atol=1e-4)
    assert np.abs(np.concatenate([term.rows for term in features])).max() > 50


def test_candidates_costed_together_cost_what_each_does_alone(body, pose, renderer):
    """`fit_costs` poses, skins, projects and samples a frame's candidates in one batch: each candidate's terms and
    cost are the bits it has alone, and a pose asked twice in the batch is made once."""
    fit = SilhouetteFit(body, RIG)
    views, pairs = silhouettes(renderer, body, pose, RIG), [some_pairs(body, pose, camera) for camera in RIG]
    fit.observe(views, pairs)
    rng = np.random.default_rng(1)
    candidates = [pose + np.r_[rng.normal(0, 0.02, 3), rng.normal(0, 0.1 * k, len(pose) - 3)] for k in range(5)]
    costs = fit.fit_costs([*candidates, candidates[2]])
    together = [fit.residuals(candidate, jacobian=False) for candidate in candidates]  # kept from the batch
    assert len(fit._asked) == len(candidates)
    for candidate, cost, terms in zip(candidates, costs, together, strict=False):
        fit.observe(views, pairs)  # nothing kept
        assert cost == fit.fit_cost(candidate)
        alone = fit.residuals(candidate, jacobian=False)
        assert len(alone) == len(terms) == 9
        for a, b in zip(alone, terms, strict=True):
            np.testing.assert_array_equal(a.values, b.values)
    assert costs[-1] == costs[2] and len(set(costs[:-1])) == len(candidates)
    fit.POSES_KEPT = 3  # a full store: the oldest pose kept, asked with a new one that evicts it
    fit.observe(views, pairs)
    fit.fit_costs(candidates[:3])
    assert fit.fit_costs([candidates[0], candidates[3]]).tolist() == [costs[0], costs[3]]
    assert len(fit._asked) == 3


def test_feature_pairs_on_the_textured_skin_follow_a_turn_of_the_body(renderer):
    """Real renders of a textured body, real KLT, one camera: the body turns 14 degrees about the vertical between
    two frames, which changes its silhouette little. The pairs made at the first pose are right (at the second pose
    their points project near their features), and the fit from the first pose with them ends nearer the second
    than the fit by the silhouette alone."""
    from tracker.models.makehuman import build_body

    body, rig = build_body(texture_seed=0), RIG[:1]
    first = arm_grid(body, [20.0], [30.0], [20.0], [10.0], yaw_deg=-90.0)[0]
    second = first.copy()
    second[3:6] = (Rotation.from_rotvec([0.0, 0.0, 0.25]) * Rotation.from_rotvec(first[3:6])).as_rotvec()
    images = [renderer.render(rig, body.surface_meshes(pose))["front"] for pose in (first, second)]
    settings = FitSettings(iterations=15, features=FeaturePairSettings(weight=5.0))
    fit, pairing = SilhouetteFit(body, rig, settings), FeaturePairs(body, rig, settings.features)
    pairing.pairs([images[0].rgb])
    fit.observe([images[0].labels > 0])
    pairing.anchor(first, [view.inside_px for view in fit.fields])
    pairs = pairing.pairs([images[1].rgb])
    assert len(pairs[0]) > 30

    def pair_error_px(pose):
        points = np.einsum("kc,kcd->kd", pairs[0].barycentric, body.posed_vertices(pose)[body.faces[pairs[0].faces]])
        return np.median(np.linalg.norm(rig[0].project(points)[0] - pairs[0].pixels, axis=1))

    assert pair_error_px(second) < 0.5 * pair_error_px(first), (pair_error_px(second), pair_error_px(first))

    def errors(estimate):
        """The root's orientation error (degrees) and the largest joint error (mm)."""
        turn = Rotation.from_rotvec(estimate[3:6]).inv() * Rotation.from_rotvec(second[3:6])
        joints = np.abs(body.joint_positions(estimate) - body.joint_positions(second)).max()
        return np.degrees(turn.magnitude()), 1000 * joints

    fit.observe([images[1].labels > 0])
    alone, _ = fit.refine(first)
    fit.observe([images[1].labels > 0], pairs)
    paired, _ = fit.refine(first)
    assert np.all(np.array(errors(paired)) < 0.9 * np.array(errors(alone))), (
        errors(first),
        errors(alone),
        errors(paired),
    )


def test_three_views_fields_and_pairs_made_on_the_worker_threads_are_each_views_made_alone(renderer):
    """The fit's fields and the feature pairs of three views, shared with the worker threads, are those each view's
    own one-camera fit and pairing make, to the bit: the views' work is independent."""
    from tracker.models.makehuman import build_body

    body = build_body(texture_seed=0)
    first = arm_grid(body, [20.0], [30.0], [20.0], [10.0], yaw_deg=-90.0)[0]
    second = first.copy()
    second[3:6] = (Rotation.from_rotvec([0.0, 0.0, 0.2]) * Rotation.from_rotvec(first[3:6])).as_rotvec()
    images = [renderer.render(RIG, body.surface_meshes(pose)) for pose in (first, second)]
    settings = FitSettings(features=FeaturePairSettings(weight=1.0))
    alone = [(SilhouetteFit(body, [c], settings), FeaturePairs(body, [c], settings.features)) for c in RIG]
    together = SilhouetteFit(body, RIG, settings), FeaturePairs(body, RIG, settings.features)
    for frame in images:
        for (fit, pairing), views in [(together, RIG), *zip(alone, [[c] for c in RIG], strict=True)]:
            fit.observe([frame[c.name].labels > 0 for c in views], pairing.pairs([frame[c.name].rgb for c in views]))
            pairing.anchor(first, [view.inside_px for view in fit.fields])
    for view, (fit, pairing) in enumerate(alone):
        mine, theirs = together[0].fields[view], fit.fields[0]
        assert mine.sampled.tobytes() == theirs.sampled.tobytes() and mine.edge.tobytes() == theirs.edge.tobytes()
        assert mine.edge_normals.tobytes() == theirs.edge_normals.tobytes()
        for part in ("faces", "barycentric", "pixels"):
            assert getattr(together[0].pairs[view], part).tobytes() == getattr(fit.pairs[0], part).tobytes()
        assert together[1].anchors[view].ids.tobytes() == pairing.anchors[0].ids.tobytes()
    assert all(len(fit.pairs[0]) > 10 for fit, _ in alone)  # the views pair features: not a vacuous test


def test_the_mean_huber_is_the_mean_of_the_robust_squares():
    values = np.random.default_rng(2).normal(0, 10, 500)
    size = np.abs(values)
    expected = np.where(size <= 8.0, size**2, 2 * 8.0 * size - 8.0**2).mean()
    assert mean_huber(values, 8.0) == pytest.approx(expected, rel=1e-12)
    assert mean_huber(values[:0], 8.0) == 0.0
