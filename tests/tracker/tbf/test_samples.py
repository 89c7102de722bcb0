import logging

import numpy as np
import pytest

from tracker.geometry.rigs import mono
from tracker.models.body_skeleton import joint_angle_differences
from tracker.motion.body_swing import BodySwing
from tracker.tbf import sample_store
from tracker.tbf.build_workers import BuildSettings
from tracker.tbf.pose_sets import remove_near_duplicates
from tracker.tbf.sample_build import load_or_build
from tracker.tbf.samples import RESOLUTIONS, cache_key, occlusion_flags, reduce_labels

CAMERA = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=480.0, width=320, height=240)[0]


@pytest.fixture(scope="module")
def swing_poses(body):
    swing = BodySwing(period_frames=100)
    return np.array([swing.params(body, frame) for frame in range(100)])  # 2 degrees apart


def test_duplicates_removal_keeps_no_pair_within_5_degrees_in_every_joint(swing_poses):
    rng = np.random.default_rng(0)
    poses = np.concatenate([swing_poses, swing_poses[rng.integers(0, 100, 30)]])  # exact repeats too
    poses[:, 3:] += rng.normal(0, 0.01, poses[:, 3:].shape)
    kept = remove_near_duplicates(poses, 5.0)
    differences = joint_angle_differences(poses[kept][:, None], poses[kept][None])  # (k, k, J)
    close = (differences <= 5.0).all(axis=2) & ~np.eye(len(kept), dtype=bool)
    assert not close.any()
    dropped = np.setdiff1d(np.arange(len(poses)), kept)
    nearest = joint_angle_differences(poses[dropped][:, None], poses[kept][None]).max(axis=2).min(axis=1)
    assert (nearest <= 5.0).all()  # everything dropped has a kept pose within 5 degrees in every joint
    assert 8 <= len(kept) <= 40  # a 200-degree path of the arm in steps of a little over 5 degrees


def test_joint_angles_by_hand(body):
    a = body.rest_pose()
    b = a.copy()
    b[3 + 3 * 5 : 6 + 3 * 5] = [0.0, np.radians(7.0), 0.0]
    differences = joint_angle_differences(a, b)
    assert differences[5] == pytest.approx(7.0) and np.delete(differences, 5).max() == 0.0


def test_a_sample_set_is_rendered_cached_and_reloaded(body, swing_poses, tmp_path):
    poses = swing_poses[::10]
    built = load_or_build(body, CAMERA, poses, tmp_path, progress=False)
    assert len(built) == 10
    full = built.silhouettes(RESOLUTIONS[0]).masks()
    np.testing.assert_array_equal(built.areas.sum(axis=1), full.sum(axis=(1, 2)))  # the parts' areas fill it
    u0, v0, u1, v1 = built.windows[(80, 60)]
    coarse = built.silhouettes((80, 60)).masks()
    assert coarse.shape == (10, v1 - v0, u1 - u0)
    np.testing.assert_allclose(coarse.sum(axis=(1, 2)) * 16, full.sum(axis=(1, 2)), rtol=0.12)  # 1/16 the pixels
    right_arm = list(body.part_names).index("right_upper_arm")
    assert built.occluded(50)[0, right_arm]  # arm down: behind the torso, side-on
    assert not built.occluded(50)[3, right_arm]  # swung 60 degrees forward: in view
    again = load_or_build(body, CAMERA, poses, tmp_path, progress=False)
    assert again.key == built.key
    np.testing.assert_array_equal(again.silhouettes((160, 120)).masks(), built.silhouettes((160, 120)).masks())
    # each level's runs stored in 2 bytes a pixel index (its window holds fewer than 65,536 pixels)
    assert all(runs.starts.dtype == runs.ends.dtype == np.uint16 for runs in again.runs.values())


