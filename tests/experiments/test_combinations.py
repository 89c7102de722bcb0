"""The plug-board's combinations: every model with every tracker that tracks it (`tracker.compatibility.FITS`), from
the fewest and the most views of the project's rigs for that model, runs 2 frames through the real command line;
and one camera tracks as it did before several views were possible."""

import json

import pandas as pd
import pytest

from experiments.components import build, compose
from tests.conftest import SMALL_ARM_GRID, SMALL_GRID, TBF_RUN, run_cli
from tracker.compatibility import FITS

RIGS_OF_MODEL = {"dsq_arm": ("mono", "orthogonal3"), "body_mesh": ("body_side", "body_multi")}
NEEDS = {"tbf": ("cost=nwxor", "motion=dm2")}
SMALL_SAMPLES = {"body_mesh": tuple(SMALL_GRID), "dsq_arm": (SMALL_ARM_GRID,)}
VIEWS = {rig: len(build(compose([f"rig={rig}"])).cameras) for rigs in RIGS_OF_MODEL.values() for rig in rigs}
COMBINATIONS = [
    (tracker, model, rig)
    for tracker, fits in FITS.items()
    for model, fit in fits.items()
    for rig in RIGS_OF_MODEL[model]
    if fit.allows(VIEWS[rig])
]


@pytest.mark.parametrize(("tracker", "model", "rig"), COMBINATIONS, ids=["-".join(c) for c in COMBINATIONS])
def test_every_allowed_combination_runs_two_frames(tracker, model, rig, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        out,
        f"tracker={tracker}",
        f"model={model}",
        f"rig={rig}",
        "frames=2",
        "record.images=false",
        f"tracker.cache_dir={tmp_path / 'cache'}" if tracker == "tbf" else "seed=0",
        *NEEDS.get(tracker, ()),
        *(SMALL_SAMPLES[model] if tracker == "tbf" else ()),
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics.get("failed_frames", 0) == 0  # render_only estimates nothing
    assert len(metrics["views"]) == VIEWS[rig]
    table = pd.read_parquet(out / "frames.parquet")
    assert sorted(table["frame"].unique()) == [0, 1]


# The 6-frame TBF run of `tests.conftest.tbf_run` (one camera, nwXOR, DM2) as the code before several views were
# possible (commit 7c38db2) tracked it: its estimates exactly, and its error, which was measured on another processor
# (SIMD and BLAS kernels round differently in the last bits), to a relative 1e-12.
ONE_CAMERA_BEFORE = {"est_sample": [16, 19, 22, 21, 24, 27], "mpjpe_mm": 3.673767399436}
MEASURED_ELSEWHERE = {"rel": 1e-12, "abs": 0.0}


def test_one_camera_tracks_as_it_did_before_several_views(tbf_run):
    metrics = json.loads((tbf_run / "metrics.json").read_text())
    table = pd.read_parquet(tbf_run / "frames.parquet").drop_duplicates("frame")
    assert table["est_sample"].tolist() == ONE_CAMERA_BEFORE["est_sample"]
    assert metrics["mpjpe_mm"] == pytest.approx(ONE_CAMERA_BEFORE["mpjpe_mm"], **MEASURED_ELSEWHERE)


def test_a_cameras_rig_of_one_view_is_the_one_camera_rig(tbf_run, tmp_path):
    """rig=body_multi cut to one camera where rig=body_side's stands tracks exactly as rig=body_side."""
    out = tmp_path / "out"
    result = run_cli(
        out,
        *TBF_RUN,
        "rig=body_multi",
        "rig.views=[{name:main,position:[4.0,0.0,0.9]}]",
        "rig.focal_px=480",
        f"tracker.cache_dir={tmp_path / 'cache'}",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    before, after = (pd.read_parquet(run / "frames.parquet") for run in (tbf_run, out))
    for column in ("est_sample", "entropy", "nodes_level3"):
        assert before[column].tolist() == after[column].tolist(), column
    one_camera, one_view = (json.loads((run / "metrics.json").read_text())["mpjpe_mm"] for run in (tbf_run, out))
    assert one_view == one_camera  # both measured here: to the last bit


def test_a_fit_that_names_a_rig_picks_it_unless_the_command_line_names_one(monkeypatch):
    """As model=body_mesh picks rig=body_side, a tracker that needs more views of a model picks its rig; a rig
    named on the command line stays, and then fails at start saying which to add."""
    from experiments.checks import ConfigError
    from experiments.schemas import CONFIG_DIR
    from experiments.validate import validate_command_line, with_picks
    from tracker.compatibility import Fit

    monkeypatch.setitem(FITS["render_only"], "body_mesh", Fit((3, 4), rig="body_multi"))
    argv = ["model=body_mesh", "frames=2"]
    assert with_picks(argv, CONFIG_DIR, "config") == [*argv, "rig=body_multi"]
    validate_command_line([*argv, "rig=body_multi"], CONFIG_DIR, "config")
    named = [*argv, "rig=body_side"]
    assert with_picks(named, CONFIG_DIR, "config") == named
    with pytest.raises(
        ConfigError,
        match=r"^tracker=render_only tracks model=body_mesh from 3 to 4 camera views: "
        r"rig=body_side has 1; add rig=body_multi$",
    ):
        validate_command_line(named, CONFIG_DIR, "config")
    assert with_picks(["model=dsq_arm"], CONFIG_DIR, "config") == ["model=dsq_arm"]  # its rig fits already


def test_the_body_by_abis_picks_its_rig_and_a_textured_skin_unless_the_command_line_names_them():
    from experiments.schemas import CONFIG_DIR
    from experiments.validate import with_picks

    argv = ["model=body_mesh", "tracker=abis"]
    assert with_picks(argv, CONFIG_DIR, "config") == [*argv, "model.texture_seed=0", "rig=body_multi_vga"]
    named = [*argv, "rig=body_multi", "model.texture_seed=7"]
    assert with_picks(named, CONFIG_DIR, "config") == named


def test_a_tracker_fails_at_start_on_a_model_its_fits_leave_out(monkeypatch):
    from experiments.checks import ConfigError
    from experiments.schemas import CONFIG_DIR
    from experiments.validate import validate_command_line

    monkeypatch.setitem(FITS, "abis", {"dsq_arm": FITS["abis"]["dsq_arm"]})
    with pytest.raises(ConfigError, match=r"^tracker=abis does not track model=body_mesh: allowed model=dsq_arm$"):
        validate_command_line(["model=body_mesh", "tracker=abis", "rig=body_multi"], CONFIG_DIR, "config")
