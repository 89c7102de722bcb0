"""Point-to-surface distances against independent answers: a brute-force search over each triangle, a square, and
a fine sphere."""

import numpy as np
import pytest
import trimesh

from tracker.geometry.surface_distance import point_mesh_distance, point_triangle_distance


def brute_force(point, a, b, c, steps=400):
    """The nearest of a fine barycentric grid over the triangle (a little above the true distance)."""
    u, v = np.meshgrid(np.linspace(0, 1, steps), np.linspace(0, 1, steps))
    inside = u + v <= 1
    grid = a + u[inside, None] * (b - a) + v[inside, None] * (c - a)
    return np.linalg.norm(grid - point, axis=1).min()


def test_every_region_of_a_triangle_gives_the_distance_a_brute_force_search_finds():
    rng = np.random.default_rng(1)
    a, b, c = rng.normal(size=(3, 200, 3))
    points = rng.normal(scale=2.0, size=(200, 3))
    fast = point_triangle_distance(points, a, b, c)
    slow = np.array([brute_force(p, *t) for p, t in zip(points, zip(a, b, c, strict=True), strict=True)])
    assert np.all(fast <= slow + 1e-12)  # never above a point of the triangle
    np.testing.assert_allclose(fast, slow, atol=0.02)  # and as close as the grid can tell


def test_a_square_gives_its_height_above_and_the_euclidean_distance_beside():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    points = np.array([[0.3, 0.6, 0.25], [1.5, 0.5, 0.0], [2.0, 2.0, 1.0], [0.5, 0.5, 0.0]])
    np.testing.assert_allclose(point_mesh_distance(points, vertices, faces), [0.25, 0.5, np.sqrt(3.0), 0.0], atol=1e-12)