def test_a_corrupt_cache_is_rebuilt_not_used(body, swing_poses, tmp_path, caplog):
    poses = swing_poses[:3]
    built = load_or_build(body, CAMERA, poses, tmp_path, progress=False)
    original = built.silhouettes((160, 120)).masks()  # decoded: a copy of what the loaded arrays map
    array = tmp_path / built.key / "runs_160x120_starts.npy"
    data = bytearray(array.read_bytes())
    data[-1] ^= 0xFF  # one flipped byte
    array.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING):
        again = load_or_build(body, CAMERA, poses, tmp_path, progress=False)
    assert "does not match its checksum" in caplog.text and "rebuilding" in caplog.text
    np.testing.assert_array_equal(again.silhouettes((160, 120)).masks(), original)
    (tmp_path / built.key / "areas.npy").write_bytes(b"truncated")
    assert load_or_build(body, CAMERA, poses, tmp_path, progress=False).areas.shape == (3, 15)


def test_the_cache_key_changes_with_the_camera_the_poses_and_the_resolutions(body, swing_poses):
    key = cache_key(body, CAMERA, swing_poses)
    moved = mono(position=(4.0, 0.1, 0.9), target=(0.0, 0.0, 0.9), focal_px=480.0, width=320, height=240)[0]
    zoomed = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=481.0, width=320, height=240)[0]
    others = {
        cache_key(body, moved, swing_poses),
        cache_key(body, zoomed, swing_poses),
        cache_key(body, CAMERA, swing_poses[1:]),
        cache_key(body, CAMERA, swing_poses, RESOLUTIONS[:2]),
    }
    assert key not in others and len(others) == 4
    assert cache_key(body, CAMERA, swing_poses.copy()) == key


def test_occlusion_flags_are_eq_3():
    areas = np.array([[0, 49, 50, 500]])
    np.testing.assert_array_equal(occlusion_flags(areas, 50), [[True, True, False, False]])
    with pytest.raises(ValueError, match="T_A=-1"):
        occlusion_flags(areas, -1)


def test_label_reduction_by_hand():
    labels = np.array([[1, 1, 0, 0, 2, 2], [1, 2, 0, 3, 2, 0], [0, 0, 3, 3, 0, 0], [0, 1, 3, 0, 0, 0]], np.uint8)
    # Blocks of 2x2: {1,1,1,2} -> 1; {0,0,0,3} -> background (1 of 4 covered); {2,2,2,0} -> 2;
    # {0,0,0,1} -> 0; {3,3,3,0} -> 3; {0,0,0,0} -> 0.
    np.testing.assert_array_equal(reduce_labels(labels, 2, 3), [[1, 0, 2], [0, 3, 0]])
    np.testing.assert_array_equal(reduce_labels(np.array([[1, 2], [0, 0]], np.uint8), 2, 2), [[1]])  # tie: lower


def test_duplicate_removal_equals_the_naive_greedy_pass(swing_poses):
    rng = np.random.default_rng(3)
    poses = np.repeat(swing_poses[::7], 12, axis=0)
    poses[:, 3:] += rng.normal(0, 0.03, poses[:, 3:].shape)  # clusters of near-duplicates, 1.7 degrees apart
    kept = []
    for index in range(len(poses)):  # naive: compare with every kept pose
        if not any((joint_angle_differences(poses[index], poses[k]) <= 5.0).all() for k in kept):
            kept.append(index)
    np.testing.assert_array_equal(remove_near_duplicates(poses, 5.0), kept)


@pytest.fixture(scope="module")
def varied_poses(body):
    """300 poses: both arms over a grid, turned a little, so parts hide and show at every resolution."""
    from tracker.tbf.pose_sets import arm_grid

    rng = np.random.default_rng(1)
    poses = arm_grid(body, np.arange(-60.0, 121.0, 10.0), [0.0, 20.0, 40.0], [0.0, 45.0, 90.0], [0.0, 40.0])
    poses[:, 5] += rng.normal(0.0, 0.3, len(poses))  # the body's yaw
    return poses[rng.choice(len(poses), 300, replace=False)]


def build_labels(body, poses, tmp_path):
    """The build's part-label images of ``poses`` at every resolution (`sample_build.shard_labels`), on the layout
    a build of them computes, and their part areas."""
    from tracker.tbf import sample_build

    shards = [slice(0, len(poses))]
    layout = sample_build._layout(tmp_path, body, CAMERA, poses, shards, 4, BuildSettings(jobs=1))
    return sample_build.shard_labels(body, CAMERA, poses, layout, [1, 2, 4])


