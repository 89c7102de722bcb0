import numpy as np
import pytest

from tracker.geometry.rotations import matrix_to_rotation_vector, rotation_z
from tracker.models.body_skeleton import JOINT_INDEX, PART_NAMES, POSE_SIZE, T_POSE_DIRECTIONS
from tracker.models.makehuman import BodyDataError, build_body
from tracker.models.skinning_jacobian import vertex_jacobian


def test_the_mesh_is_decimated_to_the_papers_polygon_count_with_valid_weights(body):
    assert abs(len(body.faces) - 4500) <= 50
    assert body.weights.min() >= 0 and np.allclose(body.weights.sum(axis=1), 1.0)
    assert body.faces.max() < len(body.rest_vertices)
    assert set(np.unique(body.face_parts)) == set(range(len(PART_NAMES)))  # every part has faces


def test_body_frame_metres_z_up_feet_on_the_floor_facing_minus_y(body):
    low, high = body.rest_vertices.min(axis=0), body.rest_vertices.max(axis=0)
    assert low[2] == pytest.approx(0.0) and 1.5 < high[2] < 1.9  # a standing adult, in metres
    head, left_hand = body.rest_heads[JOINT_INDEX["Head"]], body.rest_heads[JOINT_INDEX["LeftHand"]]
    assert head[2] > 1.4 and left_hand[0] > 0.3  # left is +x
    nose_side = body.rest_vertices[body.rest_vertices[:, 2] > head[2]]
    assert nose_side[:, 1].min() < head[1] - 0.08  # the face sticks out towards -y


def test_the_rest_pose_reproduces_the_mesh(body):
    np.testing.assert_allclose(body.posed_vertices(body.mesh_rest_pose()), body.rest_vertices, atol=1e-12)


def test_a_90_degree_elbow_bend_turns_the_forearm_about_the_elbow(body):
    pose = body.mesh_rest_pose()
    elbow, shoulder = JOINT_INDEX["RightForeArm"], JOINT_INDEX["RightArm"]
    bend = rotation_z(np.pi / 2)  # about the vertical through the elbow, in the world
    # Joint rotations are relative to the parent's (here the upper arm's) world rotation from the T-pose, which
    # at the mesh's rest undoes the upper arm's T-pose alignment A: the world bend reads A bend A^T locally.
    align = body.t_pose_alignment[shoulder]
    local = slice(3 + 3 * elbow, 6 + 3 * elbow)
    pose[local] = matrix_to_rotation_vector(align @ bend @ align.T @ _rotation(pose[local]))
    forearm_only = body.weights[:, elbow] > 0.999
    assert forearm_only.sum() >= 5
    centre = body.rest_heads[elbow]
    expected = (body.rest_vertices[forearm_only] - centre) @ bend.T + centre  # by hand: a rigid turn
    np.testing.assert_allclose(body.posed_vertices(pose)[forearm_only], expected, atol=1e-12)
    untouched = body.weights[:, JOINT_INDEX["Spine1"]] > 0.999
    np.testing.assert_allclose(body.posed_vertices(pose)[untouched], body.rest_vertices[untouched], atol=1e-12)


def test_the_t_pose_points_the_limbs_as_the_cmu_t_pose(body):
    heads = body.t_pose_heads
    for bone, child in (("RightArm", "RightForeArm"), ("LeftForeArm", "LeftHand"), ("LeftUpLeg", "LeftLeg")):
        direction = heads[JOINT_INDEX[child]] - heads[JOINT_INDEX[bone]]
        target = np.asarray(T_POSE_DIRECTIONS[bone]) / np.linalg.norm(T_POSE_DIRECTIONS[bone])
        cosine = np.clip(direction @ target / np.linalg.norm(direction), -1.0, 1.0)
        assert np.degrees(np.arccos(cosine)) < 0.5


def test_joints_stay_at_their_rest_distance_from_the_parent_in_any_pose(body):
    pose = body.rest_pose() + np.r_[np.zeros(3), np.random.default_rng(0).normal(0, 0.5, POSE_SIZE - 3)]
    posed, rest = body.joint_positions(pose), body.rest_heads
    child = np.arange(1, len(rest))
    parent = body.parents[child]
    np.testing.assert_allclose(
        np.linalg.norm(posed[child] - posed[parent], axis=1),
        np.linalg.norm(rest[child] - rest[parent], axis=1),
        atol=1e-12,
    )


def test_missing_data_files_give_a_clear_error(tmp_path):
    with pytest.raises(BodyDataError, match=r"missing body data file .*base\.obj: run `make setup`"):
        build_body(tmp_path)


def _rotation(vector):
    from tracker.geometry.rotations import rotation_vector_to_matrix

    return rotation_vector_to_matrix(vector)


def test_the_body_is_a_closed_surface_and_says_so(body):
    import trimesh

    surface = trimesh.Trimesh(body.rest_vertices, body.faces, process=False)
    assert surface.is_watertight and surface.is_winding_consistent and body.closed  # label rendering relies on it
    assert len(body.rest_vertices) - len(surface.edges_unique) + len(body.faces) == 2  # a sphere, topologically


