"""Slow results kept on disk between processes: computed once per key, read back the same, computed again when
the file is damaged, and a key that changes with the inputs and with the core's own code."""

import numpy as np

from tracker import memo


def test_a_result_is_computed_once_and_read_back_to_the_bit(tmp_path):
    calls = []

    def compute():
        calls.append(1)
        return {"values": np.random.default_rng(0).normal(size=(4, 3)), "counts": np.arange(5)}

    first = memo.memoized(tmp_path, {"what": "a test", "n": 4}, compute)
    again = memo.memoized(tmp_path, {"n": 4, "what": "a test"}, compute)  # the same inputs, in another order
    assert len(calls) == 1
    for name in first:
        np.testing.assert_array_equal(first[name], again[name])
        assert first[name].dtype == again[name].dtype
    memo.memoized(tmp_path, {"what": "a test", "n": 5}, compute)
    assert len(calls) == 2  # other inputs, another key


def test_a_damaged_file_is_computed_again(tmp_path, caplog):
    memo.memoized(tmp_path, "damaged", lambda: {"x": np.ones(3)})
    (path,) = tmp_path.glob("*.npz")
    path.write_bytes(path.read_bytes()[:40])
    assert memo.memoized(tmp_path, "damaged", lambda: {"x": np.zeros(3)})["x"].tolist() == [0.0, 0.0, 0.0]
    assert "cannot be read" in caplog.text


def test_the_key_names_the_cores_code(monkeypatch):
    key = memo.memo_key("inputs")
    monkeypatch.setattr(memo, "source_digest", lambda: "another version of the code")
    assert memo.memo_key("inputs") != key


def test_cached_sample_poses_are_the_poses_themselves(body, tmp_path):
    from tracker.tbf.sample_spec import SampleSpec, cached_sample_poses, sample_poses

    spec = SampleSpec()
    fresh = sample_poses(spec, body)
    for _ in range(2):  # made, then read back
        cached = cached_sample_poses(spec, body, tmp_path)
        for a, b in zip(fresh, cached, strict=True):
            np.testing.assert_array_equal(a, b)


def test_cached_joint_positions_are_the_bodys_own_and_the_floor_is_the_same_from_them(body, tmp_path):
    """A dictionary's joint positions kept between runs (`cached_joint_positions`) are the body's to the bit, made
    and then read back, under a key of the poses (other poses, another file); the 3-D floor found from them is the
    one found computing them."""
    from tracker.evaluation.body import nearest_in_3d
    from tracker.tbf.sample_spec import SampleSpec, cached_joint_positions, sample_poses

    poses, _ = sample_poses(SampleSpec(), body)
    fresh = body.joint_positions(poses)
    for _ in range(2):  # made, then read back
        assert cached_joint_positions(body, poses, tmp_path).tobytes() == fresh.tobytes()
    assert len(list(tmp_path.glob("*.npz"))) == 1
    assert cached_joint_positions(body, poses[::2], tmp_path).tobytes() == fresh[::2].tobytes()
    assert len(list(tmp_path.glob("*.npz"))) == 2
    truths = poses[[3, 0, len(poses) - 1]] + np.r_[0.3, -0.2, 0.0, 0.05 * np.ones(poses.shape[1] - 3)]
    computed = nearest_in_3d(body, truths, body, poses)
    given = nearest_in_3d(body, truths, body, poses, cached_joint_positions(body, poses, tmp_path))
    for a, b in zip(computed, given, strict=True):
        assert a.tobytes() == b.tobytes()
