import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.conftest import MOCAP_DIR
from tracker.models.body_skeleton import BVH_TO_BODY, JOINT_INDEX, JOINT_NAMES
from tracker.motion.bvh import BvhError, read_bvh
from tracker.motion.mocap import ClipSelection, MocapScene, clip_poses

CLIP = MOCAP_DIR / "143_23.bvh"


@pytest.fixture(scope="module")
def clip():
    return read_bvh(CLIP)


def test_a_clips_header_frame_count_and_frame_time(clip):
    assert clip.frames == 815 and clip.frame_time == pytest.approx(0.0083333)
    assert clip.names == JOINT_NAMES and clip.motion.shape == (815, 6 + 3 * 30)
    assert clip.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")


def test_a_joints_rotation_at_a_frame_matches_an_independent_reader(clip):
    bvhio = pytest.importorskip("bvhio")  # a maintained BVH library (dev dependency), its own parser and maths
    node = _find(bvhio.readAsBvh(str(CLIP)).Root, "RightForeArm")
    for frame in (1, 300, 814):
        theirs = node.Keyframes[frame].Rotation  # local rotation quaternion (w, x, y, z), float32
        mine = Rotation.from_matrix(clip.local_rotations([frame])[0, clip.index("RightForeArm")])
        np.testing.assert_allclose(
            np.abs(mine.as_quat(scalar_first=True) @ [theirs.w, theirs.x, theirs.y, theirs.z]), 1.0, atol=1e-6
        )


def test_every_motion_value_is_pythons_float_of_its_text(clip, tmp_path):
    """The MOTION numbers are read by NumPy's table reader: each is Python's ``float`` of its text, to the bit, on a
    real clip and on numbers of every form (17 digits, exponents, signs, tabs and blank lines between them)."""
    rows = [line.split() for line in CLIP.read_text().partition("MOTION")[2].splitlines()[3:] if line.strip()]
    assert clip.motion.tobytes() == np.array([[float(token) for token in row] for row in rows]).tobytes()
    rng = np.random.default_rng(4)
    values = (rng.normal(size=(40, 3)) * 10.0 ** rng.integers(-12, 12, (40, 3))).tolist()
    texts = [
        [("%.17g", "%+.6e", "%r", "%.3f")[(k + j) % 4] % value for j, value in enumerate(row)]
        for k, row in enumerate(values)
    ]
    motion = "\n\n".join("\t".join(row) if k % 5 == 0 else " ".join(row) for k, row in enumerate(texts))
    path = tmp_path / "numbers.bvh"
    path.write_text(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n}\nMOTION\n"
        f"Frames: 40\nFrame Time: 0.1\n{motion}\n"
    )
    expected = np.array([[float(text) for text in row] for row in texts])
    assert read_bvh(path).motion.tobytes() == expected.tobytes()


def test_a_rotation_by_hand(clip):
    # Frame 300, RightForeArm: Z -139.2219, Y 48.5242, X -100.9798 degrees, composed Rz @ Ry @ Rx.
    z, y, x = np.radians(clip.motion[300, clip.columns[clip.index("RightForeArm")]])
    cz, sz, cy, sy, cx, sx = np.cos(z), np.sin(z), np.cos(y), np.sin(y), np.cos(x), np.sin(x)
    by_hand = (
        np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    )
    np.testing.assert_allclose(clip.local_rotations([300])[0, clip.index("RightForeArm")], by_hand, atol=1e-12)


