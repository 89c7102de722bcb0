from dataclasses import replace

import numpy as np
import pytest

from tracker.evaluation.body import OUTCOMES, joint_error_mm, score_swing, score_swings, split_swings
from tracker.geometry.rigs import mono
from tracker.models.body_skeleton import JOINT_INDEX, PART_NAMES
from tracker.registry import COSTS
from tracker.tbf.costs import silhouette_distance
from tracker.tbf.filter import FilterSettings, TreeFilter
from tracker.tbf.motion import LearnedTransitions, OccludedWiderWalk, PosePrior, RandomWalk
from tracker.tbf.pose_sets import arm_grid
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.scoring import ObservationScorer
from tracker.tbf.tracker import most_probable
from tracker.tbf.tree import Groups, build_tree, thresholds_for_shares

CAMERA = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=480.0, width=320, height=240)[0]
THRESHOLDS = (0.006, 0.002, 0.001)


@pytest.fixture(scope="module")
def samples(body, tmp_path_factory):
    poses = arm_grid(body, np.arange(-60.0, 121.0, 6.0), [0.0, 16.0], [0.0, 40.0])  # 124 poses
    return load_or_build(body, CAMERA, poses, tmp_path_factory.mktemp("samples"), progress=False)


@pytest.fixture(scope="module")
def tree(samples):
    return build_tree(samples, THRESHOLDS)


def xor(samples, resolution, a, b):
    masks = samples.silhouettes(resolution).masks()
    return np.count_nonzero(masks[a] ^ masks[b]) / masks[a].size


def test_every_sample_is_in_exactly_one_leaf_and_nodes_nest(samples, tree):
    leaves = tree.levels[-1]
    assert leaves.node_of_sample.shape == (len(samples),) and leaves.node_of_sample.max() == len(leaves) - 1
    assert sorted(np.concatenate([tree.leaf_members([leaf]) for leaf in range(len(leaves))])) == list(
        range(len(samples))
    )
    for above, below in zip(tree.levels, tree.levels[1:], strict=False):
        # a sample's node below is a child of its node above
        np.testing.assert_array_equal(below.parents[below.node_of_sample], above.node_of_sample)
    assert tree.node_counts[0] < tree.node_counts[1] <= tree.node_counts[2] <= len(samples)