def test_batched_label_images_equal_the_per_part_render_at_every_level(body, varied_poses, renderer, tmp_path):
    built = load_or_build(body, CAMERA, varied_poses, tmp_path, progress=False)
    labels, areas = build_labels(body, varied_poses, tmp_path / "layout")
    np.testing.assert_array_equal(areas, built.areas)
    u0, v0, u1, v1 = built.windows[RESOLUTIONS[0]]
    reference = np.array(
        [renderer.render_depth_labels([CAMERA], body.surface_meshes(pose))["main"].labels for pose in varied_poses]
    )[:, v0:v1, u0:u1]
    for factor, resolution in zip((1, 2, 4), RESOLUTIONS, strict=True):
        expected = reduce_labels(reference, factor, 15)
        for part in range(1, 16):
            ours, theirs = labels[resolution] == part, expected == part
            union = (ours | theirs).sum()
            if union:
                assert (ours & theirs).sum() / union >= 0.99, (resolution, part)


def test_a_sharded_parallel_build_equals_a_serial_one(body, varied_poses, tmp_path):
    poses = varied_poses[:120]
    serial = load_or_build(body, CAMERA, poses, tmp_path / "serial", progress=False, build=BuildSettings(jobs=1))
    sharded = load_or_build(
        body, CAMERA, poses, tmp_path / "sharded", progress=False, build=BuildSettings(jobs=2, shard_size=25)
    )
    for resolution in RESOLUTIONS:
        np.testing.assert_array_equal(sharded.silhouettes(resolution).masks(), serial.silhouettes(resolution).masks())
        for part in ("starts", "ends", "ptr"):
            np.testing.assert_array_equal(
                getattr(sharded.runs[resolution], part), getattr(serial.runs[resolution], part)
            )
    np.testing.assert_array_equal(sharded.areas, serial.areas)


@pytest.mark.slow
def test_a_build_on_ray_equals_one_on_joblibs_processes(body, varied_poses, tmp_path):
    pytest.importorskip("ray", reason="the Ray extra is not installed (make ray)")
    poses = varied_poses[:60]
    local = load_or_build(body, CAMERA, poses, tmp_path / "loky", progress=False, build=BuildSettings(jobs=2))
    on_ray = load_or_build(
        body, CAMERA, poses, tmp_path / "ray", progress=False, build=BuildSettings(jobs=2, backend="ray", shard_size=16)
    )
    for resolution in RESOLUTIONS:
        np.testing.assert_array_equal(on_ray.silhouettes(resolution).masks(), local.silhouettes(resolution).masks())
    np.testing.assert_array_equal(on_ray.areas, local.areas)


def test_the_stored_silhouettes_are_those_of_the_rendered_labels(body, varied_poses, tmp_path):
    built = load_or_build(body, CAMERA, varied_poses[:40], tmp_path, progress=False)
    labels, _ = build_labels(body, varied_poses[:40], tmp_path / "layout")
    for resolution in RESOLUTIONS:
        np.testing.assert_array_equal(built.silhouettes(resolution).masks(), labels[resolution] > 0)


def test_a_killed_build_resumes_with_the_shards_it_finished(body, varied_poses, tmp_path, caplog):
    import signal
    import subprocess
    import sys
    import time

    poses = varied_poses[:200]
    np.save(tmp_path / "poses.npy", poses)
    script = (
        "import numpy as np, time\n"
        "from tracker.models.makehuman import build_body\n"
        "from tracker.geometry.rigs import mono\n"
        "from tracker.tbf import sample_build\n"
        "from tracker.tbf.build_workers import BuildSettings\n"
        "camera = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=480.0, width=320,\n"
        "              height=240)[0]\n"
        "render = sample_build.render_shard\n"
        "def slow(*a, **k):\n    time.sleep(0.5)\n    return render(*a, **k)\n"
        "sample_build.render_shard = slow\n"
        f"sample_build.load_or_build(build_body(), camera, np.load('{tmp_path / 'poses.npy'}'),\n"
        f"    '{tmp_path / 'c'}', progress=False, build=BuildSettings(jobs=1, shard_size=20))\n"
    )
    process = subprocess.Popen([sys.executable, "-c", script])
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((tmp_path / "c").glob(".*.building/shard*.done"))) < 3:
        time.sleep(0.05)
    process.send_signal(signal.SIGKILL)
    process.wait()
    done = len(list((tmp_path / "c").glob(".*.building/shard*.done")))
    assert 3 <= done < 10
    with caplog.at_level(logging.INFO):
        resumed = load_or_build(
            body, CAMERA, poses, tmp_path / "c", progress=False, build=BuildSettings(jobs=1, shard_size=20)
        )
    assert f"{done} of 10 shards done" in caplog.text
    clean = load_or_build(body, CAMERA, poses, tmp_path / "clean", progress=False)
    for resolution in RESOLUTIONS:
        np.testing.assert_array_equal(resumed.silhouettes(resolution).masks(), clean.silhouettes(resolution).masks())
    assert not list((tmp_path / "c").glob(".*.building"))


