"""The selection ablation (`tracker.selection=none`): the back-face test alone, against geometry with known answers,
and a short AbIS run that never discards for occlusion."""

import numpy as np
import pandas as pd

from tests.conftest import run_cli
from tracker.abis.visibility import facing_samples, outward_normals
from tracker.geometry.cameras import look_at


def sphere(eta, omega, radius=0.5, centre=(1.0, 2.0, 3.0)):
    return np.asarray(centre) + radius * np.column_stack(
        [np.cos(eta) * np.cos(omega), np.cos(eta) * np.sin(omega), np.sin(eta)]
    )


def test_a_spheres_outward_normals_point_away_from_its_centre():
    rng = np.random.default_rng(0)
    eta, omega = rng.uniform(-1.4, 1.4, 200), rng.uniform(-np.pi, np.pi, 200)
    normals = outward_normals(sphere, eta, omega, np.array([1.0, 2.0, 3.0]))
    expected = (sphere(eta, omega) - [1.0, 2.0, 3.0]) / 0.5
    np.testing.assert_allclose(normals, expected, atol=1e-6)


def test_the_back_face_test_keeps_the_half_of_a_sphere_that_faces_the_camera_and_ignores_what_is_in_front():
    camera = look_at(
        "main",
        np.array([1.0, 2.0 - 4.0, 3.0]),
        np.array([1.0, 2.0, 3.0]),
        np.array([0.0, 0.0, 1.0]),
        width=320,
        height=240,
        focal_px=400.0,
    )
    rng = np.random.default_rng(1)
    eta, omega = rng.uniform(-1.4, 1.4, 500), rng.uniform(-np.pi, np.pi, 500)
    points = sphere(eta, omega)
    normals = outward_normals(sphere, eta, omega, np.array([1.0, 2.0, 3.0]))
    blocker = sphere(eta, omega, radius=0.3, centre=(1.0, 1.0, 3.0))  # a second part between, hiding the first
    seen = facing_samples(
        camera,
        [points, blocker],
        [
            normals,
            outward_normals(lambda e, w: sphere(e, w, 0.3, (1.0, 1.0, 3.0)), eta, omega, np.array([1.0, 1.0, 3.0])),
        ],
    )
    first = seen.sample[seen.part == 0]
    to_camera = camera.position - points[first]
    assert np.all(np.einsum("ij,ij->i", normals[first], to_camera) > 0)
    assert 0.35 < len(first) / len(points) < 0.6  # about the near half (less than half: the cap's rim is seen edge-on)


def test_without_selection_nothing_is_discarded_for_occlusion(tmp_path):
    result = run_cli(
        tmp_path / "out", "tracker=abis", "frames=8", "tracker.selection=none", "record.images=false", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    table = pd.read_parquet(tmp_path / "out" / "frames.parquet")
    assert (table["discarded_occlusion"] == 0).all() and table["new"].sum() > 0