def test_grouped_items_and_sums_equal_a_pass_over_every_item():
    """`Groups` (a level's children, a node's samples, their prior mass) against the passes over every item it
    replaces: a mask over the groups, and a weighted `np.bincount`, to the bit; groups asked in any order, repeated,
    empty or past the last, items of one group scattered, weights zero on most items and of mixed magnitudes."""
    rng = np.random.default_rng(23)
    for items, groups in ((1, 1), (40, 7), (5000, 900)):
        group_of = rng.integers(0, groups, items)
        group_of[group_of == groups // 2] = 0  # one group without items (unless it is group 0)
        weights = rng.random(items) * 10.0 ** rng.integers(-12, 3, items) * (rng.random(items) < 0.3)
        grouping = Groups(group_of, groups)
        for asked in (np.arange(groups), rng.integers(0, groups + 3, 2 * groups), np.zeros(0, np.int64)):
            chosen = np.zeros(groups + 3, bool)
            chosen[asked] = True
            np.testing.assert_array_equal(grouping.items(asked), np.flatnonzero(chosen[group_of]))
            mass = np.bincount(group_of, weights=weights, minlength=groups)
            kept = asked[asked < groups]
            assert grouping.sums(weights, kept).tobytes() == mass[kept].tobytes()
        for outside in (groups, -1):  # summed, a group it does not hold is an error, not memory read past its end
            with pytest.raises(IndexError):
                grouping.sums(weights, np.array([0, outside]))


def test_representatives_are_members_and_the_thresholds_hold(samples, tree):
    parents = np.zeros(len(samples), dtype=int)
    for level in tree.levels:
        np.testing.assert_array_equal(level.node_of_sample[level.representatives], np.arange(len(level)))
        for parent in np.unique(parents):
            seeds = level.seeds[level.parents == parent]
            members = np.flatnonzero(parents == parent)
            for k, a in enumerate(seeds):  # step 2: each seed was farther than T_l from the earlier ones
                assert all(xor(samples, level.resolution, a, b) > level.threshold for b in seeds[:k])
            for member in members:  # and it stopped when every member was within T_l of a seed
                assert min(xor(samples, level.resolution, member, s) for s in seeds) <= level.threshold
        parents = level.node_of_sample


def test_level_scoring_equals_scoring_each_node(samples, tree):
    level = tree.levels[1]
    stack = samples.silhouettes(level.resolution)
    u0, v0, u1, v1 = stack.window
    observed = np.zeros((120, 160), bool)
    observed[v0:v1, u0:u1] = stack.mask(17)
    for cost in COSTS.names():
        scorer = ObservationScorer(cost, observed, stack.window)
        vectorised = scorer.scores(stack, level.representatives)
        one_by_one = []
        for rep in level.representatives:
            model = np.zeros_like(observed)
            model[v0:v1, u0:u1] = stack.mask(rep)
            one_by_one.append(silhouette_distance(cost, observed, model, stack.window))
        np.testing.assert_allclose(vectorised, one_by_one, rtol=1e-9, atol=1e-12 * max(one_by_one), err_msg=cost)


def test_dm2_widens_exactly_the_occluded_parts():
    occluded = np.zeros(len(PART_NAMES), bool)
    occluded[PART_NAMES.index("right_upper_arm")] = True
    occluded[PART_NAMES.index("left_hand")] = True
    dm1, dm2 = RandomWalk(sigma=0.1), OccludedWiderWalk(sigma=0.1, m=5.0)
    np.testing.assert_array_equal(dm1.sigmas(occluded), dm1.base_sigmas())
    widened = np.flatnonzero(dm2.sigmas(occluded) != dm1.base_sigmas())
    joints = ["RightArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb"]
    expected = sorted(3 + 3 * JOINT_INDEX[j] + axis for j in joints for axis in range(3))
    np.testing.assert_array_equal(widened, expected)
    np.testing.assert_allclose(dm2.sigmas(occluded)[widened], 0.5)


def test_the_sparse_prior_matches_the_dense_sum(samples):
    rng = np.random.default_rng(0)
    posterior = np.zeros(len(samples))
    posterior[rng.choice(len(samples), 6, replace=False)] = rng.random(6)
    occluded = np.zeros(len(PART_NAMES), bool)
    occluded[PART_NAMES.index("right_upper_arm")] = True
    for motion in (RandomWalk(sigma=0.15), OccludedWiderWalk(sigma=0.15, m=5.0)):
        prior = PosePrior(samples.poses, motion, reach=5.0)
        sparse, _ = prior.prior(posterior, occluded)
        dense = prior.dense_prior(posterior, occluded)
        np.testing.assert_allclose(sparse, dense, atol=4e-6 * dense.max())


def test_kernel_neighbours_are_the_same_bytes_with_either_tree_and_every_pair_within_reach(samples):
    """The trees made up front (boxes shrunk) and while tracking (boxes as split) find the same pairs, the same
    distances bit for bit; the pairs are exactly those a naive search finds within reach, and the pairs and their
    distances are the bytes scipy's KD-tree over every component finds."""
    from scipy.spatial import cKDTree

    from tracker.tbf.motion import KernelNeighbours

    sigmas = OccludedWiderWalk(sigma=0.15, m=5.0).sigmas(np.eye(len(PART_NAMES), dtype=bool)[2])
    centres = np.array([5, 40, 3, 40, 77])
    poses = np.asarray(samples.poses, dtype=np.float64)
    covariance = np.cov(poses, rowvar=False)
    found = [KernelNeighbours(poses, sigmas, 5.0, covariance, up_front).pairs(centres) for up_front in (True, False)]
    for up_front, tracking in zip(*found, strict=True):
        assert up_front.tobytes() == tracking.tobytes()
    rows, neighbours, distances = found[0]
    scaled = poses / sigmas
    naive = np.linalg.norm(scaled[centres][:, None] - scaled[None], axis=2)
    within = np.nonzero(naive <= 5.0)  # by centre, then by sample: the order pairs gives
    np.testing.assert_array_equal(rows, within[0])
    np.testing.assert_array_equal(neighbours, within[1])
    np.testing.assert_allclose(distances, naive[within], rtol=1e-12)
    assert 5 < len(rows) < len(centres) * len(samples)  # neither only the centres nor everything
    full = cKDTree(scaled).sparse_distance_matrix(cKDTree(scaled[np.unique(centres)]), 5.0, output_type="ndarray")
    order = np.lexsort((full["i"], full["j"]))
    unique_rows = np.searchsorted(np.unique(centres), centres[rows])
    kept = {(int(c), int(n)): d for c, n, d in zip(full["j"][order], full["i"][order], full["v"][order], strict=True)}
    assert len(kept) == len(set(zip(unique_rows.tolist(), neighbours.tolist(), strict=True)))
    for centre, neighbour, distance in zip(unique_rows, neighbours, distances, strict=True):
        assert kept[int(centre), int(neighbour)].tobytes() == distance.tobytes()


@pytest.mark.parametrize("dims", [96, 94, 7])
def test_squared_distances_are_the_bytes_of_scipys_kd_tree(dims):
    """Sums of squares as cKDTree sums them, whole blocks of four and a remainder: the distances of every pair of
    random points, bit for bit against the tree's own."""
    from scipy.spatial import cKDTree

    from tracker.tbf.motion import squared_distances

    points = np.random.default_rng(dims).normal(size=(60, dims)) * np.linspace(0.1, 30, dims)
    found = cKDTree(points).sparse_distance_matrix(cKDTree(points), np.inf, output_type="ndarray")
    assert len(found) == 60 * 60  # every pair
    ours = np.sqrt(squared_distances(points[found["i"]], points[found["j"]]))
    assert ours.tobytes() == found["v"].tobytes()


def test_the_prior_keeps_few_trees_and_finds_the_same_terms_after_letting_one_go(samples):
    """Over more occlusion patterns than `KERNEL_TREES_KEPT`, and back to the first with samples it was not asked
    for before, the prior is bit for bit a fresh one's, and only the last used patterns hold a tree."""
    from tracker.tbf.motion import KERNEL_TREES_KEPT

    rng = np.random.default_rng(1)
    motion = OccludedWiderWalk(sigma=0.15, m=5.0)
    kept, patterns = PosePrior(samples.poses, motion, reach=5.0), []
    for k in range(KERNEL_TREES_KEPT + 3):
        occluded = np.zeros(len(PART_NAMES), bool)
        occluded[[k % len(PART_NAMES), (3 * k + 1) % len(PART_NAMES)]] = True
        patterns.append(occluded)
    for occluded in [*patterns, patterns[0], patterns[1]]:
        posterior = np.zeros(len(samples))
        posterior[rng.choice(len(samples), 6, replace=False)] = rng.random(6)
        fresh = PosePrior(samples.poses, motion, reach=5.0).prior(posterior, occluded)
        again = kept.prior(posterior, occluded)
        np.testing.assert_array_equal(again[0], fresh[0])
        assert again[1] == fresh[1]
    trees = [neighbours.tree is not None for neighbours in kept._neighbours.values()]
    assert sum(trees) == KERNEL_TREES_KEPT and trees[-KERNEL_TREES_KEPT:] == [True] * KERNEL_TREES_KEPT


def test_the_filter_recovers_a_held_samples_pose_from_its_own_silhouette(body, samples, tree):
    held = 72  # swing 48 degrees forward, abduction 0, elbow 0: the arm in full view
    stack = samples.silhouettes((320, 240))
    u0, v0, u1, v1 = stack.window
    observed = np.zeros((240, 320), bool)
    observed[v0:v1, u0:u1] = stack.mask(held)
    # A flat prior and a sharp likelihood: the silhouette alone decides.
    settings = FilterSettings(initial_sigma=100.0, likelihood_sigma=0.25, prune_fraction=1e-6)
    for cost in COSTS.names():
        tracker = TreeFilter(samples, tree, COSTS.defaults(cost), OccludedWiderWalk(), settings)
        tracker.start(samples.poses[0])
        result = tracker.step(observed)
        # Eq 13: a leaf's members share its likelihood, so the estimate is a member of the held sample's leaf.
        leaf_of = tree.levels[-1].node_of_sample
        assert leaf_of[result.sample] == leaf_of[held], cost
        assert body.right_arm_swing_deg(result.pose) == pytest.approx(
            body.right_arm_swing_deg(samples.poses[held]), abs=6.5
        )


def test_swing_scoring_on_hand_made_traces():
    frames = np.arange(81)
    truth = 40 * np.sin(2 * np.pi * frames / 40)  # two swings from the vertical, forward first
    assert [(s.start, s.stop) for s in split_swings(truth)] == [(0, 40), (40, 80)]
    assert score_swing(truth[:40], truth[:40] + 5) == "success"
    assert score_swing(truth[:40], truth[:40] * 1.8) == "error"  # followed, 32 degrees off at the peaks
    assert score_swing(truth[:40], np.zeros(40)) == "fail"  # never moved
    assert score_swing(truth[:40], -truth[:40]) == "fail"  # the wrong way
    assert score_swing(truth[:40], np.minimum(truth[:40], 5)) == "fail"  # never came forward
    counts = score_swings(truth, np.r_[truth[:40] + 5, np.zeros(41)])
    assert counts == {"fail": 1, "error": 0, "success": 1} and tuple(counts) == OUTCOMES


def test_root_aligned_mpjpe_ignores_where_the_body_stands_but_not_its_posture(body):
    pose = arm_grid(body, [30.0], [8.0], [0.0], [0.0], yaw_deg=-90.0)[0]
    moved = pose.copy()
    moved[:3] += [0.3, -0.4, 0.0]  # 0.5 m away, same posture
    assert joint_error_mm(body, pose, moved) == pytest.approx(500.0)
    assert joint_error_mm(body, pose, moved, root_aligned=True) == pytest.approx(0.0, abs=1e-9)
    raised = arm_grid(body, [90.0], [8.0], [0.0], [0.0], yaw_deg=-90.0)[0]
    raised[:3] = moved[:3]
    # The arm turns at the shoulder: only the right elbow and wrist move, so the aligned error is theirs over 15.
    joints = body.joint_positions(raised) - body.joint_positions(pose)
    arm = [JOINT_INDEX[name] for name in ("RightForeArm", "RightHand")]
    expected = 1e3 * np.linalg.norm(joints[arm] - (joints[JOINT_INDEX["Hips"]]), axis=1).sum() / 15
    assert joint_error_mm(body, pose, raised, root_aligned=True) == pytest.approx(expected, rel=1e-9)


def test_thresholds_for_shares_give_each_level_its_share_of_the_samples_at_the_boundary(samples):
    shares = (0.2, 0.6, 0.9)
    thresholds = thresholds_for_shares(samples, shares)
    counts = build_tree(samples, thresholds).node_counts
    for level, (share, count) in enumerate(zip(shares, counts, strict=True)):
        assert count <= share * len(samples)  # the largest tree not above the share ...
        smaller = (*thresholds[:level], thresholds[level] * 0.97, *thresholds[level + 1 :])
        assert build_tree(samples, smaller).node_counts[level] > share * len(samples)  # ... at the boundary
    assert thresholds_for_shares(samples, shares) == thresholds  # kept with the set


def test_the_learned_prior_is_the_normalised_mixture_of_walk_and_learned_moves(samples):
    rng = np.random.default_rng(1)
    n = len(samples)
    posterior = np.zeros(n)
    posterior[rng.choice(n - 3, 5, replace=False)] = rng.random(5)
    support = np.flatnonzero(posterior)
    # Learned moves from all but one support sample: one or two successors each, with counts.
    transitions = np.array([(i, i + 1, 3) for i in support[1:]] + [(i, i + 3, 1) for i in support[2:]])
    occluded = np.zeros(len(PART_NAMES), bool)
    occluded[PART_NAMES.index("left_forearm")] = True
    motion = LearnedTransitions(sigma=0.15, m=5.0, learned_share=0.6, learned_sigma=0.05)
    sparse, _ = PosePrior(samples.poses, motion, reach=60.0, transitions=transitions).prior(posterior, occluded)

    def kernel_row(centre, sigmas):  # N(x_j; x_centre, sigmas) over the set, normalised
        z = (samples.poses - samples.poses[centre]) / sigmas
        row = np.exp(-0.5 * np.sum(z * z, axis=1))
        return row / row.sum()

    walk_sigmas, learned_sigmas = motion.sigmas(occluded), motion.sigmas(occluded) / 3.0
    dense = np.zeros(n)
    for i in support:
        moves = transitions[transitions[:, 0] == i]
        share = 0.6 if len(moves) else 0.0
        dense += posterior[i] * (1 - share) * kernel_row(i, walk_sigmas)
        for _, to, count in moves:
            dense += posterior[i] * share * count / moves[:, 2].sum() * kernel_row(to, learned_sigmas)
    np.testing.assert_allclose(sparse, dense, rtol=1e-9, atol=1e-12)
    assert sparse.sum() == pytest.approx(posterior.sum())  # a mixture of normalised kernels keeps the mass


def test_learned_motion_needs_transitions(samples):
    with pytest.raises(ValueError, match="motion=learned learns from the clips"):
        PosePrior(samples.poses, LearnedTransitions(), transitions=np.zeros((0, 3), int))


def _observed(samples, index):
    stack = samples.silhouettes((320, 240))
    u0, v0, u1, v1 = stack.window
    observed = np.zeros((240, 320), bool)
    observed[v0:v1, u0:u1] = stack.mask(index)
    return observed


def test_each_frames_prior_made_between_the_frames_is_the_one_the_step_would_make(samples, tree):
    """Eq 14's prior of the next frame is made by a worker thread as soon as a step ends. A filter whose prior is
    made in the step instead (a feed of nothing drops the one made ahead) steps to the same posteriors, bit for
    bit."""
    settings = FilterSettings(initial_sigma=1.0, likelihood_sigma=0.5, prune_fraction=1e-6)
    ahead, in_step = (TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings) for _ in "ab")
    for filter_ in (ahead, in_step):
        filter_.start(samples.poses[60])
    for held in (60, 63, 66, 72, 78, 84):
        observed = _observed(samples, held)
        result = ahead.step(observed)
        assert in_step.step(observed).sample == result.sample
        in_step.feed(result.sample, 0.0)  # the posterior as it was (times 1, plus 0), its prior made in the step
        np.testing.assert_array_equal(ahead.posterior, in_step.posterior)


