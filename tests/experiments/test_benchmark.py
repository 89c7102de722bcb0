"""The real-motion benchmark: its split checked before anything runs (one line per mistake), the project's split
keeping every test clip out of every dictionary, and the whole benchmark on a tiny split through the real CLI."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from eval.benchmark import MEASURES, benchmark_table
from experiments.benchmark import clip_overrides, main, searches_dictionary
from experiments.benchmark_split import LISTS, SPLITS_DIR, SplitError, load_split
from experiments.schemas import CONFIG_DIR
from experiments.validate import validate_command_line
from tracker.data import data_path
from tracker.models.body_shapes import STANDARD_BODIES
from tracker.tbf.sample_spec import SampleSpec, TrueRate, clip_files


def write_split(tmp_path, **entries):
    path = tmp_path / "split.yaml"
    path.write_text(yaml.safe_dump({"dictionary": ["mocap_daz/martial_04.bvh"], **entries}, sort_keys=False))
    return path


def test_the_project_split_keeps_every_test_clip_out_of_every_dictionary():
    split = load_split("cmu")
    files = {name: {data_path(clip).resolve() for clip in split.clips(name)} for name in LISTS}
    assert len(files["test"]) == 5 and len(files["validation"]) >= 1
    assert not files["test"] & files["dictionary"] and not files["validation"] & files["dictionary"]
    # What a row's tracker reads from the overrides is the dictionary's clips, nothing else.
    overrides = clip_overrides(split, "mocap_daz/salsa_06.bvh", dictionary=True)
    clips = next(o for o in overrides if o.startswith("tracker.samples.clips=")).split("=", 1)[1].strip("[]")
    spec = SampleSpec(clips=tuple(clips.split(",")), clip_true_fps=(TrueRate("mocap_daz/salsa_*.bvh", 60.0),))
    read = {data_path(path).resolve() for _, path, _ in clip_files(spec)}
    assert read == files["dictionary"]
    assert "scene.true_fps=60.0" in overrides  # the salsa clips' true rate, not their header's


def test_each_clip_has_a_subject_of_its_own_drawn_from_the_standard_range():
    split = load_split("cmu")
    subjects = [split.subject(clip) for clip in split.clips("test")]
    assert len(set(subjects)) == len(subjects) and split.subject("mocap/69_20.bvh") == subjects[1]
    heights = [body.height for body in STANDARD_BODIES.values()]
    assert all(min(heights) <= s.height <= max(heights) and s.gender in (0.0, 1.0) for s in subjects)


@pytest.mark.parametrize(
    "entries, message",
    [
        ({"test": ["mocap_daz/martial_0*.bvh"]}, r"martial_04.bvh is in both dictionary\[0\].* and test"),
        ({"test": ["mocap/nope.bvh"]}, r"test\[0\]=mocap/nope.bvh names no clip"),
        ({"tests": ["mocap/69_20.bvh"]}, r"unknown key tests: allowed dictionary"),
        ({"fps": -1}, r"fps=-1 is out of range"),
        ({"dictionary": []}, r"dictionary=\[\] is not allowed"),
        ({"rows": {"x": {"label": "x"}}}, r"experiment"),
    ],
)
def test_a_bad_split_stops_at_start_with_one_line(tmp_path, capsys, entries, message):
    path = write_split(tmp_path, **entries)
    with pytest.raises(SplitError, match=message):
        load_split(path)
    with pytest.raises(SystemExit) as stopped:
        main(["--split", str(path), "--reports", str(tmp_path / "reports")])
    assert stopped.value.code == 2 and len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not (tmp_path / "reports").exists()


def test_the_benchmark_on_a_tiny_split_tabulates_every_row_against_the_clips_floor(tmp_path):
    cache = tmp_path / "cache"
    small = [
        f"tracker.cache_dir={cache}",
        "tracker.samples.clip_turns_deg=[0.0]",
        "tracker.thresholds=[0.05,0.03,0.02]",
    ]
    away = [*small, "rig.target=[0,-9,1]"]
    rows = {
        "tbf": {"label": "tree filtering", "experiment": "tbf_paper_scale", "overrides": small},
        "abis": {"label": "AbIS", "experiment": "abis_body", "overrides": ["rig=body_multi"]},
        # its camera looks away: the run fails before its first frame, and the benchmark goes on
        "lost": {"label": "looking away", "experiment": "tbf_paper_scale", "overrides": away},
    }
    path = write_split(tmp_path, validation=["mocap/143_33.bvh"], test=["mocap/69_20.bvh"], max_frames=2, rows=rows)
    reports = tmp_path / "reports"
    main(["--split", str(path), "--reports", str(reports)])
    lost = reports / "benchmark" / "69_20" / "lost"
    assert json.loads((lost / "metrics.json").read_text())["frames_done"] == 0 and not (lost / "fig5.png").exists()
    rows.pop("lost")
    runs = {folder: reports / "benchmark" / "69_20" / folder for folder in rows}
    metrics = {folder: json.loads((run / "metrics.json").read_text()) for folder, run in runs.items()}
    assert all(m["status"] == "ok" and m["frames_done"] == 2 for m in metrics.values())
    assert metrics["tbf"]["config"]["tracker"]["samples"]["clips"] == ["mocap_daz/martial_04.bvh"]
    assert metrics["tbf"]["config"]["model"]["shape"] == metrics["abis"]["config"]["model"]["shape"]
    table = pd.read_csv(reports / "benchmark.csv")
    assert list(table["tracker"]) == ["tree filtering", "AbIS", "looking away"] and set(MEASURES) <= set(table.columns)
    assert table.loc[2, "status"].startswith("failed: ValueError") and table.loc[2, ["frames", "scored"]].sum() == 0
    assert table.loc[2, list(MEASURES)].isna().all()
    table = table.iloc[:2]
    assert list(table["scored"]) == [2, 2]  # 69_20 starts in every view
    floor = metrics["tbf"]["mpjpe_floor_mm"]  # AbIS searches no dictionary: held against the clip's
    assert table["floor mm"].to_numpy() == pytest.approx(floor, abs=0.1)  # per-frame values kept to 0.1 mm
    assert table.loc[1, "root-aligned mm"] == round(metrics["abis"]["mpjpe_root_aligned_mm"], 1)
    assert table.loc[1, "aligned / floor"] == pytest.approx(metrics["abis"]["mpjpe_root_aligned_mm"] / floor, abs=0.01)
    assert "± " in (reports / "benchmark.md").read_text()
    assert_losses_add_up_frame_by_frame(table, runs, metrics["tbf"]["floor_per_frame_mm"])
    assert "Where each setup loses to the floor" in (reports / "benchmark.md").read_text()
    assert all((run / "fig5.png").exists() and (run / "error_against_floor.png").exists() for run in runs.values())
    assert_scored_where_every_row_saw_the_subject(reports / "benchmark", runs, {f: r["label"] for f, r in rows.items()})
    stamp = (runs["tbf"] / "metrics.json").stat().st_mtime_ns
    main(["--split", str(path), "--reports", str(reports), "--rows", "tbf"])  # finished with the same overrides
    assert (runs["tbf"] / "metrics.json").stat().st_mtime_ns == stamp
    # The same overrides, but a run of a preset that has changed since (as if it had pruned at 0.5): run again.
    recorded = json.loads((runs["tbf"] / "metrics.json").read_text())
    pruned = recorded["config"]["tracker"]["filter"]["prune_fraction"]  # the preset's
    recorded["config"]["tracker"]["filter"]["prune_fraction"] = 0.5
    (runs["tbf"] / "metrics.json").write_text(json.dumps(recorded))
    main(["--split", str(path), "--reports", str(reports), "--rows", "tbf"])
    again = json.loads((runs["tbf"] / "metrics.json").read_text())
    assert again["config"]["tracker"]["filter"]["prune_fraction"] == pruned != 0.5 and again["status"] == "ok"
    main(["--split", str(path), "--reports", str(reports), "--rows", "tbf", "--clips", "validation"])
    validation = pd.read_csv(reports / "benchmark_validation.csv")
    assert list(validation["clip"]) == ["143_33"] and (reports / "benchmark_validation" / "143_33" / "tbf").is_dir()


def assert_losses_add_up_frame_by_frame(table, runs, floor):
    """Each row's excess over the floor, split by the frames it comes from, and the turned or lost frames its own
    cost could not have told from the floor's, as a loop over the frames finds them."""
    for folder, row in zip(runs, table.to_dict("records"), strict=True):
        frames = pd.read_parquet(runs[folder] / "frames.parquet").drop_duplicates("frame")
        flags = json.loads((runs[folder] / "metrics.json").read_text()).get("ambiguous_per_frame")
        split, ambiguous = {"turned mm": 0.0, "lost mm": 0.0, "near mm": 0.0}, 0
        for frame, (aligned, turned_deg, floor_mm) in enumerate(
            zip(frames["joint_error_aligned_mm"], frames["root_orientation_error_deg"], floor, strict=True)
        ):
            kind = "turned" if turned_deg >= 90 else "lost" if aligned > 2 * floor_mm else "near"
            split[f"{kind} mm"] += (aligned - floor_mm) / len(frames)
            ambiguous += kind != "near" and flags is not None and flags[frame]
        for column, mm in split.items():
            assert row[column] == pytest.approx(mm, abs=0.051), (folder, column)
        assert row["ambiguous frames"] == ambiguous if flags is not None else np.isnan(row["ambiguous frames"])
        assert row["excess mm"] == pytest.approx(sum(split.values()), abs=0.051)
        assert row["excess mm"] == pytest.approx(row["root-aligned mm"] - row["floor mm"], abs=0.11)


