"""The benchmarks' one JSON line (``--json``): the last line of standard output, the figures the log gave."""

import json
import subprocess
import sys

import pytest


def test_a_benchmark_ends_with_one_json_line_of_its_figures(tmp_path):
    command = [sys.executable, "-m", "experiments.bench", "render", "--frames", "3", "--size", "160x120", "--json"]
    ended = subprocess.run(command, capture_output=True, text=True, timeout=300, cwd=tmp_path, check=True)
    record = json.loads(ended.stdout.strip().splitlines()[-1])
    figures = record["figures"]
    assert record["target"] == "render" and record["machine"]["cores"] >= 1
    assert figures["views"] == 3  # the default rig: three orthogonal cameras
    assert figures["render_ms_per_view"] * 3 == pytest.approx(figures["render_ms_per_frame"])
    assert f"{figures['render_ms_per_frame']:7.2f} ms/frame" in ended.stderr  # the figure the log reported
