import math

import numpy as np
import pytest
import trimesh

from tracker.models.dsq import (
    PARAM_NAMES,
    PARAM_RANGES,
    DSQShape,
    dsq_points,
    dsq_points_jacobian,
    mesh_topology,
    pole_point,
    sample_grid,
    superquadric_points,
)
from tracker.render.mesh import vertex_normals


def random_coords(n=500, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi / 2, np.pi / 2, n), rng.uniform(-np.pi, np.pi, n)


def naive_dsq_point(q, eta, omega):
    """Eq 1-2 written out for one point with math's scalar functions: an independent derivation."""
    a, a1, a2, a3, e1, e2, t1, t2, b1, b2, b3 = q[:11]

    def spow(value, eps):
        return math.copysign(abs(value) ** eps, value) if value != 0 else 0.0

    e = (
        a * a1 * spow(math.cos(eta), e1) * spow(math.cos(omega), e2),
        a * a2 * spow(math.cos(eta), e1) * spow(math.sin(omega), e2),
        a * a3 * spow(math.sin(eta), e1),
    )
    s1 = (t1 * e[2] / (a * a3) + 1) * e[0] + b1 * math.cos((e[2] + b2) / (a * a3) * math.pi * b3)
    s2 = (t2 * e[2] / (a * a3) + 1) * e[1]
    return np.array([s1, s2, e[2]])


def test_parameter_vector_has_the_17_parameters_of_eq4():
    assert PARAM_NAMES == (
        "a",
        "a1",
        "a2",
        "a3",
        "eps1",
        "eps2",
        "t1",
        "t2",
        "b1",
        "b2",
        "b3",
        "c1",
        "c2",
        "c3",
        "r1",
        "r2",
        "r3",
    )
    assert set(PARAM_RANGES) == set(PARAM_NAMES)
    assert len(DSQShape().to_params()) == 17


def test_ellipsoid_satisfies_its_implicit_equation():
    q = DSQShape(a=0.5, a1=0.6, a2=0.3, a3=1.0).to_params()
    points = dsq_points(q, *random_coords())
    x, y, z = points.T
    np.testing.assert_allclose((x / 0.3) ** 2 + (y / 0.15) ** 2 + (z / 0.5) ** 2, 1.0, atol=1e-12)


@pytest.mark.parametrize("eps1, eps2", [(0.3, 0.5), (1.0, 2.0), (2.5, 0.8)])
def test_superquadric_satisfies_its_inside_outside_function(eps1, eps2):
    q = DSQShape(a=1.0, a1=0.5, a2=0.8, a3=0.7, eps1=eps1, eps2=eps2).to_params()
    x, y, z = superquadric_points(q, *random_coords()).T
    f = (np.abs(x / 0.5) ** (2 / eps2) + np.abs(y / 0.8) ** (2 / eps2)) ** (eps2 / eps1) + np.abs(z / 0.7) ** (2 / eps1)
    np.testing.assert_allclose(f, 1.0, atol=1e-9)


def test_deformed_points_equal_the_naive_formula():
    q = DSQShape(
        a=0.3, a1=0.4, a2=0.5, a3=0.9, eps1=0.7, eps2=1.3, t1=0.4, t2=-0.6, b1=0.05, b2=0.2, b3=0.7
    ).to_params()
    eta, omega = random_coords(200, seed=3)
    expected = np.array([naive_dsq_point(q, h, w) for h, w in zip(eta, omega, strict=True)])
    np.testing.assert_allclose(dsq_points(q, eta, omega), expected, atol=1e-12)


def test_tapering_scales_x_and_y_linearly_along_z():
    base = DSQShape(a=0.4, a1=0.5, a2=0.5, a3=1.0)
    tapered = DSQShape(a=0.4, a1=0.5, a2=0.5, a3=1.0, t1=-0.5, t2=0.25)
    eta, omega = random_coords()
    p0 = dsq_points(base.to_params(), eta, omega)
    p1 = dsq_points(tapered.to_params(), eta, omega)
    relative_z = p0[:, 2] / 0.4
    np.testing.assert_allclose(p1[:, 0], p0[:, 0] * (1 - 0.5 * relative_z), atol=1e-12)
    np.testing.assert_allclose(p1[:, 1], p0[:, 1] * (1 + 0.25 * relative_z), atol=1e-12)
    np.testing.assert_allclose(p1[:, 2], p0[:, 2])


def test_full_bending_shifts_the_middle_by_b1_and_the_ends_by_minus_b1():
    # b2 = 0, b3 = 1: offset b1 cos(pi z / (a a3)) is +b1 at z = 0 and -b1 at the poles.
    q = DSQShape(a=0.4, a1=0.3, a2=0.3, b1=0.07, b3=1.0).to_params()
    equator = dsq_points(q, np.zeros(64), np.linspace(-np.pi, np.pi, 64, endpoint=False))
    assert equator[:, 0].mean() == pytest.approx(0.07, abs=1e-12)
    np.testing.assert_allclose(pole_point(q, top=True), [-0.07, 0.0, 0.4], atol=1e-12)
    np.testing.assert_allclose(pole_point(q, top=False), [-0.07, 0.0, -0.4], atol=1e-12)


def test_a_pole_asked_again_is_a_fresh_point_of_the_same_bits_whatever_the_pose():
    q = DSQShape(a=0.4, a1=0.3, a2=0.3, t1=0.2, b1=0.07, b2=0.01, b3=0.8).to_params()
    first = pole_point(q, top=True)
    first[0] = 9.0  # the caller's own array: the next call does not see it
    posed = q.copy()
    posed[11:] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]  # c and r: the pole is in the part's own frame
    again = pole_point(posed, top=True)
    np.testing.assert_array_equal(again, dsq_points(q, np.array([np.pi / 2]), np.zeros(1))[0])
    assert not np.array_equal(pole_point(q, top=False), again)


