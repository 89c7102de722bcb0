"""Tree-based filtering from several cameras: each view's samples, one tree over the views, the product of the
views' likelihoods, and eq 3's occlusion where a part is most visible."""

import numpy as np
import pytest

from tracker.geometry.rigs import View, cameras
from tracker.models.body_skeleton import PART_NAMES
from tracker.registry import COSTS
from tracker.tbf import filter as filter_module
from tracker.tbf.calibration import neighbour_scale
from tracker.tbf.costs import silhouette_distance
from tracker.tbf.filter import FilterSettings, TreeFilter
from tracker.tbf.motion import OccludedWiderWalk
from tracker.tbf.pose_sets import arm_grid
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.samples import SampleViews
from tracker.tbf.tree import build_tree

RIG = cameras(views=(View("front", (0.0, -4.5, 0.9)), View("side", (4.5, 0.0, 0.9))))
THRESHOLDS = (0.01, 0.004, 0.002)


@pytest.fixture(scope="module")
def views(body, tmp_path_factory):
    poses = arm_grid(body, np.arange(-60.0, 121.0, 15.0), [0.0, 30.0], [0.0, 60.0])  # 52 poses
    folder = tmp_path_factory.mktemp("samples")
    return SampleViews(tuple(load_or_build(body, camera, poses, folder, progress=False) for camera in RIG))


def full_image(stack, index, resolution):
    u0, v0, u1, v1 = stack.window
    image = np.zeros(resolution[::-1], bool)
    image[v0:v1, u0:u1] = stack.mask(index)
    return image


def mean_xor(views, resolution, a, b):
    distances = []
    for stack in views.silhouettes(resolution):
        masks = stack.masks()
        distances.append(np.count_nonzero(masks[a] ^ masks[b]) / masks[a].size)
    return np.mean(distances)


def test_the_tree_of_several_views_splits_on_their_mean_xor_distance(views):
    tree = build_tree(views, THRESHOLDS)
    parents = np.zeros(len(views), dtype=int)
    for level in tree.levels:
        for parent in np.unique(parents):
            seeds = level.seeds[level.parents == parent]
            for k, a in enumerate(seeds):  # each seed farther than T_l from the earlier ones, by the views' mean
                assert all(mean_xor(views, level.resolution, a, b) > level.threshold for b in seeds[:k])
            for member in np.flatnonzero(parents == parent):
                assert min(mean_xor(views, level.resolution, member, s) for s in seeds) <= level.threshold
        parents = level.node_of_sample
    # the side view tells apart arm swings the front view sees nearly edge-on: more nodes than the front alone
    assert tree.node_counts[0] > build_tree(views.sets[0], THRESHOLDS).node_counts[0] // 2


def test_the_likelihood_of_several_views_is_the_product_of_each_views(views):
    """Eq 10 per view with the view's own sigma; the node's log-likelihood is their sum. Checked against each
    view's distance computed pixel by pixel (`silhouette_distance`) for every node of every level."""
    tree = build_tree(views, THRESHOLDS)
    cost = COSTS.defaults("nwxor")
    filter_ = TreeFilter(views, tree, cost, OccludedWiderWalk(), FilterSettings(likelihood_sigma=0.7))
    held = 23
    for k, level in enumerate(tree.levels):
        stacks = views.silhouettes(level.resolution)
        # the observation: another pose's silhouettes, one view's moved by a pixel (no node matches it exactly)
        observations = tuple(
            np.roll(full_image(stack, held, level.resolution), view, axis=1) for view, stack in enumerate(stacks)
        )
        distances = filter_.score_samples(k, observations, level.representatives)
        expected_log_likelihood = np.zeros(len(level))
        for view, (stack, observation) in enumerate(zip(stacks, observations, strict=True)):
            by_pixel = np.array(
                [
                    silhouette_distance(cost, observation, full_image(stack, rep, level.resolution), stack.window)
                    for rep in level.representatives
                ]
            )
            np.testing.assert_allclose(distances[view], by_pixel, rtol=1e-9, atol=1e-12)
            sigma = 0.7 * neighbour_scale(views.sets[view], cost, level.resolution)
            assert filter_.level_sigmas[k][view] == pytest.approx(sigma, rel=1e-12)
            expected_log_likelihood += -0.5 * (by_pixel / sigma) ** 2
        np.testing.assert_allclose(filter_.log_likelihood(k, distances), expected_log_likelihood, rtol=1e-9)


