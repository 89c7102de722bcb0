"""The hybrid tracker through the real CLI: each preset's 2-frame run on a small dictionary, the refinement's
columns and series, and a refined estimate that explains the views at least as well as the dictionary's proposal."""

import json

import numpy as np
import pandas as pd
import pytest

from experiments.bench.tbf import observations, start_tracker
from experiments.components import build, compose
from tests.conftest import _cli_run
from tests.experiments.test_run import frames_by_entity

SMALL_DICTIONARY = (
    "tracker.samples.clips=[mocap_daz/martial_04.bvh]",
    "tracker.samples.clip_turns_deg=[0.0]",
    "tracker.thresholds=[0.05,0.03,0.02]",
)


@pytest.fixture(scope="module")
def hybrid_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("hybrid_cache")


def small_run(cache, *overrides: str) -> tuple[str, ...]:
    return ("scene.path=mocap/69_20.bvh", f"tracker.cache_dir={cache}", *SMALL_DICTIONARY, *overrides)


@pytest.fixture(scope="module", params=["hybrid_paper_scale", "hybrid_multi_view"])
def hybrid_run(request, tmp_path_factory, hybrid_cache):
    overrides = small_run(hybrid_cache, f"experiment={request.param}", "frames=2")
    return _cli_run(tmp_path_factory, request.param, *overrides)