def test_a_feed_drops_the_prior_made_ahead_and_the_next_step_starts_from_the_fed_posterior(samples, tree):
    """After ``feed`` the next frame's prior comes from the fed posterior: all of it on one sample far from the
    estimate, the step's posterior lies within that sample's kernels (an independent prior, made here)."""
    motion = OccludedWiderWalk()
    settings = FilterSettings(initial_sigma=1.0, likelihood_sigma=0.5, prune_fraction=1e-6)
    fed, unfed = (TreeFilter(samples, tree, COSTS.defaults("nwxor"), motion, settings) for _ in "ab")
    for filter_ in (fed, unfed):
        filter_.start(samples.poses[60])
        estimate = filter_.step(_observed(samples, 60)).sample
    far = int(np.argmax(np.abs(samples.poses - samples.poses[estimate]).sum(axis=1)))
    fed.feed(far, 1.0)
    for filter_ in (fed, unfed):
        filter_.step(_observed(samples, 63))
    onto_far = np.zeros(len(samples.poses))
    onto_far[far] = 1.0
    prior, _ = PosePrior(samples.poses, motion).prior(onto_far, samples.occluded(motion.occlusion_area_px)[far])
    assert np.all(prior[fed.posterior > 0] > 0) and not np.array_equal(fed.posterior, unfed.posterior)
    assert not np.all(prior[unfed.posterior > 0] > 0)  # not a vacuous check: the unfed filter's lies elsewhere


