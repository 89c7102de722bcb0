import json

import pandas as pd

from tests.experiments.test_run import blueprint_origins, frames_by_entity


def test_a_tbf_run_records_the_tree_search_per_level_and_its_timings(tbf_run):
    metrics = json.loads((tbf_run / "metrics.json").read_text())
    timing = json.loads((tbf_run / "timings.json").read_text())
    assert metrics["status"] == "ok" and metrics["tracker"] == "tbf"
    assert len(metrics["nodes_evaluated_mean"]) == 3 and all(n >= 1 for n in metrics["nodes_evaluated_mean"])
    assert len(metrics["tree_nodes"]) == 3 and metrics["tree_nodes"][-1] <= metrics["samples"]
    assert metrics["mpjpe_mm"] < 60 and metrics["swing_error_deg_mean"] < 15
    assert 0 <= metrics["mpjpe_root_aligned_mm"] < 60
    for stage in ("capture", "estimate", "estimate_prior", "estimate_level1", "estimate_level2", "estimate_level3"):
        assert timing[f"{stage}_ms_median"] > 0, stage
    table = pd.read_parquet(tbf_run / "frames.parquet").drop_duplicates("frame")
    assert list(table["frame"]) == list(range(6))
    assert (table["kept_level1"] <= table["nodes_level1"]).all() and (table["nodes_level3"] >= 1).all()
    assert len(table["est_pose"].iloc[0]) == 96 and table["entropy"].ge(0).all()
    frames = frames_by_entity(tbf_run / "run.rrd")
    for entity in (
        "/metrics/tree/level1/evaluated",
        "/metrics/tree/level3/kept",
        "/metrics/tree/entropy",
        "/metrics/params/swing/right_arm_deg/estimate",
        "/metrics/params/swing/right_arm_deg/truth",
    ):
        assert frames[entity] == list(range(6)), entity


def test_the_tbf_blueprint_shows_the_silhouette_and_the_tree_search(tbf_run):
    origins = blueprint_origins(tbf_run / "run.rrd")
    view = "main"
    assert f"world/cameras/{view}/image" in origins  # the image, and the silhouette beside and over it
    assert {"world", "metrics/params/swing", "metrics/tree", "metrics/silhouette_iou"} <= origins
    assert "metrics/correspondences" not in origins  # AbIS's pairs have no place here


def test_eval_figures_writes_every_figure_of_a_body_run(tbf_run, tmp_path):
    """A tree-filtering run of the body: its views, Fig 5's strip and its error against the dictionary's floor, by
    the command a user runs; 6 frames hold no complete swing, so no Fig 4(c) evidence."""
    import shutil
    import subprocess
    import sys

    run = shutil.copytree(tbf_run, tmp_path / "run")
    subprocess.run([sys.executable, "-m", "eval.figures", str(run)], check=True, capture_output=True)
    assert {"views.png", "fig5_strip.png", "error_against_floor.png"} <= {path.name for path in run.iterdir()}
    assert "fig4c_swings.png" not in {path.name for path in run.iterdir()}


def test_the_mean_estimate_averages_the_most_probable_samples_and_leaves_the_filter_as_it_was(tmp_path):
    """``tracker.estimate=mean``: each joint's rotation the posterior-weighted mean (SciPy's, joint by joint) of the
    ``mean_of`` most probable samples', the root placed as the most probable sample's; the filter steps as with
    ``map`` (its prior comes from its posterior, not the estimate)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    filtered = ("tracker.chain.candidates=0", "tracker.filter.jump_share=0.01")  # the filter's own estimate
    runs, observed = map_and_mean_runs(tmp_path, *filtered)
    averaged = 0
    for observation in observed:
        found = {way: run.tracker.step(observation) for way, run in runs.items()}
        posterior = runs["mean"].tracker.filter.posterior
        np.testing.assert_array_equal(posterior, runs["map"].tracker.filter.posterior)
        top = np.argsort(-posterior, kind="stable")[:10]
        top = top[posterior[top] > 0]
        samples = runs["mean"].tracker.samples.poses[top]
        mean, best = found["mean"].estimate, found["map"].estimate
        np.testing.assert_array_equal(mean[:3], best[:3])
        for joint in range(1, len(mean) // 3):
            expected = Rotation.from_rotvec(samples[:, 3 * joint : 3 * joint + 3]).mean(posterior[top])
            assert Rotation.from_rotvec(mean[3 * joint : 3 * joint + 3]).approx_equal(expected, atol=1e-9)
        averaged += len(top) > 1 and not np.allclose(mean, best)
    assert averaged  # some frame's estimate lies between the samples


def test_a_chains_mean_averages_the_candidates_near_its_end_weighted_by_their_chains(tmp_path):
    """With a chain (``tbf_multi_view``'s), ``tracker.estimate=mean``: each joint's rotation the mean (SciPy's, joint
    by joint) of the candidates within ``chain.mean_radius_m`` of the best chain's end, weighted by their chains'
    probabilities, the root placed as that end's; the chain steps as with ``map``."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    runs, observed = map_and_mean_runs(tmp_path)
    averaged = 0
    for observation in observed:
        found = {way: run.tracker.step(observation) for way, run in runs.items()}
        chain, other = runs["mean"].tracker.chain, runs["map"].tracker.chain
        np.testing.assert_array_equal(chain.scores, other.scores)
        near, weights = chain.around_best(runs["mean"].tracker.settings.chain.mean_radius_m)
        samples = runs["mean"].tracker.samples.poses[near]
        mean, end = found["mean"].estimate, found["map"].estimate
        assert found["map"].filter.sample == chain.candidates[np.argmax(chain.scores)]
        np.testing.assert_array_equal(mean[:3], end[:3])
        for joint in range(1, len(mean) // 3):
            expected = Rotation.from_rotvec(samples[:, 3 * joint : 3 * joint + 3]).mean(weights)
            assert Rotation.from_rotvec(mean[3 * joint : 3 * joint + 3]).approx_equal(expected, atol=1e-9)
        averaged += len(near) > 1 and not np.allclose(mean, end)
    assert averaged  # some frame's estimate lies between the candidates


def map_and_mean_runs(cache_dir, *overrides):
    """``tbf_multi_view`` on the small dictionary with each estimate (``map``, ``mean``), both started, and 3 frames'
    observations."""
    from experiments.bench.tbf import observations, start_tracker
    from experiments.components import build, compose
    from tests.experiments.test_hybrid_run import SMALL_DICTIONARY

    preset = ["experiment=tbf_multi_view", "scene.path=mocap/69_20.bvh", f"tracker.cache_dir={cache_dir}", *overrides]
    runs = {way: build(compose([*preset, *SMALL_DICTIONARY, f"tracker.estimate={way}"])) for way in ("map", "mean")}
    observed = observations(runs["map"], 3)
    for run in runs.values():
        start_tracker(run)
    return runs, observed