def test_a_hybrid_run_refines_the_dictionarys_proposal(hybrid_run):
    metrics = json.loads((hybrid_run / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["tracker"] == "hybrid" and metrics["frames_done"] == 2
    assert "mpjpe_floor_mm" in metrics and "pa_mpjpe_mm" in metrics  # judged as tree filtering is, and by PA
    timings = json.loads((hybrid_run / "timings.json").read_text())
    assert timings["estimate_refine_ms_median"] > 0 and timings["estimate_level1_ms_median"] > 0
    table = pd.read_parquet(hybrid_run / "frames.parquet").drop_duplicates("frame")
    # then the previous refined pose moved on and as it was, from frame 1 on, or from frame 0 where the preset starts
    # from the given pose
    settings = metrics["config"]["tracker"]
    proposals, given = settings["proposals"], settings["start_from"]
    last = proposals + len(settings["turns_deg"]) + int(settings["extrapolate"])
    assert table["hybrid_choice"].between(0, last).all()
    assert table["hybrid_choice"].iloc[0] <= last if given == "initial" else table["hybrid_choice"].iloc[0] < proposals
    # Without pairs (frame 0) the fit never explains the silhouettes worse than the proposal; with them, it trades
    # some of the silhouettes' cost for the features'.
    assert table["fit_cost"].tolist()[0] <= table["fit_cost_proposal"].tolist()[0]
    pairs = table["feature_pairs"].tolist()  # the skin's features, where the preset weighs them (3 cameras)
    assert (
        "turned_away" in table
        and pairs[0] == 0
        and (pairs[1] > 20 if metrics["config"]["tracker"]["fit"]["features"]["weight"] else pairs[1] == 0)
    )
    frames = frames_by_entity(hybrid_run / "run.rrd")
    assert frames["/metrics/hybrid/fit_cost"] == [0, 1] and frames["/metrics/tree/entropy"] == [0, 1]


def test_the_fed_posterior_reaches_the_next_prior_as_if_fed_at_once(hybrid_cache):
    """A worker thread searches the sample nearest each refined pose between the frames; the next step moves the
    posterior onto it before its prior, so every frame's posterior is the same as when the feed is made within the
    step (a feed lost, or made after the prior, would change the next one)."""
    # (the one-camera preset feeds nothing back: its chain searches by the likelihood alone, without a prior)
    filtered = ("tracker.chain.candidates=0", "tracker.filter.jump_share=0.05")
    overrides = small_run(hybrid_cache, "experiment=hybrid_paper_scale", "frames=3", "tracker.feed=0.5", *filtered)
    run = build(compose(list(overrides)))
    observed = observations(run, 3)
    posteriors: dict[bool, list] = {False: [], True: []}
    for at_once in posteriors:
        start_tracker(run)
        for observation in observed:
            run.tracker.step(observation)
            posteriors[at_once].append(run.tracker.filter.posterior.copy())
            if at_once:
                run.tracker._feed()
    assert not np.array_equal(run.tracker.filter.posterior, posteriors[True][-1])  # the feed moves it
    assert np.array_equal(posteriors[False], posteriors[True])


def test_started_from_the_given_pose_frame_0_is_refined_from_it(hybrid_cache):
    """``start_from=initial``: the frame-0 pose the run gives is a candidate, held where it stands; from tree
    filtering's generic initial prior alone, frame 0 is only as good as the small dictionary's proposals."""
    from tracker.evaluation.body import joint_errors_mm

    errors = {}
    for start_from in ("prior", "initial"):
        overrides = small_run(hybrid_cache, "experiment=hybrid_multi_view", f"tracker.start_from={start_from}")
        run = build(compose(list(overrides)))
        start_tracker(run)
        result = run.tracker.step(observations(run, 1)[0])
        errors[start_from] = joint_errors_mm(run.model, run.scene.params(run.model, 0), result.estimate)
        assert result.frame_columns["hybrid_choice"] <= run.tracker.settings.proposals + 2  # 2 turns_deg
    assert errors["initial"]["absolute"] < 30.0 < errors["prior"]["absolute"]  # mm: the tracker's body is not his


def test_tree_filtering_from_one_camera_keeps_the_way_its_start_faces_and_from_the_given_pose_starts_right(
    hybrid_cache,
):
    """``tracker.initial_pose``: one silhouette does not say whether the subject faces the camera or turns his back,
    so tree filtering started upright facing away from him (``initial_yaw_deg``) estimates him turned; started from
    the given frame-0 pose it faces his way."""
    from tracker.evaluation.body import root_orientation_error_deg
    from tracker.geometry.rotations import rotation_vector_to_matrix

    def built(*overrides: str):
        both_ways = "tracker.samples.clip_turns_deg=[0.0,180.0]"  # the dictionary holds him facing either way
        filtered = ("tracker.chain.candidates=0", "tracker.filter.jump_share=0.05")  # the filter's own estimate
        overrides = (both_ways, *filtered, *overrides)
        return build(compose(list(small_run(hybrid_cache, "experiment=tbf_paper_scale", *overrides))))

    run = built()  # only its scene: the pose it gives
    given = run.scene.params(run.model, 0)
    hips = rotation_vector_to_matrix(given[3:6])
    away_deg = np.degrees(np.arctan2(hips[1, 0], hips[0, 0])) + 90.0  # `arms_pose`'s yaw turns the hips by yaw + 90
    errors = {}
    for initial_pose in ("upright", "given"):
        run = built(f"tracker.initial_pose={initial_pose}", f"tracker.initial_yaw_deg={away_deg:.3f}")
        start_tracker(run)
        estimate = run.tracker.step(observations(run, 1)[0]).estimate
        errors[initial_pose] = float(root_orientation_error_deg(given, estimate))
    assert errors["given"] < 45.0 and errors["upright"] > 90.0, errors


def test_a_candidate_turned_further_than_max_turn_deg_from_the_last_estimate_is_kept_from_the_choice(hybrid_cache):
    from scipy.spatial.transform import Rotation

    run = build(compose(list(small_run(hybrid_cache, "experiment=hybrid_paper_scale", "tracker.max_turn_deg=90"))))
    tracker, last = run.tracker, run.scene.params(run.model, 0)
    candidates = []
    for turn_deg in (0.0, 30.0, 89.0, 91.0, 179.0):  # about the vertical, then about a tilted axis
        pose = last.copy()
        pose[3:6] = (
            Rotation.from_rotvec([0.0, 0.0, np.radians(turn_deg)]) * Rotation.from_rotvec(last[3:6])
        ).as_rotvec()
        candidates.append(pose)
    tilted = last.copy()
    tilted[3:6] = (
        Rotation.from_rotvec(np.radians(100.0) * np.array([0.6, 0.0, 0.8])) * Rotation.from_rotvec(last[3:6])
    ).as_rotvec()
    assert not tracker.turned_away(candidates, None).any()  # no estimate yet: any may be chosen
    assert tracker.turned_away([*candidates, tilted], last).tolist() == [False, False, False, True, True, True]


def test_screen_best_screens_the_candidates_cheapest_as_proposed_and_the_last_pose(hybrid_cache):
    overrides = small_run(
        hybrid_cache,
        "experiment=hybrid_multi_view",
        "tracker.proposals=4",
        "tracker.screen_best=2",
        "tracker.rescue_ratio=null",  # the preset searches a hard frame again, screening every candidate
    )
    run = build(compose(list(overrides)))
    start_tracker(run)
    tracker = run.tracker
    for observation in observations(run, 2):
        result = tracker.step(observation)
        # of 4 proposals, 2 turned poses (the preset's turns_deg) and the last pose
        assert result.frame_columns["screened"] == 2 and result.frame_columns["hybrid_choice"] <= 6
    last = tracker.refined
    rng = np.random.default_rng(0)
    candidates = [last + np.r_[np.zeros(3), rng.normal(0, 0.05 * k, len(last) - 3)] for k in range(1, 5)] + [last]
    costs = [tracker.fit.fit_cost(pose) for pose in candidates]
    cheapest = min(range(4), key=costs.__getitem__)  # of the proposals; the last pose is always screened
    assert tracker.screened(candidates).tolist() == sorted([cheapest, 4])
    tracker.refined = None  # no last pose: the two cheapest
    assert tracker.screened(candidates).tolist() == sorted(np.argsort(costs, kind="stable")[:2].tolist())
    assert tracker.screened(candidates[:2]).tolist() == [0, 1]


# Proposing 4 samples, screening 2, searching again any frame that costs more than the last ones' median.
RESCUING = ("tracker.proposals=4", "tracker.screen_best=2", "tracker.rescue_ratio=1.0")


def started_multi_view(cache, *overrides: str):
    """The three-camera preset's tracker with ``overrides``, started, and its first two frames."""
    run = build(compose(list(small_run(cache, "experiment=hybrid_multi_view", *overrides))))
    start_tracker(run)
    return (run.tracker, *observations(run, 2))


def test_a_hard_frame_is_searched_again_and_keeps_the_lowest_of_the_best_screened_refined_in_full(hybrid_cache):
    """``rescue_ratio``: a frame whose estimate costs more than that many times the last frames' median screens
    every candidate and refines the ``screen_best`` lowest after their screen in full; the estimate is the lowest
    of them and the first choice, as a naive search over every candidate finds it."""
    tracker, first, second = started_multi_view(hybrid_cache, *RESCUING)
    assert tracker.step(first).frame_columns["rescued"] == 0  # no cost to compare with yet
    assert not tracker._hard(tracker._recent_costs[0]) and tracker._hard(1.0001 * tracker._recent_costs[0])
    tracker._recent_costs[0] = 1e-9  # every estimate is harder than that
    columns = tracker.step(second).frame_columns
    # every candidate screened: 4 proposals, 2 turned poses (the preset's turns_deg) and the last pose
    assert columns["rescued"] == 1 and columns["screened"] == 7
    # the same search, naively: every candidate screened, the 2 lowest refined in full, the lowest kept
    rng = np.random.default_rng(0)
    last = tracker.refined
    candidates = [last + np.r_[np.zeros(3), rng.normal(0, 0.1, len(last) - 3)] for _ in range(4)] + [last]
    placed = last[:3]
    screened = [tracker.fit.refine(pose, tracker.settings.screen_iterations, placed) for pose in candidates]
    lowest = np.argsort([cost for _, cost in screened], kind="stable")[:2]
    chosen_pose, chosen_cost = tracker.fit.refine(screened[4][0], root=placed)
    naive = [(4, chosen_pose, chosen_cost)] + [(k, *tracker.fit.refine(screened[k][0], root=placed)) for k in lowest]
    expected = min(naive, key=lambda found: found[2])  # the first of the lowest
    (pose, cost, choice), kept, turned_away = tracker.rescue(
        candidates, np.array([4]), screened[4:], (chosen_pose, chosen_cost, 4), placed
    )
    assert kept.tolist() == [0, 1, 2, 3, 4] and choice == expected[0] and cost == expected[2] <= chosen_cost
    np.testing.assert_array_equal(pose, expected[1])
    assert not turned_away.any()  # the preset lets any turn be chosen


def test_a_hard_frame_counts_every_screened_candidate_that_turned_away(hybrid_cache):
    """On a frame searched again, ``turned_away`` counts the candidates of both screens whose root turned more than
    ``max_turn_deg`` from the last estimate: at 0 degrees every one of the 7 (a screen moves even the last estimate's
    root), where the first screen holds 2."""
    tracker, first, second = started_multi_view(hybrid_cache, *RESCUING, "tracker.max_turn_deg=0")
    tracker.step(first)
    tracker._recent_costs[0] = 1e-9  # every estimate is harder than that
    columns = tracker.step(second).frame_columns
    assert columns["rescued"] == 1 and columns["screened"] == 7 and columns["turned_away"] == 7


def test_where_the_views_cannot_place_the_person_the_fit_holds_the_root_where_the_last_estimate_stood(hybrid_cache):
    """A frame the views could not place the person in (`person_placed` false: e.g. one view sees him, and none
    did before) puts its candidates, and holds their root, where the last refined pose stood, not at the filter's
    sample's own root (the samples are posed in place); a placed frame, where the filter placed him."""
    tracker, first, second = started_multi_view(hybrid_cache)
    tracker.step(first)
    assert tracker.person_placed  # every view sees him
    last, sample_root = tracker.refined.copy(), np.array([4.0, -3.0, 0.9])  # not where he stands
    tracker.person_placed = False
    np.testing.assert_array_equal(tracker.root_held(sample_root), last[:3])
    tracker.person_placed = True
    np.testing.assert_array_equal(tracker.root_held(sample_root), sample_root)
    tracker.step(second)
    assert tracker.person_placed


def test_the_last_pose_moved_on_turns_about_the_vertical_and_repeats_its_last_change(hybrid_cache):
    """``turns_deg``: the last refined pose's joints turned about the vertical through its root, nothing else moved;
    ``extrapolate``: a body that turned 20 degrees and bent a joint by some angle is proposed turned and bent as much
    again (none before a second refined pose)."""
    from scipy.spatial.transform import Rotation

    overrides = small_run(hybrid_cache, "experiment=hybrid_multi_view", "tracker.turns_deg=[-30,45]")
    run = build(compose([*overrides, "tracker.extrapolate=true"]))
    tracker, body = run.tracker, run.model
    assert tracker.moved_on() == []
    first = run.scene.params(run.model, 0)
    tracker.refined = first
    turned = tracker.moved_on()
    assert len(turned) == 2  # no change seen yet: nothing to extrapolate
    joints = body.joint_positions(first)
    for angle, pose in zip((-30.0, 45.0), turned, strict=True):
        spin = Rotation.from_euler("z", np.radians(angle)).as_matrix()
        expected = (joints - first[:3]) @ spin.T + first[:3]
        np.testing.assert_allclose(body.joint_positions(pose), expected, atol=1e-9)
        np.testing.assert_array_equal(pose[6:], first[6:])
    second = first.copy()  # turned by 20 degrees, one joint bent by 0.1 rad on each axis
    second[3:6] = (Rotation.from_euler("z", np.radians(20.0)) * Rotation.from_rotvec(first[3:6])).as_rotvec()
    second[12:15] += 0.1
    tracker._before_refined, tracker.refined = first, second
    onward = tracker.moved_on()[-1]
    again = Rotation.from_euler("z", np.radians(40.0)) * Rotation.from_rotvec(first[3:6])
    assert Rotation.from_rotvec(onward[3:6]).approx_equal(again, atol=1e-9)
    np.testing.assert_allclose(onward[12:15], first[12:15] + 0.2, atol=1e-12)
    np.testing.assert_array_equal(np.delete(onward, np.r_[3:6, 12:15]), np.delete(second, np.r_[3:6, 12:15]))