def test_the_skinned_vertices_analytic_jacobian_matches_central_differences(body):
    """d v'/d pose (the root's position and every joint's rotation vector) of 300 vertices at a random pose,
    against central differences of the skinning itself (step 1e-6: error ~1e-10)."""
    from tracker.motion.posture import arms_pose

    rng = np.random.default_rng(0)
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-60.0)
    pose[3:] += rng.normal(0.0, 0.2, POSE_SIZE - 3)  # every joint turned, some by large angles
    subset = rng.choice(len(body.rest_vertices), 300, replace=False)
    analytic = vertex_jacobian(body, pose, subset)
    step, numeric = 1e-6, np.zeros_like(analytic)
    for k in range(POSE_SIZE):
        delta = np.zeros(POSE_SIZE)
        delta[k] = step
        numeric[:, :, k] = (body.posed_vertices(pose + delta, subset) - body.posed_vertices(pose - delta, subset)) / (
            2 * step
        )
    np.testing.assert_allclose(analytic, numeric, atol=1e-8)
    assert np.abs(numeric[:, :, 3:]).max() > 0.5  # the joints move the vertices: not a vacuous comparison
    # A caller that has the pose's bone transforms (a fit needs both the vertices and their Jacobian) gets the
    # same bits from them as from the pose alone.
    transforms = body.bone_transforms(pose)
    assert np.array_equal(vertex_jacobian(body, pose, subset, transforms=transforms), analytic)
    assert np.array_equal(body.posed_vertices(pose, subset, transforms), body.posed_vertices(pose, subset))
    # Some joints only: the root position's columns, then those joints' in the order asked.
    some = vertex_jacobian(body, pose, subset, joints=[5, 2])
    np.testing.assert_allclose(some, analytic[:, :, [0, 1, 2, 18, 19, 20, 9, 10, 11]], rtol=1e-12, atol=1e-15)


def test_the_label_meshes_are_the_surface_meshes_bare(body):
    """What the z-buffer draws from the posed vertices: each part's vertices, faces and label as the lit meshes
    have them."""
    pose = body.rest_pose()
    pose[3:] += np.random.default_rng(4).normal(0.0, 0.3, POSE_SIZE - 3)
    bare, lit = body.label_meshes(body.posed_vertices(pose)), body.surface_meshes(pose)
    assert [m.label for m in bare] == [m.label for m in lit] and all(m.normals is None for m in bare)
    for a, b in zip(bare, lit, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def test_some_vertices_skinned_alone_are_those_of_the_whole_body_whichever_subset_came_before(body):
    """`posed_vertices` keeps the weights of the subsets it was asked for (a fit asks for the same at every step):
    each subset, asked in turn and again, in any integer type, gets the whole body's vertices' bits."""
    rng = np.random.default_rng(1)
    pose = body.mesh_rest_pose()
    pose[3:] += rng.normal(0.0, 0.3, POSE_SIZE - 3)
    whole = body.posed_vertices(pose)
    subsets = [rng.choice(len(whole), size, replace=False) for size in (40, 300, 40)]
    for subset in [*subsets, subsets[0].astype(np.int32), *subsets]:
        assert np.array_equal(body.posed_vertices(pose, subset), whole[subset])


def test_a_textured_body_gives_corners_to_track_and_the_plain_one_renders_as_before(body, renderer):
    """``texture_seed`` draws block noise over each part (u about its long axis, v along it): Shi-Tomasi finds
    several times more corners inside the body than on the plain skin, whose meshes carry no texture at all."""
    import cv2

    from tracker.geometry.rigs import View, cameras
    from tracker.models.makehuman import build_body
    from tracker.motion.posture import arms_pose

    rig = cameras(views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9))))
    textured = build_body(texture_seed=3)
    assert textured.source_key == body.source_key  # the same surface: cached label renders stay valid
    assert all(mesh.texture is None and mesh.uv is None for mesh in body.surface_meshes(body.rest_pose()))
    pose = arms_pose(body, (30.0, 20.0, 40.0), (-10.0, 8.0, 20.0), yaw_deg=-60.0)
    for uv, texture in textured.part_textures:
        assert uv.min() >= 0.0 and uv.max() <= 1.0 and texture.dtype == np.uint8
    counts = {}
    for model in (body, textured):
        for name, view in renderer.render(rig, model.surface_meshes(pose)).items():
            inside = cv2.erode((view.labels > 0).astype(np.uint8), np.ones((5, 5), np.uint8))
            corners = cv2.goodFeaturesToTrack(cv2.cvtColor(view.rgb, cv2.COLOR_RGB2GRAY), 500, 0.01, 3, mask=inside)
            counts[model is textured, name] = 0 if corners is None else len(corners)
    for name in ("front", "side"):  # measured: 104 and 92 against 21 and 35
        assert counts[True, name] >= 2.5 * counts[False, name] and counts[True, name] >= 60, counts
