"""Ctrl-C and SIGTERM end a run with one line and nothing lost: sent to the whole process group (as a terminal does)
while a sample set is built on worker processes, the workers stay silent, the run's outputs say it was interrupted,
the shards built so far stay for the next run to resume from (`tests/tracker/tbf/test_samples.py`), and the exit
status is the signal's; a benchmark passes a stop on to its run (or measuring process) under way and waits for it."""

import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import pytest
import yaml


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_an_interrupt_during_a_sample_build_ends_the_run_with_one_line(tmp_path, signal_name):
    cache, run_dir = tmp_path / "cache", tmp_path / "run"
    command = [
        sys.executable,
        "-m",
        "experiments.run",
        "experiment=tbf_table4c",
        "frames=2",
        f"tracker.cache_dir={cache}",
        "tracker.build.jobs=2",
        "tracker.build.shard_size=64",
        f"hydra.run.dir={run_dir}",
    ]
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    deadline = time.monotonic() + 240
    while not list(cache.glob("samples/.*.building/shard*")) and time.monotonic() < deadline and run.poll() is None:
        time.sleep(0.2)
    assert run.poll() is None, "the build ended before a shard was seen"
    os.killpg(run.pid, getattr(signal, signal_name))  # the group: the run and its workers
    output, _ = run.communicate(timeout=120)
    assert run.returncode == 128 + getattr(signal, signal_name), output
    assert "Traceback" not in output and output.strip().splitlines()[-1] == f"interrupted by {signal_name}", output
    assert len(output.strip().splitlines()) <= 2, output  # the run's warning, and the line that says why it ended
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["status"] == f"failed: interrupted by {signal_name}"
    assert list(cache.glob("samples/.*.building/shard*")), "the finished shards are kept for the next run"


def sweep_command(sweep_dir):
    """A sweep of three 100-frame jobs (two at a time, on joblib's workers) into ``sweep_dir``."""
    command = [sys.executable, "-m", "experiments.run", "-m", "model=dsq_arm", "frames=100", "seed=0,1,2"]
    return [*command, f"hydra.sweep.dir={sweep_dir}"]


def start_sweep(sweep_dir):
    return subprocess.Popen(
        sweep_command(sweep_dir), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )


def wait_until(sweep, ready):
    deadline = time.monotonic() + 240
    while not ready() and time.monotonic() < deadline and sweep.poll() is None:
        time.sleep(0.02)
    assert sweep.poll() is None, "the sweep ended before it was stopped"


def ended_by(sweep, sweep_dir, signal_name):
    """The stopped sweep's jobs' metrics, once it ended as a stopped command ends: one line, 128 + the signal."""
    output, _ = sweep.communicate(timeout=120)
    assert sweep.returncode == 128 + getattr(signal, signal_name) and "Traceback" not in output, output
    assert output.strip().splitlines()[-1] == f"interrupted by {signal_name}", output
    return {job.parent.name: json.loads(job.read_text()) for job in sweep_dir.glob("*/metrics.json")}


def test_an_interrupted_sweep_marks_its_running_jobs_and_resumes_with_the_rest(tmp_path):
    sweep_dir = tmp_path / "sweep"
    command, sweep = sweep_command(sweep_dir), start_sweep(sweep_dir)
    wait_until(sweep, lambda: list(sweep_dir.glob("*/.run.rrd.*.tmp")))
    time.sleep(1)
    os.killpg(sweep.pid, signal.SIGINT)
    statuses = {name: job["status"] for name, job in ended_by(sweep, sweep_dir, "SIGINT").items()}
    assert set(statuses.values()) <= {"ok", "failed: interrupted by SIGINT"}, statuses
    assert "failed: interrupted by SIGINT" in statuses.values(), statuses  # the running jobs said so
    finished = {
        name: (sweep_dir / name / "metrics.json").stat().st_mtime_ns for name, s in statuses.items() if s == "ok"
    }
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    statuses = {job.parent.name: json.loads(job.read_text())["status"] for job in sweep_dir.glob("*/metrics.json")}
    assert statuses == {"0": "ok", "1": "ok", "2": "ok"}
    assert all((sweep_dir / name / "metrics.json").stat().st_mtime_ns == stamp for name, stamp in finished.items())


def test_a_sigterm_to_the_sweep_alone_stops_its_running_jobs_after_their_frame(tmp_path):
    """A scheduler's ``kill <pid>`` reaches the sweep's process, not its workers: the jobs hear of it all the same
    (`experiments.stopping.SweepStop`), write their outputs marked interrupted, and no queued job starts."""
    sweep_dir = tmp_path / "sweep"
    sweep = start_sweep(sweep_dir)
    wait_until(sweep, lambda: list(sweep_dir.glob("*/.run.rrd.*.tmp")))
    os.kill(sweep.pid, signal.SIGTERM)
    jobs = ended_by(sweep, sweep_dir, "SIGTERM")
    stopped = [job for job in jobs.values() if job["status"] == "failed: interrupted by SIGTERM"]
    assert stopped and all(job["frames_done"] < 100 for job in stopped) and "2" not in jobs, jobs
    assert not list(Path(tempfile.gettempdir()).glob(f"articulated-tracking-sweep-{sweep.pid}.stop"))


