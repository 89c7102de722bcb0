import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from experiments.config import CONFIG_DIR, GROUP_SCHEMAS, ConfigError, check_config
from experiments.validate import sweep_combinations, validate_command_line
from tests.conftest import MOCAP_DIR
from tracker.abis.tracker import AbisTracker
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.models.dsq_arm import DSQArm
from tracker.motion.mocap import MocapScene
from tracker.motion.scenes import ArmSwingScene
from tracker.sequence import RenderOnly
from tracker.tbf.distances import COSTS, SilhouetteCost
from tracker.tbf.motion import MotionModel
from tracker.tbf.tracker import TbfTracker

OPTIONS = sorted((p.parent.name, p.stem) for p in CONFIG_DIR.glob("*/*.yaml") if p.parent.name != "experiment")
CLIP, SHORT_CLIP = MOCAP_DIR / "69_20.bvh", MOCAP_DIR / "143_33.bvh"
PRESETS = sorted(p.stem for p in (CONFIG_DIR / "experiment").glob("*.yaml"))


def compose_run(overrides):
    with initialize_config_dir(config_dir=str(CONFIG_DIR), version_base="1.3"):
        cfg = compose("config", overrides=overrides, return_hydra_config=True)
    choices = {k: v for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra") and v is not None}
    return cfg, choices


def test_every_option_file_has_a_schema_and_every_schema_a_file():
    assert {(g, o) for g, options in GROUP_SCHEMAS.items() for o in options} == set(OPTIONS)


@pytest.mark.parametrize("group, option", OPTIONS)
def test_every_group_option_composes_and_instantiates(group, option):
    tbf = ["model=body_mesh", "tracker=tbf"]
    needs = {("scene", "bvh"): ["model=body_mesh", f"scene.path={CLIP}"], ("tracker", "tbf"): [*tbf, "cost=xor",
             "motion=dm1"], **{("cost", kind): [*tbf, "motion=dm1"] for kind in COSTS},
             **{("motion", kind): [*tbf, "cost=xor"] for kind in ("dm1", "dm2")}}  # fmt: skip
    cfg, choices = compose_run([f"{group}={option}", *needs.get((group, option), [])])
    check_config(cfg, choices)
    extras = {"cost": instantiate(cfg.cost), "motion": instantiate(cfg.motion)} if group == "tracker" and \
        option == "tbf" else {}  # fmt: skip
    built = instantiate(cfg[group], _convert_="all", _partial_=bool(extras))
    built = built(**extras) if extras else built
    expected_type = {"model": {"dsq_arm": DSQArm, "body_mesh": BodyMesh}.get(option),
                     "scene": {"arm_swing": ArmSwingScene, "bvh": MocapScene}.get(option), "rig": tuple,
                     "tracker": {"render_only": RenderOnly, "abis": AbisTracker, "tbf": TbfTracker}.get(option),
                     "cost": SilhouetteCost, "motion": MotionModel}[group]  # fmt: skip
    assert isinstance(built, expected_type)
    if group == "rig":
        assert all(isinstance(camera, Camera) for camera in built)


@pytest.mark.parametrize("preset", PRESETS)
def test_experiment_presets_compose_and_validate(preset):
    validate_command_line([f"experiment={preset}"], CONFIG_DIR, "config")


def test_composed_defaults_build_what_the_yaml_files_say(arm, motion):
    cfg, _ = compose_run([])  # schema defaults + YAML, through Hydra; the fixtures read the YAML alone
    built = instantiate(cfg.model, _convert_="all")
    assert built.parts == arm.parts and built.mesh == arm.mesh and built.samples == arm.samples
    assert instantiate(cfg.scene, _convert_="all").arm == motion
    np.testing.assert_array_equal(built.textures[1], arm.textures[1])  # textures follow the seed


BAD_OVERRIDES = [
    (["model=nope"], r"^model=nope: no such option, allowed body_mesh, dsq_arm$"),
    (["model.parts.0.shape.eps1=-1"], r"^model\.parts\[0\]\.shape\.eps1=-1\.0 is out of range: allowed >= 0$"),
    (["model.parts.1.shape.a1=1.5"], r"a1=1\.5 is out of range: allowed in \(0, 1\]"),
    (["model.parts.1.shape.b3=0"], r"b3=0\.0 is out of range: allowed in \(0, 1\]"),
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
    (["scene=bvh", f"scene.path={CLIP}"], r"^scene=bvh drives the body: it needs model=body_mesh, not model=dsq_arm$"),
    (["model=body_mesh", "scene=bvh", "scene.path=nope.bvh"],
     r"^scene\.path=nope\.bvh: cannot read BVH file nope\.bvh"),
    (["model=body_mesh", "scene=bvh", f"scene.path={SHORT_CLIP}", "frames=1000"],
     rf"^frames=1000: scene\.path={re.escape(str(SHORT_CLIP))} has 90 frames at 30 fps from scene\.start_s=0\.0; "
     r"allowed at most 90$"),  # 360 steps of .0083333 s = 2.99999 s: 89 steps of 1/30 s
    (["model=body_mesh", "model.triangles=10"], r"^model\.triangles=10 is out of range"),
    (["cost=nwxor"], r"^cost=nwxor serves tracker=tbf only, not tracker=render_only: add tracker=tbf"),
    (["tracker=tbf"], r"^tracker=tbf tracks the body: it needs model=body_mesh, not model=dsq_arm$"),
    (["model=body_mesh", "tracker=tbf", "motion=dm1"], r"^tracker=tbf needs a cost and a motion model: add cost=nwxor"),
    (["model=body_mesh", "cost=wxor", "cost.w=-1"], r"^cost\.w=-1\.0 is out of range: allowed >= 0$"),
    (["model=body_mesh", "cost=xor", "cost.kind=and"], r"^cost\.kind='and' is not allowed: allowed xor, wxor, nwxor$"),
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
    (["experiment=nope"],
     r"^experiment=nope: no such option, allowed abis_fig8_fig9, arm_scene, tbf_paper_scale, tbf_table4c$"),
]


@pytest.mark.parametrize("argv, message", BAD_OVERRIDES)
def test_bad_overrides_give_one_line_naming_key_value_and_allowed(argv, message):
    with pytest.raises(ConfigError) as caught:
        validate_command_line(argv, CONFIG_DIR, "config")
    assert "\n" not in str(caught.value)
    assert re.search(message, str(caught.value)), str(caught.value)


def test_every_value_of_a_sweep_is_checked():
    assert sweep_combinations(["frames=1,2", "seed=3", "rig=mono,orthogonal3"]) == [
        ["frames=1", "seed=3", "rig=mono"],
        ["frames=2", "seed=3", "rig=mono"],
        ["frames=1", "seed=3", "rig=orthogonal3"],
    ]
    with pytest.raises(ConfigError, match="^frames=0 is out of range"):
        validate_command_line(["-m", "frames=2,0"], CONFIG_DIR, "config")


@pytest.mark.parametrize("argv, key", [
    (["model=nope"], "model=nope"),
    (["model.parts.0.shape.eps1=-1"], "eps1=-1"),
    (["frames=0"], "frames=0"),
    (["nokey=1"], "nokey"),
    (["-m", "frames=1,0"], "frames=0"),
])  # fmt: skip
def test_bad_overrides_through_the_cli_exit_nonzero_and_leave_no_files(tmp_path, argv, key):
    result = subprocess.run([sys.executable, "-m", "experiments.run", *argv], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and key in result.stderr
    assert result.stderr.count("\n") == 1 and result.stdout == ""
    assert list(Path(tmp_path).iterdir()) == []  # no runs/ or multirun/ folder, no log