@pytest.mark.parametrize(("count", "size"), [(1, 5), (2, 1), (40, 3)])
def test_the_sparse_prior_equals_the_dense_sum_for_sets_of_few_samples_or_components(count, size):
    """A set of one sample, of one component, or of fewer components than the trees' search axes: the prior's
    terms within reach are the dense sum's (a single sample has no covariance to take axes from)."""
    from tracker.tbf.motion import PosePrior, PoseSpace

    poses = np.random.default_rng(count).normal(0.0, 0.2, size=(count, size))
    prior = PosePrior(poses, RandomWalk(sigma=0.15), reach=6.0, space=PoseSpace(size, ()))
    posterior = np.random.default_rng(size).random(count)
    sparse, _ = prior.prior(posterior, np.zeros(0, bool))
    np.testing.assert_allclose(sparse, prior.dense_prior(posterior, np.zeros(0, bool)), rtol=1e-6, atol=1e-9)


def test_the_most_probable_samples_are_a_full_stable_sorts_nonzero_head():
    rng = np.random.default_rng(7)
    posterior = np.where(rng.random(5000) < 0.01, rng.choice([0.5, 0.25, 0.125], 5000), 0.0)  # sparse, with ties
    for count in (1, 3, 12, 60, 1000):
        full = np.argsort(-posterior, kind="stable")[:count]
        np.testing.assert_array_equal(most_probable(posterior, count), full[posterior[full] > 0])
    assert len(most_probable(np.zeros(10), 3)) == 0


