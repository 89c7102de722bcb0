import numpy as np
import pytest

from tracker.geometry.rotations import euler_to_matrix, rigid_transform, transform_points
from tracker.models.articulated import KinematicTree, forward_kinematics, local_from_world
from tracker.models.dsq import PARAM_INDEX, pole_point


def random_transforms(n, seed):
    rng = np.random.default_rng(seed)
    return np.stack([rigid_transform(euler_to_matrix(rng.uniform(-3, 3, 3)), rng.normal(size=3)) for _ in range(n)])


def test_topdown_order_visits_parents_first():
    tree = KinematicTree(("torso", "l_arm", "r_arm", "l_hand", "head"), (None, 0, 0, 1, 0))
    order = tree.topdown_order()
    assert order == [0, 1, 3, 2, 4]
    for part, parent in enumerate(tree.parents):
        if parent is not None:
            assert order.index(parent) < order.index(part)


def test_a_parent_must_come_before_its_child():
    with pytest.raises(ValueError, match="earlier part"):
        KinematicTree(("a", "b"), (1, None))


def test_forward_kinematics_composes_down_the_chain_and_round_trips():
    tree = KinematicTree(("a", "b", "c", "d"), (None, 0, 1, 0))
    local = random_transforms(4, seed=2)
    world = forward_kinematics(tree, local)
    np.testing.assert_allclose(world[2], local[0] @ local[1] @ local[2])
    np.testing.assert_allclose(world[3], local[0] @ local[3])
    np.testing.assert_allclose(local_from_world(tree, world), local, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_arm_joints_stay_connected_for_any_rotation_and_bending(arm, seed):
    rng = np.random.default_rng(seed)
    params = arm.rest_params()
    params[:, PARAM_INDEX["r1"] :] = rng.uniform(-2, 2, size=(3, 3))
    params[:, PARAM_INDEX["b1"]] = rng.uniform(-0.05, 0.05, size=3)
    params[:, PARAM_INDEX["t1"]] = rng.uniform(-0.5, 0.5, size=3)
    params = arm.connect(params)
    world = arm.world_transforms(params)
    for child, parent in ((1, 0), (2, 1)):
        tip = transform_points(world[parent], pole_point(params[parent], top=True)[None])
        base = transform_points(world[child], pole_point(params[child], top=False)[None])
        np.testing.assert_allclose(base, tip, atol=1e-12)
    tips = [transform_points(world[parent], pole_point(params[parent], top=True)[None])[0] for parent in (0, 1)]
    np.testing.assert_allclose(arm.joint_positions(params), tips, atol=1e-12)