@pytest.mark.parametrize("eps", [0.0, 1e-9, 1e-3])
def test_no_nan_near_box_limit_and_at_the_poles(eps):
    q = DSQShape(a=1.0, a1=0.5, a2=0.4, a3=0.8, eps1=eps, eps2=eps, t1=0.3, b1=0.1, b3=0.5).to_params()
    topology = mesh_topology(9, 12)
    points = dsq_points(q, topology.eta, topology.omega)
    assert np.isfinite(points).all()
    assert np.isfinite(vertex_normals(points, topology.faces, topology.weld)).all()
    if eps == 0.0:  # a box: every undeformed point has a coordinate on a face
        x, y, z = superquadric_points(q, *random_coords()).T
        box = np.max(np.abs(np.stack([x / 0.5, y / 0.4, z / 0.8])), axis=0)
        np.testing.assert_allclose(box, 1.0)
    # Poles are single points whatever eps is.
    np.testing.assert_allclose(points[topology.eta == np.pi / 2], points[topology.eta == np.pi / 2][:1].repeat(13, 0))


def test_sample_ids_are_stable_and_name_fixed_surface_coordinates():
    grid = sample_grid(4, 6)
    np.testing.assert_array_equal(grid.ids, np.arange(24))
    # id = row * n_omega + column, rows bottom to top at midpoints, columns from -pi.
    assert grid.eta[13] == pytest.approx(-np.pi / 2 + 2.5 * np.pi / 4)
    assert grid.omega[13] == pytest.approx(-np.pi + 1 * 2 * np.pi / 6)
    assert sample_grid(4, 6) is grid  # cached, read-only
    with pytest.raises(ValueError):
        grid.eta[0] = 0.0
    # The same id is the same material point as the shape changes: it moves continuously with b1.
    q0 = DSQShape(a=0.3).to_params()
    q1 = q0.copy()
    q1[PARAM_NAMES.index("b1")] = 1e-4
    shift = np.linalg.norm(dsq_points(q1, grid.eta, grid.omega) - dsq_points(q0, grid.eta, grid.omega), axis=1)
    assert shift.max() <= 1e-4 + 1e-12


@pytest.mark.parametrize(
    "shape",
    [
        DSQShape(a=0.3, a1=0.5, a2=0.7),
        DSQShape(a=0.3, a1=0.4, a2=0.3, eps1=0.3, eps2=1.7, t1=-0.4, t2=0.2, b1=0.05, b3=0.5),
    ],
)
def test_render_mesh_is_watertight_and_outward_once_welded(shape):
    topology = mesh_topology(24, 32)
    vertices = dsq_points(shape.to_params(), topology.eta, topology.omega)
    mesh = trimesh.Trimesh(vertices, topology.weld[topology.faces], process=False)  # our weld, not trimesh's
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert not trimesh.Trimesh(vertices, topology.faces, process=False).is_watertight  # the seam is open unwelded
    assert mesh.volume > 0  # outward normals
    # Welding only merged genuinely coincident vertices (poles, seam).
    np.testing.assert_allclose(vertices[topology.weld], vertices, atol=1e-15)


def test_ellipsoid_mesh_volume_converges_to_the_analytic_volume():
    topology = mesh_topology(64, 96)
    vertices = dsq_points(DSQShape(a=0.5, a1=0.6, a2=0.4).to_params(), topology.eta, topology.omega)
    volume = trimesh.Trimesh(vertices, topology.weld[topology.faces], process=False).volume
    assert volume == pytest.approx(4 / 3 * np.pi * 0.5 * 0.3 * 0.2, rel=2e-3)


def test_vertex_normals_of_a_sphere_point_outwards():
    topology = mesh_topology(20, 24)
    vertices = dsq_points(DSQShape(a=1.0).to_params(), topology.eta, topology.omega)
    normals = vertex_normals(vertices, topology.faces, topology.weld)
    np.testing.assert_allclose(np.einsum("ij,ij->i", normals, vertices), 1.0, atol=1e-2)


@pytest.mark.parametrize(
    "shape",
    [
        DSQShape(a=0.3, a1=0.4, a2=0.5, a3=0.9, eps1=0.7, eps2=1.3, t1=0.4, t2=-0.6, b1=0.05, b2=0.2, b3=0.7),
        DSQShape(a=0.22, a1=0.3, a2=0.3, eps1=0.5, t1=-0.2, t2=-0.2, b1=-0.03, b3=0.5),
        DSQShape(a=0.1, a1=0.9, a2=0.2, a3=0.6, eps1=1.8, eps2=0.4, b1=0.01, b2=-0.5, b3=1.0),
    ],
)
def test_shape_jacobian_matches_central_differences(shape):
    q = shape.to_params()
    grid = sample_grid(12, 16)  # includes omega = -pi, -pi/2, 0, pi/2, where a sine or cosine is 0
    eta = np.concatenate([grid.eta, [-np.pi / 2, np.pi / 2]])  # and the poles
    omega = np.concatenate([grid.omega, [0.3, -2.0]])
    analytic = dsq_points_jacobian(q, eta, omega)
    assert analytic.shape == (len(eta), 3, 11) and np.isfinite(analytic).all()
    for k, name in enumerate(PARAM_NAMES[:11]):
        step = 1e-6 * max(1.0, abs(q[k]))
        plus, minus = q.copy(), q.copy()
        plus[k] += step
        minus[k] -= step
        numeric = (dsq_points(plus, eta, omega) - dsq_points(minus, eta, omega)) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, k], numeric, atol=1e-7, err_msg=name)