def assert_scored_where_every_row_saw_the_subject(root, runs, labels):
    """One row's camera losing the subject at frame 1 leaves frame 0 alone scored, for every row."""
    path = runs["abis"] / "frames.parquet"
    frames = pd.read_parquet(path)
    view = next(column for column in frames.columns if column.startswith("in_view_"))
    frames.loc[frames["frame"] == 1, view] = False
    frames.to_parquet(path)
    table = benchmark_table(root, labels)
    assert list(table["scored"]) == [1, 1] and list(table["frames"]) == [2, 2]
    for folder, row in zip(labels, table.to_dict("records"), strict=True):
        first = pd.read_parquet(runs[folder] / "frames.parquet").drop_duplicates("frame").iloc[0]
        assert row["root-aligned mm"] == round(first["joint_error_aligned_mm"], 1)
        assert row["PA-MPJPE mm"] == round(first["joint_error_pa_mm"], 1)
        # the scored frames' time alone
        assert row["estimation ms/frame"] == row["mean ms/frame"] == round(first["estimate_ms"], 1)


@pytest.mark.parametrize("folder", list(yaml.safe_load((SPLITS_DIR / "cmu.yaml").read_text())["rows"]))
def test_every_row_of_the_project_split_is_a_valid_run_of_its_clips(folder):
    """A clip of each skeleton (the DAZ-friendly one at its true rate): the config check reads every clip the
    dictionary names, so each row is checked on two clips, not all."""
    split = load_split("cmu")
    row = split.rows[folder]
    for clip in ("mocap/69_20.bvh", "mocap_daz/salsa_06.bvh"):
        overrides = clip_overrides(split, clip, searches_dictionary(row))
        validate_command_line([f"experiment={row.experiment}", *overrides, *row.overrides], CONFIG_DIR, "config")