def test_the_trees_xor_distances_count_differing_bits_as_numpy_does():
    """The tree's XOR distance counts each row's bits that differ from one row (a population count by halves in a
    compiled loop), as NumPy's ``bitwise_count`` counts them: random rows, one with no bit set, one with all, the
    last word part-filled."""
    from tracker.tbf.tree import _differing_bits

    rng = np.random.default_rng(2)
    rows = rng.integers(0, 2**63, (50, 7), dtype=np.uint64) << np.uint64(1) | rng.integers(0, 2, (50, 7)).astype(
        np.uint64
    )
    rows[3], rows[4] = 0, np.uint64(2**64 - 1)  # none set, all set
    rows[:, -1] &= np.uint64(2**20 - 1)  # the last word part-filled
    for index in (0, 3, 4):
        expected = np.bitwise_count(rows ^ rows[index]).sum(axis=1, dtype=np.int64)
        np.testing.assert_array_equal(_differing_bits(rows, index), expected)
    assert _differing_bits(rows, 3)[4] == 7 * 64 - 44  # all ones against none (the last word masked to 20 bits)


def test_the_seeds_are_those_of_the_loop_written_with_numpy():
    """Steps 2-3 (`_seeds`, one compiled loop): the same seeds in the same order and the same nearest seed for every
    member as the loop written with NumPy arrays (each new seed the first member of the largest mean XOR distance
    among those still farther than T_l from every seed), over two views of different sizes, with members alike."""
    from tracker.tbf.tree import _seeds

    def numpy_seeds(views, pixels, first, threshold):
        count = len(views[0])
        nearest, nearest_seed, total = np.full(count, np.inf), np.zeros(count, np.int64), np.zeros(count)
        seeds, candidate = [], first
        while candidate is not None:
            seeds.append(candidate)
            distance = sum(
                np.bitwise_count(rows ^ rows[candidate]).sum(axis=1, dtype=np.int64) / size
                for rows, size in zip(views, pixels, strict=True)
            ) / len(views)
            closer = distance < nearest
            nearest[closer], nearest_seed[closer] = distance[closer], len(seeds) - 1
            total += distance
            eligible = nearest > threshold
            eligible[seeds] = False
            mean = np.where(eligible, total / len(seeds), -np.inf)
            candidate = int(np.argmax(mean)) if eligible.any() else None
        return np.array(seeds), nearest_seed

    rng = np.random.default_rng(6)
    centre = rng.integers(0, 2**63, 5, dtype=np.uint64)

    def view(words):  # 300 members about one silhouette, each with its bits flipped at a rate of its own
        flipped = rng.random((300, words * 64)) < rng.uniform(0.0, 0.2, (300, 1))
        return centre[:words] ^ np.packbits(flipped, axis=1, bitorder="little").view(np.uint64)

    views = (view(5), view(3))
    for rows in views:  # members alike in both views: ties, which the first of them wins
        rows[200:260] = rows[100:160]
    pixels = np.array([5 * 64, 3 * 64])
    counts = []
    for threshold in (0.02, 0.08, 0.15, 0.3):
        seeds, nearest_seed = _seeds(views, pixels, 7, threshold)
        expected_seeds, expected_nearest = numpy_seeds(views, pixels, 7, threshold)
        np.testing.assert_array_equal(seeds, expected_seeds)
        np.testing.assert_array_equal(nearest_seed, expected_nearest)
        counts.append(len(seeds))
    assert counts == sorted(counts, reverse=True) and counts[0] > 100 and counts[-1] < 10  # a few seeds to most


