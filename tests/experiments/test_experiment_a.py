"""Experiment A under the paper's conditions (`experiment=tbf_table4c`): a two-frame run of the preset through the
real CLI, the standard body it names, its pictures, and the realism sweep's settings."""

import json

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from eval.body_figures import posture_strip, realism_plot, swing_traces
from eval.cost_figures import competing_samples
from experiments.experiment_a import realism_overrides
from tracker.models.body_shapes import STANDARD_BODIES


def test_the_preset_runs_on_the_nearest_standard_body_and_says_which(experiment_a_run):
    metrics = json.loads((experiment_a_run / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["frames_done"] == 2
    body = metrics["body"]
    assert body["name"] in STANDARD_BODIES and body["name"].startswith("male")
    assert abs(body["stature_m"] - body["subject_stature_m"]) < 0.05  # a man of 1.77 m in a size of 1.80 m
    assert body["subject_stature_m"] != body["stature_m"]  # ... but not the subject himself
    assert len(metrics["tree_thresholds"]) == 3 and metrics["samples"] <= 15 * 30
    assert metrics["tree_nodes"][0] < metrics["tree_nodes"][1] <= metrics["tree_nodes"][2] <= metrics["samples"]


def test_experiment_a_pictures_are_drawn_from_a_run(experiment_a_run, tmp_path):
    strip = posture_strip(experiment_a_run, (0, 1), tmp_path / "strip.png")
    traces = swing_traces({"nwxor + dm2": experiment_a_run}, tmp_path / "traces.png")
    cells = ((0, "wxor", 20), (1, "wxor", 3), (0, "nwxor", 22), (1, "nwxor", 6))
    points = pd.DataFrame([{"realism": r, "cost": c, "success": s, "followed": s + 2} for r, c, s in cells])
    realism = realism_plot(points, tmp_path / "realism.png")
    why = competing_samples({"nwxor + dm2": experiment_a_run}, tmp_path / "why.png")
    for path in (strip, traces, realism, why):
        image = np.asarray(Image.open(path))
        assert image.shape[0] > 100 and image.std() > 10  # drawn, not blank


def test_the_realism_knob_runs_from_the_standard_body_at_rest_to_the_experiment_itself():
    none, half, full = (dict(o.split("=") for o in realism_overrides(level)) for level in (0.0, 0.5, 1.0))
    assert none["scene.body.variation"] == "0" and none["tracker.samples.capture.amplitude"] == "0"
    standard = STANDARD_BODIES["male_h0.54_stout"]
    assert [float(none[f"model.shape.{k}"]) for k in ("gender", "muscle", "weight", "height")] == pytest.approx(
        [standard.gender, standard.muscle, standard.weight, standard.height]
    )
    assert [float(full[f"model.shape.{k}"]) for k in ("muscle", "weight", "height")] == pytest.approx([0.6, 0.6, 0.52])
    assert float(half["model.shape.height"]) == pytest.approx((standard.height + 0.52) / 2)
