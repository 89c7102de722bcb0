"""Shared fixtures. The arm, its motion and the rig are the defaults of ``conf/``, built as a run builds them."""

import subprocess
import sys

import pytest
import yaml

from experiments.components import Components, build, compose
from tracker.data import data_dir
from tracker.models.dsq_arm import DSQArm
from tracker.motion.arm_swing import ArmSwing

MOCAP_DIR = data_dir() / "mocap"  # the CMU clips, read in place


@pytest.fixture(scope="session")
def default_run() -> Components:
    """The components of ``python -m experiments.run`` with no overrides (seed 0)."""
    return build(compose())


@pytest.fixture(scope="session")
def arm(default_run) -> DSQArm:
    return default_run.model


@pytest.fixture(scope="session")
def motion(default_run) -> ArmSwing:
    return default_run.scene.arm


@pytest.fixture(scope="session")
def rig(default_run):
    return default_run.cameras


@pytest.fixture(scope="session")
def body():
    from tracker.models.makehuman import build_body

    return build_body()


@pytest.fixture(scope="session")
def renderer():
    from tracker.render.offscreen import SceneRenderer

    with SceneRenderer(320, 240) as shared:
        yield shared


def run_cli(run_dir, *overrides, cwd):
    return subprocess.run(
        [sys.executable, "-m", "experiments.run", f"hydra.run.dir={run_dir}", *overrides],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def components_of(run_dir) -> Components:
    """A run's components, built from the overrides it ran with."""
    overrides = yaml.safe_load((run_dir / ".hydra" / "overrides.yaml").read_text())
    return build(compose([o for o in overrides if not o.startswith("hydra.")]))


def _cli_run(tmp_path_factory, name: str, *overrides: str):
    root = tmp_path_factory.mktemp(name)
    result = run_cli(root / "out", *overrides, cwd=root)
    assert result.returncode == 0, result.stderr
    return root / "out"


@pytest.fixture(scope="session")
def five_frame_run(tmp_path_factory):
    """A 5-frame render-only run of the default scene through the real CLI."""
    return _cli_run(tmp_path_factory, "run", "model=dsq_arm", "frames=5")


@pytest.fixture(scope="session")
def abis_run(tmp_path_factory):
    """A 10-frame AbIS run of the default scene through the real CLI."""
    return _cli_run(tmp_path_factory, "abis", "tracker=abis", "frames=10")


@pytest.fixture(scope="session")
def body_swing_run(tmp_path_factory):
    """A 4-frame render-only run of the body's arm swing through the real CLI (blue backdrop, nuisance)."""
    return _cli_run(
        tmp_path_factory, "body", "model=body_mesh", "scene=arm_swing", "frames=4", "record.weight_maps=true"
    )


@pytest.fixture(scope="session")
def experiment_a_run(tmp_path_factory):
    """A 2-frame run of paper 2's experiment A under its conditions, on a short capture session of samples."""
    cache = tmp_path_factory.mktemp("experiment_a_cache")
    return _cli_run(
        tmp_path_factory,
        "experiment_a",
        "experiment=tbf_table4c",
        "frames=2",
        "tracker.samples.capture.seconds=15",
        f"tracker.cache_dir={cache}",
    )


# A small right-arm grid of TBF samples (side-on): enough for a run of a few frames.
# paper 1's arm by tree filtering on 33 grid poses (the elbow every 8 degrees, the forearm bent both ways) instead of
# the default 4,725: the same code, a tenth of a second's rendering.
SMALL_ARM_GRID = (
    "tracker.arm_samples.axes=[{part:upper_arm,param:r2,span:[90.0,90.0,1.0]},"
    "{part:forearm,param:r2,span:[0.0,80.0,8.0]},{part:forearm,param:b1,span:[-0.04,0.04,0.04]}]"
)
SMALL_GRID = [
    "tracker.samples.grid.swing_deg=[-30,60,10]",
    "tracker.samples.grid.abduction_deg=[0,0,8]",
    "tracker.samples.grid.elbow_deg=[0,0,30]",
    "tracker.samples.grid.left_swing_deg=[0]",
    "tracker.samples.grid.yaw_deg=[-90]",
]

# A 6-frame TBF run (nwXOR, DM2) of the body's arm swing on a small pose grid, seen by rig=body_side's camera.
TBF_RUN = (
    "model=body_mesh",
    "tracker=tbf",
    "cost=nwxor",
    "motion=dm2",
    "frames=6",
    "tracker.samples.grid.swing_deg=[-30,60,6]",
    "tracker.samples.grid.abduction_deg=[0,16,8]",
    "tracker.samples.grid.elbow_deg=[0,0,30]",
    "tracker.samples.grid.left_swing_deg=[0]",
    "tracker.samples.grid.yaw_deg=[-90]",
)


@pytest.fixture(scope="session")
def tbf_run(tmp_path_factory):
    """`TBF_RUN` through the real CLI."""
    cache = tmp_path_factory.mktemp("tbf_cache")
    return _cli_run(tmp_path_factory, "tbf", *TBF_RUN, f"tracker.cache_dir={cache}")


@pytest.fixture(scope="session")
def real_motion_run(tmp_path_factory):
    """4 frames of the walking clip 69_20 tracked by the paper-scale preset on a small dictionary that holds the clip
    itself (so that the posture is right and the placement is what is tested) and a DAZ-friendly clip, mirrored,
    at 15 fps; learned motion, placed on the floor."""
    cache = tmp_path_factory.mktemp("real_motion_cache")
    return _cli_run(
        tmp_path_factory,
        "real_motion",
        "experiment=tbf_paper_scale",
        "frames=4",
        "scene.path=mocap/69_20.bvh",
        "scene.center=path",
        f"tracker.cache_dir={cache}",
        "tracker.samples.clips=[mocap/69_20.bvh,mocap_daz/martial_04.bvh]",
        "tracker.samples.clip_turns_deg=[0.0]",
        "tracker.thresholds=[0.05,0.03,0.02]",
    )