def test_bit_rows_are_the_images_packed():
    """A stack's bit rows for the tree (`_packed_bits`, set straight from its runs) are its images as ``np.packbits``
    packs them, zero-padded to whole 64-bit words: runs of every length, aligned to a byte or not, images empty and
    full, a run wrapping into the next row."""
    from tracker.tbf.scoring import SilhouetteStack
    from tracker.tbf.tree import _packed_bits

    rng = np.random.default_rng(8)
    images = rng.random((40, 9, 13)) < rng.uniform(0.0, 1.0, (40, 1, 1))
    images[0], images[1] = False, True
    images[2] = False
    images[2, 3, 5:], images[2, 4, :7] = True, True  # 8 + 7 pixels from pixel 44: a byte's boundary crossed
    stack = SilhouetteStack.of(images, (0, 0, 13, 9))
    expected = np.zeros((40, 16), np.uint8)  # 117 pixels: two 64-bit words
    expected[:, :15] = np.packbits(images.reshape(40, -1), axis=1)
    np.testing.assert_array_equal(_packed_bits(stack), expected.view(np.uint64))


def test_a_flip_share_moves_each_samples_prior_to_its_flip_and_reaches_what_the_walk_cannot(samples, tree):
    """``flip_share`` of each sample's prior mass goes to its flip (a naive loop over the samples); a sample the
    motion model cannot reach from the start is found through the flip of the start's sample."""
    count = len(samples.poses)
    rng = np.random.default_rng(5)
    flips = rng.integers(0, count, count)
    settings = FilterSettings(initial_sigma=0.05, likelihood_sigma=0.5, prune_fraction=1e-6, flip_share=0.2)
    filter_ = TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings, flips=flips)
    prior = rng.random(count) * (rng.random(count) < 0.3)
    expected = 0.8 * prior / prior.sum()
    for sample in range(count):
        expected[flips[sample]] += 0.2 * prior[sample] / prior.sum()
    np.testing.assert_allclose(filter_.flipped(prior), expected, rtol=1e-12)

    held, start = 0, 72  # swing -60 degrees, and 48: far apart for the walk
    unflipped = TreeFilter(
        samples,
        tree,
        COSTS.defaults("nwxor"),
        OccludedWiderWalk(),
        FilterSettings(initial_sigma=0.05, likelihood_sigma=0.5, prune_fraction=1e-6),
    )
    unflipped.start(samples.poses[start])
    assert unflipped.step(_observed(samples, held)).sample != held and unflipped.posterior[held] == 0
    flips = np.arange(count)
    flips[unflipped.initial_sample] = held
    flipped = TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings, flips=flips)
    flipped.start(samples.poses[start])
    result = flipped.step(_observed(samples, held))
    leaf_of = tree.levels[-1].node_of_sample
    assert leaf_of[result.sample] == leaf_of[held] and flipped.posterior[held] > 0
    with pytest.raises(ValueError, match="needs the flips"):
        TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)


