"""A full disk never hangs a run nor leaves half-written outputs: a folder with too little space stops the run at
start (exit 2, one line); a disk that fills during the run ends it with one line naming the folder and the error
(exit 1), the temporary files removed. Each disk is a small tmpfs, mounted where the tests run as root."""

import subprocess
import sys
import time

import pytest

from experiments.validate import MIN_FREE_BYTES


@pytest.fixture
def small_disk(tmp_path, request):
    """A tmpfs of ``request.param`` bytes under ``tmp_path``, unmounted afterwards."""
    mount = tmp_path / "disk"
    mount.mkdir()
    made = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={request.param}", "tmpfs", str(mount)], capture_output=True
    )
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (root only): {made.stderr.decode().strip()}")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


def run_command(run_dir, *overrides):
    return [sys.executable, "-m", "experiments.run", "model=dsq_arm", f"hydra.run.dir={run_dir}", *overrides]


@pytest.mark.parametrize("small_disk", [300 << 10], indirect=True)
def test_a_folder_on_a_nearly_full_disk_stops_the_run_at_start(small_disk):
    result = subprocess.run(run_command(small_disk / "run", "frames=3"), capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert result.stderr.startswith(f"error: hydra.run.dir={small_disk / 'run'}: {small_disk} has 0.3 MiB free")
    assert f"at least {MIN_FREE_BYTES >> 20} MiB" in result.stderr and list(small_disk.iterdir()) == []


@pytest.mark.parametrize("small_disk", [MIN_FREE_BYTES + (8 << 20)], indirect=True)
def test_a_disk_that_fills_during_the_run_ends_it_with_one_line_and_nothing_half_written(small_disk):
    run_dir = small_disk / "run"
    run = subprocess.Popen(
        run_command(run_dir, "frames=300"), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    deadline = time.monotonic() + 120
    while not list(run_dir.glob(".run.rrd.*.tmp")) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(2)  # a few frames in
    with open(small_disk / "filler", "wb") as filler:  # another program takes what is left
        try:
            while True:
                filler.write(bytes(1 << 20))
        except OSError:
            pass
    errors, _ = run.communicate(timeout=300)  # the log's lines (Hydra logs to stdout) and anything else
    assert run.returncode == 1, errors
    lines = errors.strip().splitlines()
    assert all("[ERROR]" in line for line in lines) and len(lines) <= 2, errors  # no traceback, no Rerun noise
    assert f"{run_dir}: the run's outputs could not be written" in lines[-1] and "No space left" in lines[-1]
    assert not list(run_dir.glob(".*.tmp")) and not (run_dir / "metrics.json").exists()
