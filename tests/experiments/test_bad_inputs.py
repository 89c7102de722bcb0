"""The bad-input suite: each input either stops the command at start (exit 2, one line on stderr naming what is
wrong and what is allowed, no files) or, found inside a run, is recorded (a failed frame or ``status: failed:
<reason>``) with every output still readable."""

import importlib.util
import json
import re
import subprocess
import sys

import pandas as pd
import pytest

from experiments.run import main
from tests.conftest import MOCAP_DIR, SMALL_GRID
from tests.experiments.test_run import frames_by_entity

CLIP, SHORT_CLIP = MOCAP_DIR / "69_20.bvh", MOCAP_DIR / "143_33.bvh"


def _bvh_variant(tmp_path, name, edit):
    path = tmp_path / name
    path.write_bytes(edit(SHORT_CLIP.read_bytes()))
    return path


def _truncated(data: bytes) -> bytes:
    return data[: len(data) * 2 // 3]  # cut in the middle of the MOTION lines


def _with_nan(data: bytes) -> bytes:
    head, motion = data.split(b"MOTION", 1)
    lines = motion.split(b"\n")
    lines[5] = b" ".join([b"nan", *lines[5].split()[1:]])
    return head + b"MOTION" + b"\n".join(lines)


def _frames_kept(count: int):
    def edit(data: bytes) -> bytes:
        head, motion = data.split(b"MOTION", 1)
        lines = motion.strip().split(b"\n")  # Frames:, Frame Time:, then one line per frame
        return head + b"MOTION\n" + b"\n".join([f"Frames: {count}".encode(), lines[1], *lines[2 : 2 + count]]) + b"\n"

    return edit


BVH_VARIANTS = {
    "one_frame.bvh": (_frames_kept(1), r"the clip has 1 frame\(s\), no motion to track$"),
    "no_frames.bvh": (_frames_kept(0), r"the clip has 0 frame\(s\), no motion to track$"),
    "truncated.bvh": (
        _truncated,
        r"the file ends inside frame \d+ \(\d+ of 96 values; the header says 36\d frames\): "
        r"truncated\?$",
    ),
    "short.bvh": (
        lambda data: data[: data.rindex(b"\n", 0, len(data) * 2 // 3) + 1],
        r"header says 36\d frames, the file holds \d+ \(truncated\?\)$",
    ),
    "nan.bvh": (_with_nan, r"the MOTION section holds NaN or infinite values$"),
    "binary.bvh": (lambda data: bytes(range(256)) * 4, r"it is not a BVH file \(not text\)$"),
    "hierarchy_only.bvh": (lambda data: data.split(b"MOTION")[0], r"it is not a BVH file: no MOTION section$"),
    "not_cmu.bvh": (
        lambda data: data.replace(b"JOINT RightHand\n", b"JOINT RightPaw\n"),
        r"no retargeting table fits its skeleton \(31 joints rooted at 'Hips'\): the nearest, cmu, needs "
        r"joints RightHand; known skeletons: cmu, daz \(tracker/motion/retarget.py\)$",
    ),
}

BODY_TBF = ["model=body_mesh", "tracker=tbf", "cost=nwxor", "motion=dm2"]
AT_START = [
    (["model=nope"], r"^model=nope: no such option, allowed body_mesh, dsq_arm$"),
    (["model.parts.0.shape.eps1=-1"], r"^model\.parts\[0\]\.shape\.eps1=-1\.0 is out of range: allowed >= 0$"),
    (["model.parts.1.shape.a1=1.5"], r"a1=1\.5 is out of range: allowed in \(0, 1\]$"),
    (["model.parts.1.shape.b3=0"], r"b3=0\.0 is out of range: allowed in \(0, 1\]$"),
    (["model.parts.2.shape.t1=-2"], r"t1=-2\.0 is out of range: allowed in \[-1, 1\]"),
    (["frames=0"], r"^frames=0 is out of range: allowed >= 1$"),
    (["frames=abc"], r"^frames: Value 'abc' of type 'str' could not be converted to Integer$"),
    (["nokey=1"], r"^nokey: unknown key, allowed keys here: model, scene"),
    (["+nokey=1"], r"^nokey: unknown key"),
    (["rig.fov=3"], r"^rig\.fov: unknown key, allowed keys here: target, front_distance"),
    (["rig.width=8"], r"^rig\.width=8 is out of range: allowed in \[16, 4096\]$"),
    (["rig.target=[1,2]"], r"^rig\.target=\[1\.0, 2\.0\] has 2 values: allowed exactly 3$"),
    (["scene.arm.period_frames=nan"], r"^scene\.arm\.period_frames=nan is out of range: allowed > 0$"),
    (["model=body_mesh", "scene=bvh"], r"^scene\.path: missing value"),
    (["scene=bvh", f"scene.path={CLIP}"], r"^scene=bvh needs model=body_mesh, not model=dsq_arm$"),
    (
        ["model=body_mesh", "scene=bvh", "scene.path=nope.bvh"],
        r"^scene\.path=nope\.bvh: cannot read BVH file .*/nope\.bvh: No such file",
    ),
    (
        ["model=body_mesh", "scene=bvh", f"scene.path={SHORT_CLIP}", "frames=1000"],
        rf"^frames=1000: scene\.path={re.escape(str(SHORT_CLIP))} has 90 frames at 30 fps from scene\.start_s=0\.0 "
        r"\(3\.00 s of motion\); allowed at most 90$",
    ),  # 360 steps of .0083333 s = 2.99999 s: 89 steps of 1/30 s
    (
        ["model=body_mesh", "scene=bvh", f"scene.path={SHORT_CLIP}", "scene.start_s=100"],
        rf"^scene\.start_s=100\.0: past the end of {re.escape(str(SHORT_CLIP))} \(3\.00 s of motion\); allowed "
        r"below 3\.00$",
    ),
    (
        ["experiment=tbf_table4c", "tracker.cache_dir=/proc/version/cache"],
        r"^tracker\.cache_dir=/proc/version/cache: /proc/version is a file, not a folder$",
    ),
    pytest.param(
        ["experiment=tbf_table4c", "tracker.build.backend=ray"],
        r"^tracker\.build\.backend=ray: Ray is not installed here \(make ray installs it\); allowed loky$",
        marks=pytest.mark.skipif(importlib.util.find_spec("ray") is not None, reason="Ray is installed here"),
    ),
    (
        ["experiment=tbf_table4c", "rig.width=64", "rig.height=48"],
        r"^rig=body_side: camera main is 64x48, tracker=tbf needs at least 80x60 \(set rig\.width and rig\.height\)$",
    ),
    (["model=body_mesh", "model.triangles=10"], r"^model\.triangles=10 is out of range"),
    (
        ["cost=nwxor"],
        r"^cost=nwxor serves tracker=tbf and tracker=hybrid only, not tracker=render_only: add tracker=tbf",
    ),
    (
        ["tracker=tbf"],
        r"^tracker=tbf needs cost and motion: add cost=nwxor motion=dm2 \(allowed cost=xor\|wxor\|nwxor, "
        r"motion=dm1\|dm2\|learned\)$",
    ),
    (
        ["tracker=abis", "model=body_mesh", "rig=body_side"],
        r"^tracker=abis tracks model=body_mesh from 3 to 4 camera views: rig=body_side has 1; "
        r"add rig=body_multi_vga model\.texture_seed=0$",
    ),
    (
        ["tracker=abis", "model=body_mesh", "rig=body_multi_vga", "model.texture_seed=null"],
        r"^tracker=abis tracks model=body_mesh with model\.texture_seed set: add model\.texture_seed=0$",
    ),
    (
        ["model=dsq_arm", "tracker=tbf", "cost=nwxor", "motion=dm2", "tracker.align=feet"],
        r"^tracker\.align=feet: the arm stands on no floor, allowed none$",
    ),
    (
        ["model=dsq_arm", "tracker=tbf", "cost=nwxor", "motion=dm2", "tracker.estimate=mean"],
        r"^tracker\.estimate=mean: the arm's grid is not averaged, allowed map$",
    ),
    (
        ["model=dsq_arm", "tracker=tbf", "cost=nwxor", "motion=dm2", "tracker.filter.flip_share=0.05"],
        r"^tracker\.filter\.flip_share=0\.05: the arm's grid has no flips, allowed 0$",
    ),
    (
        [*BODY_TBF, "tracker.placed_on=own"],
        r"^tracker\.placed_on=own: the samples' anchors stand on the floor, tracker\.align=none places nobody there "
        r"\(align=ground does\); allowed reference$",
    ),
    (
        ["model=dsq_arm", "tracker=tbf", "cost=nwxor", "motion=dm2", "tracker.chain.candidates=50"],
        r"^tracker\.chain\.candidates=50: the arm's grid has no joints to chain, allowed 0$",
    ),
    ([*BODY_TBF, "tracker.chain.step_m=0"], r"^tracker\.chain\.step_m=0\.0 is out of range: allowed > 0$"),
    (
        ["model=body_mesh", "tracker=tbf", "motion=dm1"],
        r"^tracker=tbf needs cost: add cost=nwxor \(allowed cost=xor\|wxor\|nwxor\)$",
    ),
    (
        [
            *BODY_TBF,
            "rig=body_multi",
            "rig.views=[" + ",".join(f"{{name:v{k},position:[{k},-4.5,0.9]}}" for k in range(5)) + "]",
        ],
        r"^tracker=tbf tracks model=body_mesh from 1 to 4 camera views: rig=body_multi has 5$",
    ),
    (
        ["rig=body_multi", "rig.views=[{name:a,position:[0,-4.5,0.9]},{name:a,position:[4.5,0,0.9]}]"],
        r"^rig\.views: names \['a', 'a'\] repeat; allowed distinct names$",
    ),
    (["rig=body_multi", "rig.views=[]"], r"^rig\.views=\[\]: allowed one camera or more$"),
    (["model=body_mesh", "cost=wxor", "cost.w=-1"], r"^cost\.w=-1\.0 is out of range: allowed >= 0$"),
    (["model=body_mesh", "cost=xor", "cost.w=1"], r"^cost\.w: unknown key, allowed keys here: none$"),  # xor has no w
    (["motion=dm1", "motion.m=5"], r"^motion\.m: unknown key, allowed keys here: sigma, sigma_root_m, occlusion_area"),
    (["experiment=tbf_table4c", "tracker.thresholds=[0.1,-1,0.1]"], r"^tracker\.thresholds\[1\]=-1\.0 is out of range"),
    (["experiment=tbf_table4c", "tracker.filter.prune_fraction=1"], r"^tracker\.filter\.prune_fraction=1\.0 is out"),
    (["model=body_mesh", "render.noise_std=-2"], r"^render\.noise_std=-2\.0 is out of range"),
    (["seed=-1"], r"^seed=-1 is out of range: allowed in \[0, 4294967295\]$"),
    (["motion=dm2", "motion.m=0.5"], r"^motion\.m=0\.5 is out of range: allowed >= 1$"),
    (["motion=dm1", "motion.sigma=-0.1"], r"^motion\.sigma=-0\.1 is out of range: allowed > 0$"),
    (["motion=dm2", "motion.occlusion_area_px=-1"], r"occlusion_area_px=-1\.0 is out of range: allowed >= 0"),
    (["tracker=abis", "tracker.fit.optimizer=newton"], r"^tracker\.fit\.optimizer='newton' is not allowed: allowed sd"),
    (["tracker=abis", "tracker.pairing_radius_px=0"], r"^tracker\.pairing_radius_px=0\.0 is out of range: allowed > 0"),
    (["tracker=abis", "tracker.fit.huber_px=-1"], r"^tracker\.fit\.huber_px=-1\.0 is out of range: allowed > 0$"),
    (["tracker=abis", "tracker.features.max_features=0"], r"max_features=0 is out of range: allowed >= 1"),
    (["model=schema_dsq_arm"], r"^model=schema_dsq_arm is a schema, not an option"),
    (["frames=["], r"^cannot parse the overrides"),
    (["rig.target=${nope}"], r"^rig\.target: Interpolation key 'nope' not found$"),
    (
        ["rig=mono", "rig.position=[0.55,0,-0.2]"],
        r"^rig=mono: camera 'main': position and target coincide \(\[0\.55, 0\.0, -0\.2\]\)$",
    ),
    (
        ["experiment=nope"],
        r"^experiment=nope: no such option, allowed abis_body, abis_fig8_fig9, abis_occlusion, arm_scene, "
        r"hybrid_multi_view, hybrid_paper_scale, "
        r"tbf_multi_view, tbf_paper_scale, "
        r"tbf_table4c, tbf_table4c_clean$",
    ),
    (["tracker=kalman"], r"^tracker=kalman: no such option, allowed abis, hybrid, render_only, tbf$"),
    ([*BODY_TBF, "tracker.thresholds=[0.01,0.002]"], r"^tracker\.thresholds=.* has 2 values: allowed exactly 3$"),
    (["scene.arm.bend_amplitude=nan"], r"^scene\.arm\.bend_amplitude=nan is out of range: allowed a finite number$"),
    (["-m", "frames=2,0"], r"^frames=0 is out of range: allowed >= 1$"),
    (
        ["-m", "experiment=abis_fig8_fig9,abis_occlusion", "tracker.selection=none"],
        r"^tracker\.selection: unknown key, allowed keys here: none \(a sweep composes this before its swept "
        r"experiment: name the option it belongs to\)$",
    ),
    (
        ["experiment=tbf_table4c_clean", "tracker.samples.grid.swing_deg=[60,-60,6]"],
        r"^tracker\.samples\.grid\.swing_deg=\[60\.0, -60\.0, 6\.0\] is not allowed: allowed \[start, stop, step\] "
        r"with start <= stop$",
    ),
    (
        ["experiment=tbf_table4c_clean", "tracker.samples.grid.elbow_deg=[0,60,0]"],
        r"^tracker\.samples\.grid\.elbow_deg\[2\]=0\.0 is out of range: allowed > 0$",
    ),
    (
        ["experiment=tbf_table4c", "tracker.samples.clips=[mocap/nope.bvh]"],
        r"^tracker\.samples\.clips\[0\]=mocap/nope\.bvh: cannot read BVH file .*mocap/nope\.bvh: No such file",
    ),
    (
        ["experiment=tbf_table4c", "tracker.body=tallest"],
        r"^tracker\.body='tallest' is not allowed: allowed base, nearest_standard$",
    ),
    (["experiment=tbf_table4c", "tracker.node_shares=[0.2,1.5,0.9]"], r"^tracker\.node_shares\[1\]=1\.5 is out of"),
    (["experiment=tbf_table4c", "model.shape.height=2"], r"^model\.shape\.height=2\.0 is out of range: allowed in"),
    (["experiment=tbf_table4c", "scene.body.variation=-0.5"], r"^scene\.body\.variation=-0\.5 is out of range"),
    (["hydra.run.dir=/proc/nope/run"], r"^hydra\.run\.dir=/proc/nope/run: cannot make it, /proc is not writable"),
    (["-m", "hydra.sweep.dir=/proc/nope", "seed=0,1"], r"^hydra\.sweep\.dir=/proc/nope: cannot make it"),
    (
        ["tracker=abis", "tracker.initial_noise=-1"],
        r"^tracker\.initial_noise=-1: expects its settings \(translation_m, rotation_rad, scale_fraction\), not a "
        r"value; set one, e\.g\. tracker\.initial_noise\.translation_m=\.\.\.$",
    ),
]


def _fails_at_start(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and captured.err.startswith("error: ")
    assert re.search(message, captured.err.removeprefix("error: ").strip()), captured.err
    assert [p.name for p in tmp_path.iterdir() if not p.name.endswith(".bvh")] == []  # no runs/, multirun/, logs


@pytest.mark.parametrize("argv, message", AT_START, ids=[" ".join(getattr(c, "values", c)[0]) for c in AT_START])
def test_a_bad_override_stops_at_start_with_one_line(argv, message, tmp_path, monkeypatch, capsys):
    _fails_at_start(argv, message, tmp_path, monkeypatch, capsys)


@pytest.mark.parametrize("name", sorted(BVH_VARIANTS))
def test_a_bad_bvh_file_stops_at_start_with_one_line(name, tmp_path, monkeypatch, capsys):
    edit, message = BVH_VARIANTS[name]
    path = _bvh_variant(tmp_path, name, edit)
    argv = ["model=body_mesh", "scene=bvh", f"scene.path={path}"]
    _fails_at_start(argv, rf"^scene\.path={re.escape(str(path))}: {message}", tmp_path, monkeypatch, capsys)


def test_a_users_preset_that_does_not_parse_or_names_an_unknown_key_stops_at_start_with_one_line(
    tmp_path, monkeypatch, capsys
):
    presets = tmp_path / "user" / "experiment"
    presets.mkdir(parents=True)
    head = "# @package _global_\ndefaults:\n  - tbf_table4c\n"
    (presets / "broken.yaml").write_text(head + "tracker:\n  thresholds: [0.1, 0.2\n")
    (presets / "typo.yaml").write_text(head + "tracker:\n  thresholdz: [0.1, 0.2, 0.3]\n")
    monkeypatch.chdir(tmp_path)
    cases = {
        "broken": rf"^{re.escape(str(presets / 'broken.yaml'))}, line 5, column 15: not valid YAML, while parsing a "
        r"flow sequence: expected ',' or '\]', but got '<stream end>'$",
        "typo": r"^experiment/typo\.yaml: tracker\.thresholdz: unknown key, allowed keys here: samples, thresholds",
    }
    for preset, message in cases.items():
        with pytest.raises(SystemExit) as stopped:
            main([f"hydra.searchpath=[file://{tmp_path / 'user'}]", f"experiment={preset}"])
        error = capsys.readouterr().err
        assert stopped.value.code == 2 and error.count("\n") == 1 and re.search(message, error.removeprefix("error: "))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["user"]  # no run folder


def _run(tmp_path, *overrides):
    run_dir = tmp_path / "run"
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", f"hydra.run.dir={run_dir}", *overrides],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    return result, run_dir


def _outputs_readable(run_dir):
    metrics = json.loads((run_dir / "metrics.json").read_text())
    frames = pd.read_parquet(run_dir / "frames.parquet")
    recorded = frames_by_entity(run_dir / "run.rrd")
    assert not list(run_dir.glob(".*.tmp"))
    return metrics, frames, recorded


def test_a_camera_looking_away_loses_every_feature_and_each_abis_frame_is_recorded_failed(tmp_path):
    result, run_dir = _run(tmp_path, "tracker=abis", "rig=mono", "rig.target=[0,-9,1]", "frames=3")
    assert result.returncode == 0, result.stderr
    metrics, frames, recorded = _outputs_readable(run_dir)
    assert metrics["status"] == "ok" and metrics["failed_frames"] == 3
    assert set(frames["failure"]) == {"all pairs lost"} and (frames["tracked"] == 0).all()
    assert recorded["/metrics/timing/estimate_ms"] == [0, 1, 2]


def test_a_camera_looking_away_fails_the_tbf_run_with_its_reason(tmp_path):
    result, run_dir = _run(
        tmp_path, *BODY_TBF, "rig.target=[0,9,0.9]", "frames=3", f"tracker.cache_dir={tmp_path}/c", *SMALL_GRID
    )
    assert result.returncode == 1
    metrics, _, _ = _outputs_readable(run_dir)
    assert metrics["status"] == "failed: ValueError: the pose samples are not in the camera's view", metrics["status"]


def test_a_subject_leaving_the_view_gives_failed_frames_and_the_run_goes_on(tmp_path):
    # 69_20 walks forward out of the side camera's view: those frames have no silhouette to score.
    walk = [f"scene.path={MOCAP_DIR / '69_20.bvh'}", "scene.fps=6", "frames=27"]
    result, run_dir = _run(
        tmp_path, *BODY_TBF, "scene=bvh", *walk, f"tracker.cache_dir={tmp_path}/c", "record.images=false", *SMALL_GRID
    )
    assert result.returncode == 0, result.stderr
    metrics, frames, recorded = _outputs_readable(run_dir)
    per_frame = frames.drop_duplicates("frame")
    failed = per_frame[per_frame["failure"] != ""]
    assert metrics["status"] == "ok" and metrics["failed_frames"] == len(failed) > 0
    assert failed["failure"].str.contains("silhouette").all(), failed["failure"].unique()
    assert recorded["/metrics/tree/entropy"] == sorted(set(per_frame["frame"]) - set(failed["frame"]))


def test_a_view_that_loses_the_subject_does_not_stop_the_others(tmp_path):
    # Three cameras: a fighter (a dictionary clip) leaves some views' images, then all of them; a frame fails only
    # when no view sees him.
    clip = [f"scene.path={MOCAP_DIR.parent / 'mocap_daz' / 'martial_04.bvh'}", "scene.fps=4"]
    walk = [*clip, "frames=30", "rig=body_multi", "tracker.align=ground"]
    result, run_dir = _run(
        tmp_path, *BODY_TBF, "scene=bvh", *walk, f"tracker.cache_dir={tmp_path}/c", "record.images=false", *SMALL_GRID
    )
    assert result.returncode == 0, result.stderr
    _, frames, _ = _outputs_readable(run_dir)
    seen = frames.groupby("frame")[["visible_px_front", "visible_px_side", "visible_px_oblique"]].sum() > 0
    failed = frames.drop_duplicates("frame").set_index("frame")["failure"] != ""
    assert (seen.any(axis=1) & ~seen.all(axis=1)).sum() >= 3  # frames some views lost him in, others not
    assert failed.equals(~seen.any(axis=1)), (failed, seen)


def test_a_damaged_cache_is_rebuilt_not_used(tmp_path):
    cache = tmp_path / "c"
    arguments = [*BODY_TBF, "frames=2", f"tracker.cache_dir={cache}", "record.images=false", *SMALL_GRID]
    first, run_dir = _run(tmp_path, *arguments)
    assert first.returncode == 0, first.stderr
    expected = (run_dir / "metrics.json").read_bytes()
    manifests = list(cache.glob("samples/*/meta.json"))
    assert [list(json.loads(m.read_text())["files"]) for m in manifests] == [[t.name] for t in cache.glob("**/tree-*")]
    for tree in cache.glob("**/tree-*.npz"):
        data = bytearray(tree.read_bytes())
        data[len(data) // 2] ^= 0xFF  # one byte flipped inside an array
        tree.write_bytes(bytes(data))
    for manifest in manifests:  # every sigma scaled by hand: never used
        stored = json.loads(manifest.read_text())
        stored["derived"]["values"] = {name: 1000 * value for name, value in stored["derived"]["values"].items()}
        manifest.write_text(json.dumps(stored))
    again, run_dir = _run(tmp_path, *arguments)
    assert again.returncode == 0, again.stderr
    log = (run_dir / "run.log").read_text()
    assert "tree cache" in log and "does not match its checksum): rebuilding" in log, log
    assert log.count("is damaged") == 1 and log.count("are damaged (they do not match their digest)") == 1, log
    assert (run_dir / "metrics.json").read_bytes() == expected
    for manifest in manifests:
        manifest.write_text(manifest.read_text()[: len(manifest.read_text()) // 2])  # cut short
    cut, run_dir = _run(tmp_path, *arguments)  # (a damaged sample array: tests/tracker/tbf/test_samples.py)
    assert cut.returncode == 0 and "sample cache" in (log := (run_dir / "run.log").read_text()) and "rebuilding" in log
    assert (run_dir / "metrics.json").read_bytes() == expected
