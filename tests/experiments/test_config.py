import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from experiments.checks import ConfigError, check_config
from experiments.components import build, choices_of, compose
from experiments.schemas import CONFIG_DIR, GROUPS, entry_schema
from experiments.validate import sweep_combinations, validate_command_line
from tests.conftest import MOCAP_DIR
from tracker.models.dsq import DSQShape
from tracker.registry import REGISTRIES
from tracker.settings import REQUIRED, to_plain

OPTIONS = sorted((p.parent.name, p.stem) for p in CONFIG_DIR.glob("*/*.yaml") if p.parent.name in GROUPS)
CLIP = MOCAP_DIR / "69_20.bvh"
PRESETS = sorted(p.stem for p in (CONFIG_DIR / "experiment").glob("*.yaml"))
TBF = ["model=body_mesh", "tracker=tbf", "cost=xor", "motion=dm1"]
# What an option needs beside it to make a run.
COMPANIONS = {
    ("scene", "bvh"): ["model=body_mesh", f"scene.path={CLIP}"],
    ("tracker", "tbf"): TBF,
    ("tracker", "hybrid"): TBF,  # the body only
    ("cost", None): TBF,
    ("motion", None): TBF,
    ("rig", "orthogonal3"): [],
    ("rig", None): [],
}


def companions(group, option):
    return COMPANIONS.get((group, option), COMPANIONS.get((group, None), []))


@pytest.mark.parametrize("group, option", OPTIONS)
def test_every_option_file_composes_checks_and_builds_its_registered_component(group, option):
    cfg = compose([*companions(group, option), f"{group}={option}"])
    check_config(cfg, choices_of(cfg))
    assert build(cfg).entries[group].target == cfg[group]["_target_"]


def test_every_registered_component_has_an_option_file():
    targets = {
        (group, OmegaConf.select(compose([*companions(group, option), f"{group}={option}"]), group)._target_)
        for group, option in OPTIONS
    }
    assert {(kind, entry.target) for kind, registry in REGISTRIES.items() for entry in registry} <= targets


@pytest.mark.parametrize(
    "kind, name", [(kind, entry.name) for kind, registry in REGISTRIES.items() for entry in registry]
)
def test_a_schema_holds_the_core_defaults_and_nothing_else(kind, name):
    entry = REGISTRIES[kind][name]
    schema = OmegaConf.to_container(OmegaConf.structured(entry_schema(entry)))
    assert schema.pop("_target_") == entry.target
    assert list(schema) == [setting.name for setting in entry.fields]
    for setting in entry.fields:
        expected = "???" if setting.default is REQUIRED else to_plain(setting.default)
        assert schema[setting.name] == expected, setting.name


def test_the_default_components_are_built_from_their_settings(arm, motion):
    forearm = DSQShape(a=0.22, a1=0.30, a2=0.30, a3=1.0, eps1=0.5, eps2=1.0, t1=-0.2, t2=-0.2, b3=0.5)
    assert arm.parts[1].shape == forearm  # conf/model/dsq_arm.yaml, the rest the core's defaults
    assert motion == REGISTRIES["scene"].defaults("arm_swing").arm  # the scene's YAML states no value of its own
    again = build(compose(["seed=0"]))
    assert (again.model.textures[1] == arm.textures[1]).all()  # textures follow the run's seed


@pytest.mark.parametrize("preset", PRESETS)
def test_experiment_presets_compose_and_validate(preset):
    validate_command_line([f"experiment={preset}"], CONFIG_DIR, "config")


def test_every_value_of_a_sweep_is_checked():
    assert sweep_combinations(["frames=1,2", "seed=3", "rig=mono,orthogonal3"]) == [
        ["frames=1", "seed=3", "rig=mono"],
        ["frames=2", "seed=3", "rig=mono"],
        ["frames=1", "seed=3", "rig=orthogonal3"],
    ]
    with pytest.raises(ConfigError, match="^frames=0 is out of range"):
        validate_command_line(["-m", "frames=2,0"], CONFIG_DIR, "config")


@pytest.mark.parametrize(
    "argv, key",
    [
        (["model=nope"], "model=nope"),
        (["model.parts.0.shape.eps1=-1"], "eps1=-1"),
        (["frames=0"], "frames=0"),
        (["nokey=1"], "nokey"),
        (["-m", "frames=1,0"], "frames=0"),
    ],
)
def test_bad_overrides_through_the_cli_exit_nonzero_and_leave_no_files(tmp_path, argv, key):
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and key in result.stderr
    assert result.stderr.count("\n") == 1 and result.stdout == ""
    assert list(Path(tmp_path).iterdir()) == []  # no runs/ or multirun/ folder, no log


def test_the_option_and_compatibility_tables_are_the_ones_the_registrations_make():
    from experiments.generated import README, with_block
    from experiments.options import COMMAND, CONFIGURATION, compatibility_table, table

    for path, name, made in ((CONFIGURATION, "options", table()), (README, "compatibility", compatibility_table())):
        text = path.read_text()
        assert with_block(text, name, COMMAND, made) == text, f"{path.name}: run {COMMAND}"
