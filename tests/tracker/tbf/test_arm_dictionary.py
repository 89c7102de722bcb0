"""The DSQ arm's pose dictionary for tree-based filtering: pose vectors against the arm scene's own parameters,
its surface against the arm's render meshes, its motion space."""

import numpy as np
import pytest

from tracker.tbf.arm_dictionary import ArmAxis, ArmDictionary, ArmGridSpec, axis_values
from tracker.tbf.motion import OccludedWiderWalk


@pytest.fixture(scope="module")
def dictionary(arm):
    return ArmDictionary(arm)


def test_a_pose_vector_gives_the_arm_scenes_own_parameters(dictionary, arm, motion):
    """The arm swing moves exactly the default grid's axes: its parameters, read into a pose vector and back, are
    what the scene computed (the shoulder and the connected joints included)."""
    for frame in (0, 7, 19, 33):
        truth = motion.params(arm, frame)
        np.testing.assert_allclose(dictionary.params(dictionary.pose_of(truth)), truth, atol=1e-12)


def test_the_grid_holds_every_combination_of_its_axes(dictionary):
    poses = dictionary.poses()
    sizes = [len(axis_values(axis)) for axis in dictionary.spec.axes]
    assert len(poses) == np.prod(sizes) == 4725
    assert len(np.unique(poses, axis=0)) == len(poses)
    forearm_r2 = poses[:, 2]
    np.testing.assert_allclose(np.unique(forearm_r2), np.radians(np.arange(0.0, 81.0, 4.0)))


def test_the_dictionarys_surface_is_the_arms_render_mesh(dictionary, arm):
    pose = dictionary.poses()[1234]
    meshes = arm.surface_meshes(dictionary.params(pose))
    np.testing.assert_allclose(dictionary.posed_vertices(pose[None])[0], np.concatenate([m.vertices for m in meshes]))
    faces = np.concatenate([mesh.faces + k * len(mesh.vertices) for k, mesh in enumerate(meshes)])
    np.testing.assert_array_equal(dictionary.faces, faces)
    assert np.bincount(dictionary.face_parts).tolist() == [len(mesh.faces) for mesh in meshes]


def test_dm2_widens_the_occluded_parts_axes_and_lengths_take_the_root_sigma(dictionary):
    space = dictionary.space
    assert space.size == 5 and space.lengths == (3,)  # forearm b1 is a length
    assert space.part_components == ((0, 1), (2, 3), (4,))
    walk = OccludedWiderWalk(sigma=0.1, sigma_root_m=0.02, m=5.0)
    np.testing.assert_allclose(walk.base_sigmas(space), [0.1, 0.1, 0.1, 0.02, 0.1])
    np.testing.assert_allclose(walk.sigmas(np.array([False, True, False]), space), [0.1, 0.1, 0.5, 0.1, 0.1])


def test_an_axis_of_no_part_fails_naming_it(arm):
    with pytest.raises(ValueError, match=r"^tracker\.arm_samples\.axes\[0\]\.part=elbow: no such part"):
        ArmDictionary(arm, ArmGridSpec(axes=(ArmAxis("elbow", "r2", (0.0, 10.0, 5.0)),)))


def test_the_cache_key_follows_the_grid(arm):
    one = ArmDictionary(arm).source_key
    other = ArmDictionary(arm, ArmGridSpec(shoulder=(0.0, 0.0, 0.1))).source_key
    assert one != other and one == ArmDictionary(arm).source_key
