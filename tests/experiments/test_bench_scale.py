"""The scaling benchmark's parts: its turns, the peak memory of a process tree, the fitted exponent; and the whole
of it on two tiny dictionaries (slow)."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from experiments.bench.scale import PeakMemory, exponents, turns_deg


def test_turns_are_evenly_spaced_and_the_presets_four_come_first():
    assert turns_deg(4) == [0.0, 90.0, 180.0, -90.0]  # tbf_paper_scale's clip_turns_deg
    eight = np.array(turns_deg(8))
    assert np.allclose(np.sort(np.mod(eight, 360)), np.arange(8) * 45.0) and np.all((eight > -180) & (eight <= 180))


def test_the_peak_memory_counts_a_childs_allocation():
    allocate = "import time; block = bytearray(400 * 2**20); block[::4096] = b'x' * len(block[::4096]); time.sleep(1.5)"
    parent = subprocess.Popen(
        [sys.executable, "-c", f"import subprocess, sys; subprocess.run([sys.executable, '-c', {allocate!r}])"]
    )
    memory = PeakMemory(parent.pid)
    parent.wait()
    resident, anonymous = memory.close()
    assert 400 / 1024 < anonymous <= resident < 2.0  # the grandchild's 400 MiB, plus two interpreters


def test_the_exponent_is_the_slope_in_log_log():
    samples = np.array([1000, 2000, 4000, 8000])
    table = pd.DataFrame({"experiment": "a", "samples": samples, "ms_per_frame": 3.0 * samples**0.5})
    assert exponents(table)["a"] == pytest.approx(0.5)
    assert np.isnan(exponents(table.iloc[:1])["a"])


@pytest.mark.slow
def test_the_scaling_benchmark_on_two_tiny_dictionaries(tmp_path):
    command = [sys.executable, "-m", "experiments.bench", "scale", "--turns=1,2", "--experiments=tbf_paper_scale"]
    command += [
        "--frames=2",
        "tracker.samples.clips=[mocap_daz/martial_04.bvh]",
        "tracker.samples.clip_fps=3",
        "--json",
    ]
    ended = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=900, check=True)
    rows = json.loads(ended.stdout.strip().splitlines()[-1])["figures"]["rows"]
    assert [row["turns"] for row in rows] == [1, 2]
    assert 1.5 < rows[1]["samples"] / rows[0]["samples"] <= 2.0  # twice the turns: about twice the samples
    assert all(row["disk_gib"] > 0 and row["build_peak_gib"] > 0 and row["ms_per_frame"] > 0 for row in rows)
    assert (tmp_path / "reports" / "scale.md").exists() and not list((tmp_path / ".cache").iterdir())