def test_a_ctrl_c_as_the_sweeps_workers_start_their_jobs_ends_it_with_one_line(tmp_path):
    """Both workers have just started a job (the jobs' folders are made by them) and are still building it when the
    terminal's Ctrl-C reaches the whole group: neither breaks joblib's pool with a traceback, each writes its outputs
    marked interrupted, and the job queued behind them does not start."""
    sweep_dir = tmp_path / "sweep"
    sweep = start_sweep(sweep_dir)
    wait_until(sweep, lambda: len(list(sweep_dir.glob("*/.hydra"))) >= 2)
    os.killpg(sweep.pid, signal.SIGINT)
    statuses = {name: job["status"] for name, job in ended_by(sweep, sweep_dir, "SIGINT").items()}
    assert set(statuses.values()) <= {"failed: interrupted by SIGINT"} and "2" not in statuses, statuses
    assert not list(sweep_dir.glob("*/.*.tmp"))  # no job was ended while it wrote its outputs


@pytest.mark.slow
def test_a_sweep_killed_at_ten_random_points_loses_nothing_and_does_nothing_twice(tmp_path):
    sweep_dir = tmp_path / "sweep"
    command = [sys.executable, "-m", "experiments.run", "-m", "model=dsq_arm", "frames=40", "seed=0,1,2,3,4,5"]
    command.append(f"hydra.sweep.dir={sweep_dir}")
    rng = random.Random(0)
    finished: dict[str, int] = {}  # job -> its metrics.json's mtime when first seen finished
    for _ in range(10):
        sweep = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        time.sleep(rng.uniform(0.5, 12.0))
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)  # no handler runs: the outputs are what the atomic writes left
        sweep.wait()
        for path in sweep_dir.glob("*/metrics.json"):
            metrics = json.loads(path.read_text())  # never half-written: it parses
            if metrics["status"] == "ok":
                assert finished.setdefault(path.parent.name, path.stat().st_mtime_ns) == path.stat().st_mtime_ns
        assert not list(sweep_dir.glob("*/run.rrd")) or all(p.stat().st_size > 0 for p in sweep_dir.glob("*/run.rrd"))
    completed = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert completed.returncode == 0, completed.stderr
    statuses = {path.parent.name: json.loads(path.read_text())["status"] for path in sweep_dir.glob("*/metrics.json")}
    assert statuses == {str(job): "ok" for job in range(6)}
    assert all((sweep_dir / job / "metrics.json").stat().st_mtime_ns == stamp for job, stamp in finished.items())


@pytest.mark.parametrize("to_group", [False, True], ids=["SIGTERM to the benchmark", "Ctrl-C to its group"])
def test_a_stopped_benchmark_stops_its_run_under_way_and_waits_for_its_outputs(tmp_path, to_group):
    """A scheduler's or a user's ``kill`` reaches the benchmark alone, a terminal's Ctrl-C its whole group: either
    way the run under way stops after its frame and writes its outputs, marked interrupted, before the benchmark
    ends with one line (not left running on its own, not killed before its outputs)."""
    split = tmp_path / "split.yaml"
    rows = {"abis": {"label": "AbIS", "experiment": "abis_body", "overrides": ["rig=body_multi"]}}
    entries = {"dictionary": ["mocap_daz/martial_04.bvh"], "test": ["mocap/69_20.bvh"]}  # 69 frames
    split.write_text(yaml.safe_dump({**entries, "rows": rows}, sort_keys=False))
    reports, run_dir = tmp_path / "reports", tmp_path / "reports" / "benchmark" / "69_20" / "abis"
    command = [sys.executable, "-m", "experiments.benchmark", "--split", str(split), "--reports", str(reports)]
    benchmark = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    deadline = time.monotonic() + 240
    while not list(run_dir.glob(".run.rrd.*.tmp")) and time.monotonic() < deadline and benchmark.poll() is None:
        time.sleep(0.2)
    time.sleep(2.0)  # its frames under way (on a loaded machine, maybe still its first)
    stop = signal.SIGINT if to_group else signal.SIGTERM
    if to_group:
        os.killpg(benchmark.pid, stop)
    else:
        benchmark.send_signal(stop)
    output, _ = benchmark.communicate(timeout=120)
    assert benchmark.returncode == 128 + stop, output
    assert "Traceback" not in output and output.strip().splitlines()[-1] == f"interrupted by {stop.name}", output
    metrics = json.loads((run_dir / "metrics.json").read_text())  # written before the benchmark ended
    assert metrics["status"] == f"failed: interrupted by {stop.name}" and metrics["frames_done"] < 69
    assert not (reports / "benchmark.md").exists()  # no table of a benchmark cut short


def test_a_stopped_scaling_benchmark_stops_its_measuring_process_and_leaves_no_cache(tmp_path):
    """``kill`` of ``python -m experiments.bench scale`` (or of ``make reproduce`` in its scaling step) while a cell
    builds its dictionary: the cell's process and its build workers end with it, and its fresh cache is removed."""
    command = [sys.executable, "-m", "experiments.bench", "scale", "--experiments", "tbf_table4c", "--turns", "1"]
    bench = subprocess.Popen(
        [*command, "--frames", "2"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not psutil.Process(bench.pid).children() and time.monotonic() < deadline and bench.poll() is None:
        time.sleep(0.1)
    time.sleep(2.0)  # the cell is building its dictionary
    measuring = psutil.Process(bench.pid).children(recursive=True)
    assert measuring, "no measuring process was seen"
    bench.send_signal(signal.SIGTERM)  # to the benchmark alone
    output, _ = bench.communicate(timeout=120)
    assert bench.returncode == 128 + signal.SIGTERM, output
    assert "Traceback" not in output and output.strip().splitlines()[-1] == "interrupted by SIGTERM", output
    assert not [process for process in measuring if process.is_running()], "a measuring process was left running"
    assert not list((tmp_path / ".cache").glob("scale_*")) and not (tmp_path / "reports").exists()