def test_the_top_level_scored_view_by_view_keeps_the_nodes_and_log_likelihoods_of_every_view_scored(views, monkeypatch):
    """`TreeFilter._top_level` scores the second view only where the first leaves a node in reach of the pruning:
    after the level's pruning the same nodes as when every node is scored in every view, with the same
    log-likelihoods to the bit, whichever nodes bound the level's best (one, or `BOUNDING_NODES`); and it drops
    nodes on the way."""
    tree = build_tree(views, THRESHOLDS)
    level = tree.levels[0]
    nodes, rng = np.arange(len(level)), np.random.default_rng(5)
    dropped = 0
    for prune_fraction in (0.5, 1e-3, 0.0):
        settings = FilterSettings(likelihood_sigma=0.25, prune_fraction=prune_fraction)
        filter_ = TreeFilter(views, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)
        for held in (3, 23, 40):
            observations = [  # another pose's silhouettes, one view's moved by a pixel
                np.roll(full_image(stack, held, level.resolution), view, axis=1)
                for view, stack in enumerate(views.silhouettes(level.resolution))
            ]
            scorers = [filter_._scorer(0, view, observed) for view, observed in enumerate(observations)]
            mass = rng.uniform(0.1, 1.0, len(nodes))
            every = filter_.log_likelihood(0, [filter_.scores_from(s, 0, view) for view, s in enumerate(scorers)])
            posterior = every + np.log(mass)
            kept = np.flatnonzero(posterior >= posterior.max() + 2 * filter_.prune_log)
            for bounding in (1, filter_module.BOUNDING_NODES):
                monkeypatch.setattr(filter_module, "BOUNDING_NODES", bounding)
                reached, reached_mass, log_likelihood = filter_._top_level(nodes, mass, scorers)
                np.testing.assert_array_equal(reached_mass, mass[reached])
                assert log_likelihood.tobytes() == every[reached].tobytes()
                posterior = log_likelihood + np.log(reached_mass)
                np.testing.assert_array_equal(reached[posterior >= posterior.max() + 2 * filter_.prune_log], kept)
                dropped += len(nodes) - len(reached)
    assert dropped > 0


def test_a_part_is_occluded_only_when_no_view_sees_enough_of_it(views):
    front, side = (view.areas for view in views.sets)
    np.testing.assert_array_equal(views.areas, np.maximum(front, side))
    arm = PART_NAMES.index("right_upper_arm")
    # side-on the right arm hangs behind the torso; the front camera sees it beside the body
    hidden_from_the_side = np.flatnonzero((side[:, arm] < 50) & (front[:, arm] >= 50))
    assert len(hidden_from_the_side)
    assert views.sets[1].occluded(50)[hidden_from_the_side, arm].all()
    assert not views.occluded(50)[hidden_from_the_side, arm].any()


def test_without_pruning_the_two_views_find_every_held_samples_leaf(views):
    """A flat prior, no pruning: the silhouettes alone decide, and every sample's own silhouettes take the filter to
    its leaf (whose members share the leaf's likelihood)."""
    tree = build_tree(views, THRESHOLDS)
    settings = FilterSettings(initial_sigma=100.0, likelihood_sigma=0.25, prune_fraction=0.0)
    filter_ = TreeFilter(views, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)
    leaf_of = tree.levels[-1].node_of_sample
    for held in range(len(views)):
        filter_.start(np.asarray(views.poses[0]))
        observed = tuple(full_image(stack, held, (320, 240)) for stack in views.silhouettes((320, 240)))
        assert leaf_of[filter_.step(observed).sample] == leaf_of[held], held


def test_a_view_that_lost_the_person_has_no_say(views):
    """Given None for the side view (or specks that vanish at the top level), the two views' filter steps as a filter
    of the front view alone over the same tree: the same posterior and estimate frame after frame (its likelihood
    and its pruning one view's)."""
    tree = build_tree(views, THRESHOLDS)
    settings = FilterSettings(likelihood_sigma=0.5)
    both = TreeFilter(views, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)
    front = TreeFilter(SampleViews(views.sets[:1]), tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)
    for filter_ in (both, front):
        filter_.start(np.asarray(views.poses[0]))
    stack = views.silhouettes((320, 240))[0]
    specks = np.zeros((240, 320), bool)
    specks[100, 100] = specks[140, 200] = True  # two pixels: nothing at the top level's resolution
    for held, other in ((3, None), (17, specks), (30, None)):
        observed = full_image(stack, held, (320, 240))
        lost, alone = both.step((observed, other)), front.step((observed,))
        assert lost.sample == alone.sample and lost.nodes_kept == alone.nodes_kept
        np.testing.assert_allclose(both.posterior, front.posterior, rtol=1e-12, atol=1e-300)
    with pytest.raises(ValueError, match="no view sees the person"):
        both.step((None, None))
