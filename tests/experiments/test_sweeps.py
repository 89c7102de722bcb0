"""Sweeps through the real Hydra CLI: the joblib launcher, the sweep table, and resuming an interrupted sweep."""

import json
import subprocess
import sys

import pytest

from eval.runs import collect
from eval.tables import sweep_table

SWEEP = ["frames=2", "record.images=false", "seed=0,1", "rig=orthogonal3,mono"]


def run_sweep(sweep_dir, *overrides, cwd):
    command = [sys.executable, "-m", "experiments.run", "-m", f"hydra.sweep.dir={sweep_dir}", *overrides]
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=600)


def test_a_2x2_sweep_runs_on_joblib_tabulates_by_choice_and_resumes_only_what_is_missing(tmp_path):
    sweep_dir = tmp_path / "sweep"
    result = run_sweep(sweep_dir, *SWEEP, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Joblib" in (sweep_dir / "multirun.yaml").read_text()  # the launcher the sweep ran on
    jobs = sorted(sweep_dir.glob("*/metrics.json"))
    assert len(jobs) == 4 and all(json.loads(p.read_text())["status"] == "ok" for p in jobs)

    table = sweep_table(collect([sweep_dir]))
    assert sorted(table["rig"]) == ["mono", "orthogonal3"]
    assert list(table["runs"]) == [2, 2] and list(table["seeds"]) == ["0,1", "0,1"]

    # An interrupted sweep: one job's metrics are gone (as if it was killed), and a killed job's temporary file
    # is left over. Re-running the same command redoes that job only.
    lost, kept = jobs[1], [p for p in jobs if p != jobs[1]]
    lost.unlink()
    (lost.parent / ".run.rrd.x1y2z3.tmp").write_bytes(b"half a recording")
    stamps = {p: p.stat().st_mtime_ns for p in kept}
    result = run_sweep(sweep_dir, *SWEEP, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads(lost.read_text())["status"] == "ok"
    assert {p: p.stat().st_mtime_ns for p in kept} == stamps  # finished jobs were not recomputed
    assert not list(sweep_dir.glob("*/.*.tmp"))


def test_a_job_with_a_changed_config_is_not_taken_for_finished(tmp_path):
    sweep_dir = tmp_path / "sweep"
    assert run_sweep(sweep_dir, "frames=2", "record.images=false", cwd=tmp_path).returncode == 0
    first = (sweep_dir / "0" / "metrics.json").read_text()
    result = run_sweep(sweep_dir, "frames=3", "record.images=false", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    again = json.loads((sweep_dir / "0" / "metrics.json").read_text())
    assert json.loads(first)["frames"] == 2 and again["frames"] == 3


def test_the_launcher_is_a_choice_on_the_command_line(tmp_path):
    sweep_dir = tmp_path / "sweep"
    result = run_sweep(sweep_dir, "hydra/launcher=basic", "frames=1", "record.images=false", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Joblib" not in (sweep_dir / "multirun.yaml").read_text()
    assert json.loads((sweep_dir / "0" / "metrics.json").read_text())["status"] == "ok"


@pytest.mark.slow
def test_the_same_sweep_on_ray_gives_the_same_metrics_as_on_joblib(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason="the Ray launcher is an extra: make ray")
    sweep = ["frames=2", "record.images=false", "seed=0,1", "tracker=abis"]
    for launcher in ("joblib", "ray"):
        result = run_sweep(tmp_path / launcher, *sweep, f"hydra/launcher={launcher}", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    for job in ("0", "1"):
        joblib_metrics = (tmp_path / "joblib" / job / "metrics.json").read_bytes()
        assert (tmp_path / "ray" / job / "metrics.json").read_bytes() == joblib_metrics