@pytest.mark.parametrize(
    "text, message",
    [
        ("", r"not a BVH file: no MOTION section"),
        (
            "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n}\nMOTION\nFrames: 2\n"
            "Frame Time: 0.1\n0 0 0\n",
            r"header says 2 frames, the file holds 1 \(truncated\?\)",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n}\nMOTION\nFrames: 1\n"
            "Frame Time: 0.1\n0 0\n",
            r"every MOTION line must hold 3 values, found lines of \[2\]",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Wrong\n}\nMOTION\nFrames: 1\n"
            "Frame Time: 0.1\n0 0 0\n",
            r"bad CHANNELS Xposition Yposition Wrong",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\nMOTION\nFrames: 1\n"
            "Frame Time: 0.1\n0 0 0\n",
            r"HIERARCHY section is incomplete",
        ),
    ],
)
def test_a_malformed_file_gives_one_clear_error(tmp_path, text, message):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(BvhError, match=message) as caught:
        read_bvh(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_missing_or_truncated_clip_gives_one_clear_error(tmp_path):
    with pytest.raises(BvhError, match=r"^cannot read BVH file .*nope\.bvh: No such file"):
        read_bvh(tmp_path / "nope.bvh")
    truncated = tmp_path / "cut.bvh"
    truncated.write_bytes(CLIP.read_bytes()[:300_000])
    with pytest.raises(BvhError, match=r"cut\.bvh: (header says 815 frames|the file ends inside frame)"):
        read_bvh(truncated)


def test_resampling_at_a_divisor_of_the_capture_rate_picks_the_captured_frames(body, clip):
    step = clip.frame_time  # the file's (rounded) frame time: 0.0083333 s
    captured = clip_poses(clip, body, ClipSelection(start_s=60 * step, frames=9, fps=1 / step))
    quarter = clip_poses(clip, body, ClipSelection(start_s=60 * step, frames=3, fps=1 / (4 * step)))
    np.testing.assert_allclose(quarter, captured[::4], atol=1e-9)
    halfway = clip_poses(clip, body, ClipSelection(start_s=60.5 * step, frames=1, fps=1 / step))[0]
    for joint in ("RightForeArm", "LeftUpLeg"):  # slerp: the half-way rotation between two captured frames
        k = 3 + 3 * JOINT_INDEX[joint]
        a, b, mid = (Rotation.from_rotvec(p[k : k + 3]) for p in (captured[0], captured[1], halfway))
        assert (a.inv() * mid).magnitude() == pytest.approx((a.inv() * b).magnitude() / 2, abs=1e-9)
        assert (mid.inv() * b).magnitude() == pytest.approx((a.inv() * b).magnitude() / 2, abs=1e-9)
    np.testing.assert_allclose(halfway[:3], (captured[0, :3] + captured[1, :3]) / 2, atol=1e-12)


def test_the_body_points_its_limbs_where_the_clip_points_them(body, clip):
    # The body's limbs turn by the clip's rotations from its T-pose; both T-poses agree within 2 degrees. (The
    # trunk keeps the mesh's own curve, a few degrees off the clip's straight spine: not compared.)
    frames = np.array([1 + 4 * k for k in range(0, 200, 40)])
    poses = clip_poses(clip, body, ClipSelection(fps=30.0, frames=200))[(frames - 1) // 4]
    positions = clip.joint_positions(frames)
    for bone, child in (
        ("RightArm", "RightForeArm"),
        ("LeftForeArm", "LeftHand"),
        ("RightUpLeg", "RightLeg"),
        ("LeftLeg", "LeftFoot"),
    ):
        theirs = (positions[:, clip.index(child)] - positions[:, clip.index(bone)]) @ BVH_TO_BODY.T
        for pose, direction in zip(poses, theirs, strict=True):
            heads = body.joint_positions(pose)
            mine = heads[JOINT_INDEX[child]] - heads[JOINT_INDEX[bone]]
            cosine = mine @ direction / np.linalg.norm(mine) / np.linalg.norm(direction)
            assert np.degrees(np.arccos(min(cosine, 1.0))) < 3.0, (bone, pose)


def test_a_scene_faces_the_configured_way_and_starts_over_the_origin(body):
    for yaw in (-90.0, 0.0, 135.0):
        pose = MocapScene(str(MOCAP_DIR / "69_20.bvh"), yaw_deg=yaw).params(body, 0)
        facing = Rotation.from_rotvec(pose[3:6]).apply([0.0, -1.0, 0.0])
        assert np.degrees(np.arctan2(facing[1], facing[0])) == pytest.approx(yaw if yaw <= 180 else yaw - 360)
        assert np.allclose(pose[:2], 0.0)


def _find(joint, name):
    if joint.Name == name:
        return joint
    return next((found for child in joint.Children if (found := _find(child, name)) is not None), None)
