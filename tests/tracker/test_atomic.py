import json
import multiprocessing
import time

import pandas as pd
import pytest

from tracker.atomic import AtomicFile, atomic_path, exclusive, write_json, write_parquet


def test_json_and_parquet_round_trip(tmp_path):
    write_json(tmp_path / "m.json", {"b": 1, "a": [1.5]})
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": [1.5], "b": 1}
    frame = pd.DataFrame({"frame": [0, 1], "x": [0.5, 1.5]})
    write_parquet(tmp_path / "f.parquet", frame)
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "f.parquet"), frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.parquet", "m.json"]


def test_a_failed_write_leaves_the_previous_file_and_no_temporary(tmp_path):
    target = tmp_path / "m.json"
    write_json(target, {"complete": True})
    with pytest.raises(ValueError):
        write_json(target, {"bad": float("nan")})  # refused mid-write
    assert json.loads(target.read_text()) == {"complete": True}
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("killed")
    assert json.loads(target.read_text()) == {"complete": True}
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"]


def test_uncommitted_file_never_appears_under_its_name(tmp_path):
    file = AtomicFile(tmp_path / "run.rrd")
    file.temporary.write_bytes(b"partial")
    assert not (tmp_path / "run.rrd").exists()
    file.commit()
    assert (tmp_path / "run.rrd").read_bytes() == b"partial"
    assert (tmp_path / "run.rrd").stat().st_mode & 0o044  # readable by others, like any output


def _hold_lock(lock_path, log_path, name):
    with exclusive(lock_path):
        with open(log_path, "a") as log:
            log.write(f"{name} in {time.monotonic()}\n")
        time.sleep(0.3)
        with open(log_path, "a") as log:
            log.write(f"{name} out {time.monotonic()}\n")


def test_exclusive_lets_parallel_processes_take_turns(tmp_path):
    context = multiprocessing.get_context("spawn")
    workers = [context.Process(target=_hold_lock, args=(tmp_path / "x.lock", tmp_path / "log", n)) for n in "ab"]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=30)
        assert worker.exitcode == 0
    events = [line.split() for line in (tmp_path / "log").read_text().splitlines()]
    assert [event[1] for event in events] == ["in", "out", "in", "out"]  # never both inside
    assert events[0][0] == events[1][0] and events[2][0] == events[3][0]
