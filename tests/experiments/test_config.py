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
CLIP = MOCAP_DIR / "69_20.bvh"
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