def test_a_search_by_the_likelihood_alone_reaches_what_the_walk_cannot_and_ranks_the_leaves_members(samples, tree):
    """``jump_share`` 1: after frame 0 the prior is flat, so a pose far from the last estimate is found; the most
    likely samples are the surviving leaves' members by their leaf's likelihood (its representative scored anew),
    best first, and the posterior is that likelihood normalised."""
    settings = FilterSettings(initial_sigma=0.05, likelihood_sigma=0.5, prune_fraction=1e-6, jump_share=1.0)
    alone = TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), settings)
    walking = TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), replace(settings, jump_share=0.0))
    held, start = 0, 72  # swing -60 degrees, and 48: far apart for the walk
    for filter_ in (alone, walking):
        filter_.start(samples.poses[start])
        filter_.step(_observed(samples, start))
    assert walking.step(_observed(samples, held)).sample != held
    result = alone.step(_observed(samples, held))
    finest = tree.levels[-1]
    assert finest.node_of_sample[result.sample] == finest.node_of_sample[held]

    likely, log_likelihood = alone.most_likely(len(samples.poses))
    assert set(likely) == set(np.flatnonzero(alone.posterior))
    assert np.all(np.diff(log_likelihood) <= 0)
    representatives = finest.representatives[finest.node_of_sample[likely]]
    scored = alone.log_likelihood(
        len(tree.levels) - 1, alone.score_samples(len(tree.levels) - 1, (_observed(samples, held),), representatives)
    )
    np.testing.assert_allclose(log_likelihood, scored, rtol=1e-12, atol=1e-12)
    expected = np.exp(log_likelihood - log_likelihood.max())
    np.testing.assert_allclose(alone.posterior[likely], expected / expected.sum(), rtol=1e-9)
    assert np.array_equal(alone.most_likely(3)[0], likely[:3])