def test_a_full_check_reads_every_byte_a_sampled_one_the_sizes_and_ends(
    body, swing_poses, tmp_path, caplog, monkeypatch
):
    monkeypatch.setattr(sample_store, "BLOCK", 256)  # so that a small array is read in part, as a large one is
    monkeypatch.setattr(sample_store, "SAMPLED_BLOCKS", 4)
    poses = swing_poses[:60]
    built = load_or_build(body, CAMERA, poses, tmp_path, progress=False)
    array = tmp_path / built.key / "runs_320x240_starts.npy"
    data = bytearray(array.read_bytes())
    middle = len(data) // 2
    data[middle] ^= 0xFF  # inside no sampled block: only a full check sees it
    array.write_bytes(bytes(data))
    assert load_or_build(body, CAMERA, poses, tmp_path, progress=False).key == built.key  # sampled: trusted
    with caplog.at_level(logging.WARNING):
        load_or_build(body, CAMERA, poses, tmp_path, progress=False, check="full")
    assert "runs_320x240_starts.npy does not match its checksum" in caplog.text


def _naive_reduction(labels, factor, n_parts):
    """Block by block: count every label, keep the most frequent part where half the block is covered."""
    rows, cols = labels.shape[0] // factor, labels.shape[1] // factor
    out = np.zeros((rows, cols), np.uint8)
    for r in range(rows):
        for c in range(cols):
            counts = np.bincount(
                labels[r * factor : (r + 1) * factor, c * factor : (c + 1) * factor].ravel(), minlength=n_parts + 1
            )
            if (factor * factor - counts[0]) * 2 >= factor * factor:
                out[r, c] = np.argmax(counts[1:]) + 1
    return out


@pytest.mark.parametrize("factor", [2, 4])
def test_label_reduction_equals_counting_block_by_block(factor):
    rng = np.random.default_rng(factor)
    labels = rng.integers(0, 16, (3, 24, 32)).astype(np.uint8)
    labels[1] = np.where(rng.random((24, 32)) < 0.6, 0, labels[1])  # mostly background
    labels[2, :, :16] = 7  # whole blocks of one part
    reduced = reduce_labels(labels, factor, 15)
    for image, ours in zip(labels, reduced, strict=True):
        np.testing.assert_array_equal(ours, _naive_reduction(image, factor, 15))


def test_part_areas_count_each_label_and_reduction_wants_whole_blocks():
    """`label_areas` counts each part's pixels (the naive count, label by label) of one image or of many; a label
    image whose sides are not whole blocks is not reduced."""
    from tracker.sequence import label_areas

    rng = np.random.default_rng(9)
    labels = rng.integers(0, 16, (4, 12, 20)).astype(np.uint8)
    naive = np.array([[(image == part).sum() for part in range(1, 16)] for image in labels])
    np.testing.assert_array_equal(label_areas(labels, 15), naive)
    np.testing.assert_array_equal(label_areas(labels[2], 15), naive[2])
    np.testing.assert_array_equal(
        reduce_labels(labels.reshape(2, 2, 12, 20), 4, 15)[1, 0], reduce_labels(labels[2], 4, 15)
    )
    with pytest.raises(ValueError, match="not whole blocks of 3x3"):
        reduce_labels(labels, 3, 15)