def test_a_mesh_with_a_vertex_not_a_number_is_measured_on_its_other_triangles_every_time():
    vertices = np.array([[0.0, 0, 0], [np.nan, 0, 0], [1, 1, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    for _ in range(2):  # the second time, the trees kept are tried first: no rotation fits it
        np.testing.assert_array_equal(point_mesh_distance(np.array([[0.3, 0.6, 0.25]]), vertices, faces), [0.25])


def test_points_around_a_fine_sphere_are_their_height_above_it_and_the_shortcut_is_exact():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    rng = np.random.default_rng(2)
    directions = rng.normal(size=(300, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    heights = rng.uniform(-0.5, 1.0, 300)
    points = directions * (1.0 + heights)[:, None]
    distance = point_mesh_distance(points, sphere.vertices, sphere.faces)
    np.testing.assert_allclose(distance, np.abs(heights), atol=3e-3)  # the facets sit inside the sphere by < 3 mm
    every = np.array(
        [
            point_triangle_distance(
                np.repeat(p[None], len(sphere.faces), 0), *(sphere.vertices[sphere.faces[:, j]] for j in range(3))
            ).min()
            for p in points[:40]
        ]
    )
    np.testing.assert_array_equal(distance[:40], every)


@pytest.mark.parametrize("shift", [0.0, 0.004])
def test_a_surface_of_revolution_turned_about_its_axis_is_at_distance_zero_but_shifted_is_not(shift):
    cylinder = trimesh.creation.cylinder(radius=0.05, height=0.3, sections=64)
    angle = 2 * np.pi / 64  # one section: the mesh maps onto itself
    turn = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    moved = cylinder.vertices @ turn.T + [shift, 0, 0]
    distance = point_mesh_distance(moved, cylinder.vertices, cylinder.faces)
    assert distance.max() == pytest.approx(shift, abs=1e-9)


def test_the_arms_forearm_turned_about_its_own_axis_slides_along_its_surface_but_stays_on_it():
    """The forearm is a surface of revolution (a1 = a2, eps2 = 1, equal tapering, no bending in x or y): turned about
    its own axis, its samples move (surface_error_mm) but stay on the true surface (surface_distance_mm)."""
    from experiments.components import build, compose
    from tracker.evaluation.arm import ArmEvaluation
    from tracker.geometry.rotations import euler_to_matrix, matrix_to_euler, rotation_z
    from tracker.models.dsq import PARAM_INDEX
    from tracker.presentation import PAPER_PART

    components = build(compose(["frames=2"]))
    arm, truth = components.model, components.scene.params(components.model, 0)
    truth[PAPER_PART, PARAM_INDEX["b1"]] = 0.0  # unbent
    r = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)
    turned = truth.copy()
    turned[PAPER_PART, r] = matrix_to_euler(euler_to_matrix(truth[PAPER_PART, r]) @ rotation_z(0.5))
    part, _ = ArmEvaluation().columns(arm, truth, arm.connect(turned))
    assert part["surface_error_mm"][PAPER_PART] > 20.0  # samples slid by centimetres ...
    assert part["surface_distance_mm"][PAPER_PART] < 0.5  # ... along the surface (facets' chords: < 0.5 mm)
    same, _ = ArmEvaluation().columns(arm, truth, truth.copy())
    assert np.all(same["surface_distance_mm"] < 0.5) and np.all(same["surface_error_mm"] == 0.0)


def test_on_the_arms_meshes_every_point_gets_the_nearest_of_every_triangle_to_the_bit():
    """The DSQ parts' meshes hold slivers and fans beside small facets (radii over a factor of ten): points near,
    on and far from each surface get exactly what trying every triangle gives."""
    from experiments.components import build, compose

    components = build(compose(["frames=2"]))
    arm = components.model
    rng = np.random.default_rng(3)
    for part, mesh in enumerate(arm.surface_meshes(components.scene.params(arm, 0))):
        samples = arm.sample_points(components.scene.params(arm, 5))[part]
        points = samples + rng.normal(scale=rng.choice([1e-4, 3e-3, 5e-2], size=(len(samples), 1)), size=samples.shape)
        corners = [mesh.vertices[mesh.faces[:, j]] for j in range(3)]
        every = np.array(
            [point_triangle_distance(np.repeat(p[None], len(mesh.faces), 0), *corners).min() for p in points]
        )
        np.testing.assert_array_equal(point_mesh_distance(points, mesh.vertices, mesh.faces), every)


def _every_triangle(points, vertices, faces):
    corners = [vertices[faces[:, j]] for j in range(3)]
    return np.array([point_triangle_distance(np.repeat(p[None], len(faces), 0), *corners).min() for p in points])


def test_across_a_dsq_meshs_seam_points_get_every_triangles_answer():
    """The omega seam repeats its vertices (the topology's weld says which): points on and beside its edges tie
    between the triangles on either side, which share no vertex index, and get what trying every triangle gives."""
    from experiments.components import build, compose

    components = build(compose(["frames=2"]))
    arm, topology = components.model, components.model.topology
    rng = np.random.default_rng(0)
    seam = np.flatnonzero(np.isclose(topology.omega, -np.pi))
    seam = seam[np.argsort(topology.eta[seam])]
    for vertices in arm.surface_vertices(components.scene.params(arm, 0)):
        along, edge = rng.uniform(0, 1, (300, 1)), rng.integers(0, len(seam) - 1, 300)
        on = vertices[seam[edge]] * (1 - along) + vertices[seam[edge + 1]] * along
        points = on + (on - vertices.mean(axis=0)) * rng.choice([0.0, 1e-6, 1e-3, 0.03], (300, 1))
        np.testing.assert_array_equal(
            point_mesh_distance(points, vertices, topology.faces),
            _every_triangle(points, vertices, topology.faces),
        )


def test_a_tree_shape_made_from_one_mesh_searches_another_of_its_faces_exactly():
    """The tree's shape is kept per set of faces, made from the first mesh asked about: a mesh of the same faces moved
    far and bent, and a sphere whose faces are not the arm's, get what trying every triangle gives; points not finite
    find no triangle; the shapes kept stay within their bound."""
    from experiments.components import build, compose
    from tracker.geometry import triangle_tree
    from tracker.geometry.rotations import rotation_vectors_to_matrices

    components = build(compose(["frames=2"]))
    arm, topology = components.model, components.model.topology
    params = components.scene.params(arm, 0)
    faces = np.ascontiguousarray(topology.faces, dtype=np.int64)
    turn = rotation_vectors_to_matrices(np.array([[0.3, -1.2, 2.0]]))[0]
    bent = params.copy()
    bent[1, 8] += 0.3  # b1: the part bends
    first, moved = arm.surface_vertices(params)[1], arm.surface_vertices(bent)[1] @ turn.T + [0.2, -0.1, 0.5]
    rng = np.random.default_rng(4)
    for mesh in (first, moved):
        near = mesh[::5]
        points = near + rng.normal(scale=rng.choice([1e-4, 3e-3, 5e-2], size=(len(near), 1)), size=near.shape)
        np.testing.assert_array_equal(point_mesh_distance(points, mesh, faces), _every_triangle(points, mesh, faces))
        nearest, distance = triangle_tree.nearest_triangles(points, mesh, faces)
        corners = [mesh[faces[nearest, j]] for j in range(3)]
        np.testing.assert_array_equal(distance, point_triangle_distance(points, *corners))
    assert faces.tobytes() in triangle_tree._SHAPES
    nearest, distance = triangle_tree.nearest_triangles(np.array([[np.nan, 0, 0], [0, np.inf, 0]]), first, faces)
    assert np.all(nearest == -1) and np.isnan(distance).all()
    for subdivisions in range(triangle_tree.SHAPES_KEPT + 1):
        sphere = trimesh.creation.icosphere(subdivisions=subdivisions % 4, radius=1.0 + subdivisions)
        sphere_faces = np.roll(sphere.faces, subdivisions // 4, axis=1)  # other faces' bytes, the same triangles
        points = rng.normal(size=(50, 3)) * (1.0 + subdivisions)
        np.testing.assert_array_equal(
            point_mesh_distance(points, sphere.vertices, sphere_faces),
            _every_triangle(points, sphere.vertices, sphere_faces),
        )
    assert len(triangle_tree._SHAPES) == triangle_tree.SHAPES_KEPT