def test_a_beam_keeps_at_most_its_width_of_the_best_nodes_a_level(samples, tree):
    """``beam``: each level keeps at most that many nodes, the pruning's survivors of highest posterior: the next
    level scores only their children. Wider than the pruning keeps, it changes nothing, to the bit."""
    settings = FilterSettings(initial_sigma=1.0, likelihood_sigma=4.0, prune_fraction=1e-9, jump_share=1.0)
    filters = {
        beam: TreeFilter(samples, tree, COSTS.defaults("nwxor"), OccludedWiderWalk(), replace(settings, beam=beam))
        for beam in (None, 2, 10**6)
    }
    results = {}
    for beam, filter_ in filters.items():
        filter_.start(samples.poses[60])
        filter_.step(_observed(samples, 60))
        results[beam] = filter_.step(_observed(samples, 72))
    wide = results[None]
    assert max(wide.nodes_kept) > 2 and max(results[2].nodes_kept) <= 2
    np.testing.assert_array_equal(filters[10**6].posterior, filters[None].posterior)
    narrow = filters[2]
    for level, evaluated in enumerate(narrow.last_evaluated[1:], 1):  # the children of the best 2 above
        above = tree.levels[level - 1]
        parents = {int(above.node_of_sample[tree.levels[level].representatives[node]]) for node in evaluated}
        assert len(parents) <= 2
    leaf_of = tree.levels[-1].node_of_sample
    assert leaf_of[results[2].sample] == leaf_of[wide.sample]  # here the best leaf's ancestors lead their levels
