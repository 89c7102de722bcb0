"""The plug-board: a tracker and a cost of a user's own (`tests.experiments.plugin_toys`, one module, and one YAML
each, written here into the test's folder) run through the real command line, recorded and tabled, with no file of
the project changed: the tracker's one registration also says which models it tracks from how many views (checked
at start, shown in the compatibility table) and how it looks in the recording (its panel, its points' colours)."""

import json
import subprocess
import sys

import pandas as pd
from rerun.chunk import RrdReader

from eval.figures import write_figures
from eval.paper_2_tables import table_4c
from eval.runs import collect
from eval.tables import sweep_table
from experiments.schemas import CONFIG_DIR
from tests.conftest import SMALL_GRID
from tests.experiments.test_run import blueprint_origins, frames_by_entity
from tracker.registry import COSTS, TRACKERS

PROJECT = CONFIG_DIR.parent
PLUGIN = "tests.experiments.plugin_toys"
OPTIONS = {
    "tracker/hold_still.yaml": "defaults:\n  - schema_hold_still\n  - _self_\n\nmarker_px: 8.0\n",
    "cost/uniform.yaml": "defaults:\n  - schema_uniform\n  - _self_\n",
}


def command_line(tmp_path, name, *overrides) -> list[str]:
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
    return command


def run(tmp_path, name, *overrides):
    result = subprocess.run(command_line(tmp_path, name, *overrides), cwd=PROJECT, capture_output=True, text=True)
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
    # How it looks, from its registration: its panel in the default layout, its points in its states' colours.
    assert "metrics/hold" in blueprint_origins(out / "run.rrd")
    assert state_colors(out / "run.rrd", "/world/cameras/left/image/corners") == {
        "near": (10, 20, 30, 255),
        "far": (40, 50, 60, 255),
    }


def test_a_users_tracker_says_once_what_it_tracks_from_how_many_views(tmp_path):
    """Its registration's fits: checked at start in one line, and a row of the README's compatibility table."""
    for overrides, message in (
        (["model=body_mesh"], "error: tracker=hold_still does not track model=body_mesh: allowed model=dsq_arm"),
        (["rig=mono"], "error: tracker=hold_still tracks model=dsq_arm from 2 to 3 camera views: rig=mono has 1"),
    ):
        command = command_line(tmp_path, "refused", "tracker=hold_still", *overrides)
        result = subprocess.run(command, cwd=PROJECT, capture_output=True, text=True)
        assert result.returncode == 2 and result.stderr.strip() == message
        assert not (tmp_path / "refused").exists()
    table = subprocess.run(
        [
            sys.executable,
            "-c",
            f"import {PLUGIN}; from experiments.options import compatibility_table as t; print(t())",
        ],
        cwd=PROJECT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "| `tracker=hold_still` | 2 to 3 views | — |" in table.splitlines()


def state_colors(path, entity: str) -> dict[str, tuple[int, ...]]:
    """The colour (RGBA) of each state of the points logged at ``entity``: their annotation classes."""
    colors = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path == entity and "AnnotationContext:context" in batch.schema.names:
            for context in batch.column("AnnotationContext:context").to_pylist():
                for annotation in context[0]:
                    info = annotation["class_description"]["info"]
                    colors[info["label"]] = tuple(int(info["color"]).to_bytes(4, "big"))
    return colors


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
