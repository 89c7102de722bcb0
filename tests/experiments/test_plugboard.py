"""The plug-board: a tracker and a cost of a user's own (`tests.experiments.plugin_toys`, one module, and one YAML
each, written here into the test's folder) run through the real command line, recorded and tabled, with no file of
the project changed."""

import json
import subprocess
import sys

import pandas as pd

from eval.figures import write_figures
from eval.tables import collect, sweep_table, table_4c
from experiments.schemas import CONFIG_DIR
from tests.conftest import SMALL_GRID
from tests.experiments.test_run import frames_by_entity
from tracker.registry import COSTS, TRACKERS

PROJECT = CONFIG_DIR.parent
PLUGIN = "tests.experiments.plugin_toys"
OPTIONS = {
    "tracker/hold_still.yaml": "defaults:\n  - schema_hold_still\n  - _self_\n\nmarker_px: 8.0\n",
    "cost/uniform.yaml": "defaults:\n  - schema_uniform\n  - _self_\n",
}


def run(tmp_path, name, *overrides):
    conf = tmp_path / "conf"
    for path, text in OPTIONS.items():
        (conf / path).parent.mkdir(parents=True, exist_ok=True)
        (conf / path).write_text(text)
    command = [
        sys.executable,
        "-m",
        "experiments.run",
        f"plugins=[{PLUGIN}]",
        f"hydra.searchpath=[file://{conf}]",
        f"hydra.run.dir={tmp_path / name}",
        *overrides,
    ]
    result = subprocess.run(command, cwd=PROJECT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return tmp_path / name


def test_a_users_tracker_runs_is_recorded_tabled_and_drawn(tmp_path):
    assert "hold_still" not in TRACKERS and not list(CONFIG_DIR.glob("*/hold_still.yaml"))  # nothing in the project
    out = run(tmp_path, "hold", "tracker=hold_still", "frames=3")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["tracker"] == "hold_still"
    assert metrics["config"]["tracker"]["marker_px"] == 8.0  # from the user's YAML
    assert metrics["frames_held_max"] == 2 and metrics["failed_frames"] == 0  # its own figure, and the run's
    assert metrics["rms"]["forearm"]["r2_deg"] > 0  # the model's accuracy figures, for any tracker
    table = pd.read_parquet(out / "frames.parquet")
    assert table["held"].all() and list(table["frames_held"].unique()) == [0, 1, 2]
    # The tracker is given each frame's images, never the truth; its summary reads its own columns, none of the truth.
    assert set(table["given"]) == {"frame,images,silhouettes"}
    assert metrics["summarized_from"] == ["failure", "frame", "frames_held", "given", "held", "part"]
    recorded = frames_by_entity(out / "run.rrd")
    assert recorded["/metrics/hold/frames"] == [0, 1, 2]
    assert recorded["/world/cameras/left/image/corners"] == [0, 1, 2]
    assert recorded["/world/estimate/forearm"] == [0]  # the estimate never changed: its mesh is logged once
    assert [path.name for path in write_figures(out)] == [  # the arm's figures, but no pairs: no Fig 9
        "views.png",
        "fig6_input_views.png",
        "fig7_estimated_views.png",
        "fig8_part2_b1_r2.png",
    ]
    runs = collect([out])
    assert sweep_table(runs).loc[0, "tracker"] == "hold_still"


def test_a_users_cost_serves_the_tree_filter(tmp_path):
    assert "uniform" not in COSTS
    out = run(
        tmp_path,
        "tbf",
        "model=body_mesh",
        "tracker=tbf",
        "cost=uniform",
        "cost.weight=3",
        "motion=dm1",
        "frames=3",
        f"tracker.cache_dir={tmp_path / 'cache'}",
        "record.weight_maps=true",
        *SMALL_GRID,
    )
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["choices"]["cost"] == "uniform"
    assert metrics["mpjpe_mm"] < 60
    assert frames_by_entity(out / "run.rrd")["/capture/main/weights/uniform"] == [0, 1, 2]  # shown as every cost
    assert table_4c(collect([out])).loc[0, "cost"] == "uniform"
