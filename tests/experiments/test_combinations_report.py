"""The comparison of combinations in ``make reproduce SCALE=paper`` (`experiments.combinations`): every row is a
valid run, and its tables read the runs' own metrics (`eval.combinations`)."""

import json
import shutil

import pytest

from eval.combinations import arm_table, body_table
from experiments.combinations import ARM_TRACKERS, body_runs, first_views
from experiments.real_motion import HELD_OUT
from experiments.schemas import CONFIG_DIR
from experiments.validate import validate_command_line
from tests.conftest import SMALL_ARM_GRID, run_cli
from tracker.motion.mocap import available_frames, read_clip


@pytest.mark.parametrize("folder", list(body_runs()))
def test_every_body_row_is_a_valid_run_of_every_held_out_clip(folder):
    row = body_runs()[folder]
    for clip in HELD_OUT:
        frames = available_frames(read_clip(clip), 0.0, row.fps)
        validate_command_line(
            [f"experiment={row.experiment}", f"scene.path={clip}", f"frames={frames}", *row.overrides],
            CONFIG_DIR,
            "config",
        )


def test_the_first_views_are_rig_body_multis_first_cameras():
    assert first_views(1) == "rig.views=[{name:front,position:[0.0,-4.5,0.9]}]"
    assert first_views(3).count("name:") == 3 and "oblique" in first_views(3)


def test_the_body_table_reads_each_clips_runs(tbf_run, tmp_path):
    root = tmp_path / "combinations"
    shutil.copytree(tbf_run, root / "swing" / "tbf_1_views")
    table = body_table(root, {"tbf_1_views": "tree filtering, 1 camera", "tbf_3_views": "absent"})
    metrics = json.loads((tbf_run / "metrics.json").read_text())
    assert len(table) == 1 and table.loc[0, "tracker and views"] == "tree filtering, 1 camera"
    assert table.loc[0, "root-aligned mm"] == round(metrics["mpjpe_root_aligned_mm"], 1)
    assert table.loc[0, "aligned / floor"] == round(metrics["mpjpe_root_aligned_mm"] / metrics["mpjpe_floor_mm"], 2)


def test_the_arm_table_compares_abis_and_tree_filtering_on_the_same_frames(tmp_path):
    runs = {}
    for label, overrides in ARM_TRACKERS.items():
        out = tmp_path / label.split()[0]
        grid = (f"tracker.cache_dir={tmp_path / 'cache'}", SMALL_ARM_GRID) if overrides else ()  # AbIS has none
        result = run_cli(
            out, "experiment=abis_fig8_fig9", "frames=3", "record.images=false", *overrides, *grid, cwd=tmp_path
        )
        assert result.returncode == 0, result.stderr
        runs[label] = out
    table = arm_table(runs).set_index("tracker")
    for label, out in runs.items():
        metrics = json.loads((out / "metrics.json").read_text())
        assert table.loc[label, "r2 RMS °"] == round(metrics["part2_r2_rms_deg"], 2)
        assert table.loc[label, "b1 RMS"] == round(metrics["part2_b1_rms"], 4)
    tbf = next(label for label in runs if "tree" in label)
    assert table.loc[tbf, "floor r2 RMS °"] != "—"  # the grid's floor, for tree filtering only
