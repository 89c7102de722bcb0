"""Config schemas (registered in Hydra's ConfigStore) and their validation.

Every group option in ``conf/<group>/<option>.yaml`` starts from one of these schemas (its defaults list names
``schema_<option>``), so a mistyped key or a value of the wrong type fails at composition. Numeric ranges are
field metadata (``allowed=Range``) checked by `check_ranges` with the full key path in the message. ``_target_``
names the core factory that `hydra.utils.instantiate` calls with plain values (``_convert_="all"``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import II, MISSING, DictConfig, ListConfig, OmegaConf, open_dict

from tracker.models.dsq import PARAM_RANGES, SHAPE_NAMES, DSQShape
from tracker.ranges import ANY, NON_NEGATIVE, POSITIVE, Range, check_in_range

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"
CONFIG_NAME = "config"


def option_values(group: str, option: str) -> dict[str, Any]:
    """The values ``conf/<group>/<option>.yaml`` sets, as plain Python (its defaults list and ``_target_`` aside):
    the keyword arguments of the option's core factory, for code that builds components without Hydra."""
    values = OmegaConf.to_container(OmegaConf.load(CONFIG_DIR / group / f"{option}.yaml"))
    return {key: value for key, value in values.items() if key not in ("defaults", "_target_")}


def allowed(
    values: Range | tuple[str, ...],
    *,
    each: bool = False,
    length: int | None = None,
    optional: bool = False,
    default: Any = MISSING,
    **kw,
) -> Any:
    """A dataclass field whose value (or, with ``each``, every element) must lie in ``values`` (a `Range`, or a
    tuple of allowed strings); ``optional`` also allows None (null in YAML)."""
    metadata = {"allowed": values, "each": each, "length": length, "optional": optional}
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=metadata, **kw)
    return field(default=default, metadata=metadata, **kw)


BYTE = Range(0, 255)
IMAGE_SIDE = Range(16, 4096)
COUNT = Range(1, math.inf)

# One field per DSQ shape parameter, with the default and the allowed range the core defines (eq 1-2).
DSQShapeSchema = dataclasses.make_dataclass(
    "DSQShapeSchema",
    [(name, float, allowed(PARAM_RANGES[name], default=getattr(DSQShape(), name))) for name in SHAPE_NAMES],
)


@dataclass
class ResolutionSchema:
    n_eta: int = allowed(Range(3, 1024), default=16)
    n_omega: int = allowed(Range(3, 1024), default=24)


@dataclass
class ArmPartSchema:
    name: str = MISSING
    shape: DSQShapeSchema = field(default_factory=DSQShapeSchema)
    tint: list[int] = allowed(BYTE, each=True, length=3, default=[220, 220, 220])
    texture_cells: list[int] = allowed(Range(1, 256), each=True, length=2, default=[12, 12])


@dataclass
class DSQArmSchema:
    _target_: str = "tracker.models.dsq_arm.build_arm"
    parts: list[ArmPartSchema] = MISSING
    mesh: ResolutionSchema = field(default_factory=lambda: ResolutionSchema(40, 48))
    samples: ResolutionSchema = field(default_factory=lambda: ResolutionSchema(16, 24))
    seed: int = II("seed")  # the parts' textures


@dataclass
class BodyMeshSchema:
    """Paper 2's skinned body (tracker/models/body_mesh.py), decimated to about ``triangles`` faces."""

    _target_: str = "tracker.models.body_mesh.build_body"
    triangles: int = allowed(Range(500, 30000), default=4500)
    height: float = allowed(Range(0.5, 2.0), default=1.0)  # the subject's scale against the standard body
    girth: float = allowed(Range(0.5, 2.0), default=1.0)


@dataclass
class ArmSwingSchema:
    """Paper 1's elbow swing of the DSQ arm (tracker/motion/arm_swing.py)."""

    period_frames: float = allowed(POSITIVE, default=48.0)
    elbow_swing: float = allowed(Range(-math.pi, math.pi), default=1.2)
    bend_amplitude: float = allowed(ANY, default=0.04)
    bend_period_frames: float = allowed(POSITIVE, default=64.0)
    wrist_rock: float = allowed(Range(-math.pi, math.pi), default=0.35)
    shoulder_sway: float = allowed(Range(-math.pi, math.pi), default=0.06)
    shoulder: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 0.0, 0.0])


@dataclass
class BodySwingSchema:
    """Paper 2's experiment A: the body's right arm swings forward and back (tracker/motion/body_swing.py)."""

    period_frames: float = allowed(POSITIVE, default=40.0)
    forward_deg: float = allowed(Range(0.0, 180.0), default=60.0)
    backward_deg: float = allowed(Range(0.0, 90.0), default=40.0)
    abduction_deg: float = allowed(Range(0.0, 90.0), default=8.0)
    yaw_deg: float = allowed(ANY, default=-90.0)


@dataclass
class ArmSwingSceneSchema:
    """``scene=arm_swing``: the block for the chosen model drives it (tracker/motion/scenes.py)."""

    _target_: str = "tracker.motion.scenes.ArmSwingScene.from_config"
    arm: ArmSwingSchema = field(default_factory=ArmSwingSchema)
    body: BodySwingSchema = field(default_factory=BodySwingSchema)


@dataclass
class BvhSceneSchema:
    """``scene=bvh``: a CMU-style BVH clip drives the body (tracker/motion/mocap.py)."""

    _target_: str = "tracker.motion.mocap.MocapScene"
    path: str = MISSING
    start_s: float = allowed(NON_NEGATIVE, default=0.0)
    fps: float = allowed(Range(1.0, 1000.0), default=30.0)
    yaw_deg: float = allowed(ANY, default=-90.0)
    center: bool = True


@dataclass
class Orthogonal3Schema:
    _target_: str = "tracker.geometry.rigs.orthogonal3"
    target: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 0.0, 0.0])
    front_distance: float = allowed(POSITIVE, default=2.0)
    left_distance: float = allowed(POSITIVE, default=2.0)
    top_distance: float = allowed(POSITIVE, default=2.0)
    focal_px: float = allowed(POSITIVE, default=400.0)
    width: int = allowed(IMAGE_SIDE, default=320)
    height: int = allowed(IMAGE_SIDE, default=240)


@dataclass
class MonoSchema:
    _target_: str = "tracker.geometry.rigs.mono"
    position: list[float] = allowed(ANY, each=True, length=3, default=[0.0, -3.0, 1.0])
    target: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 0.0, 1.0])
    up: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 0.0, 1.0])
    focal_px: float = allowed(POSITIVE, default=400.0)
    width: int = allowed(IMAGE_SIDE, default=320)
    height: int = allowed(IMAGE_SIDE, default=240)
    name: str = "main"


@dataclass
class RenderOnlySchema:
    """No estimation: the run renders and records the scene (what every tracker will observe)."""

    _target_: str = "tracker.sequence.RenderOnly"


@dataclass
class FitSchema:
    """Per-part fitting (tracker/abis/fitting.py). huber_px: eq 7's rho (null: plain squares, eq 8)."""

    optimizer: str = allowed(("sd", "lm"), default="lm")
    max_iterations: int = allowed(COUNT, default=20)
    sd_iterations_factor: int = allowed(COUNT, default=10)
    relative_tolerance: float = allowed(POSITIVE, default=1e-6)
    huber_px: Optional[float] = allowed(POSITIVE, optional=True, default=1.0)  # noqa: UP045 (OmegaConf needs it)


@dataclass
class FeatureSchema:
    """Shi-Tomasi + pyramidal LK (tracker/observe/features.py)."""

    max_features: int = allowed(COUNT, default=300)
    quality_level: float = allowed(Range(0.0, 1.0, low_open=True), default=0.01)
    min_distance_px: float = allowed(POSITIVE, default=5.0)
    block_size: int = allowed(Range(3, 31), default=5)
    window_px: int = allowed(Range(5, 101), default=15)
    pyramid_levels: int = allowed(Range(1, 8), default=3)
    max_forward_backward_px: float = allowed(POSITIVE, default=0.25)


@dataclass
class PriorSchema:
    """One sigma of plausible change per frame, per parameter group (tracker/abis/tracker.py PriorSigmas)."""

    scale: float = allowed(POSITIVE, default=0.002)
    roundness: float = allowed(POSITIVE, default=0.01)
    tapering: float = allowed(POSITIVE, default=0.01)
    bending: float = allowed(POSITIVE, default=0.005)
    translation_m: float = allowed(POSITIVE, default=0.01)
    rotation_rad: float = allowed(POSITIVE, default=0.1)


@dataclass
class InitialNoiseSchema:
    """Frame 0 starts from the truth plus this noise (the paper aligns the model with a user's help)."""

    translation_m: float = allowed(NON_NEGATIVE, default=0.003)
    rotation_rad: float = allowed(NON_NEGATIVE, default=0.01)
    scale_fraction: float = allowed(NON_NEGATIVE, default=0.01)


@dataclass
class AbisSchema:
    """Paper 1's AbIS tracker. prior: null fits eq 8 alone (no prior around the previous frame)."""

    _target_: str = "tracker.abis.tracker.AbisTracker.from_config"
    fit: FitSchema = field(default_factory=FitSchema)
    features: FeatureSchema = field(default_factory=FeatureSchema)
    prior: Optional[PriorSchema] = field(default_factory=PriorSchema)  # noqa: UP045
    pairing_radius_px: float = allowed(POSITIVE, default=2.0)
    refined_tolerance_px: float = allowed(POSITIVE, default=0.5)
    boundary_margin_px: int = allowed(Range(0, 50), default=5)
    max_residual_px: float = allowed(POSITIVE, default=2.0)
    initial_noise: InitialNoiseSchema = field(default_factory=InitialNoiseSchema)


@dataclass
class CostSchema:
    """Silhouette distance (paper 2, eq 6-9; tracker/tbf/distances.py). ``w``: wXOR's outside weight."""

    _target_: str = "tracker.tbf.distances.SilhouetteCost"
    kind: str = allowed(("xor", "wxor", "nwxor"), default=MISSING)
    w: float = allowed(NON_NEGATIVE, default=1.0)


@dataclass
class MotionModelSchema:
    """Random-walk motion over pose samples (paper 2, eq 3-5; tracker/tbf/motion.py). ``sigma``: per-joint step
    (radians per frame); ``m``: DM2's factor for occluded parts; ``occlusion_area_px``: T_A."""

    _target_: str = "tracker.tbf.motion.MotionModel"
    kind: str = allowed(("dm1", "dm2"), default=MISSING)
    sigma: float = allowed(POSITIVE, default=0.1)
    m: float = allowed(Range(1.0, math.inf), default=1.0)
    occlusion_area_px: float = allowed(NON_NEGATIVE, default=50.0)
    sigma_root_m: float = allowed(POSITIVE, default=0.02)


@dataclass
class GridSchema:
    """The right-arm pose grid: ``[start, stop, step]`` degrees (stop included); lists for the left arm's swing
    and the body's yaw (tracker/tbf/tracker.py GridSpec)."""

    swing_deg: list[float] = allowed(ANY, each=True, length=3, default=[-60.0, 120.0, 6.0])
    abduction_deg: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 40.0, 8.0])
    elbow_deg: list[float] = allowed(ANY, each=True, length=3, default=[0.0, 60.0, 30.0])
    left_swing_deg: list[float] = allowed(ANY, each=True, default=[0.0, 20.0])
    yaw_deg: list[float] = allowed(ANY, each=True, default=[-100.0, -90.0, -80.0])


@dataclass
class SamplesSchema:
    grid: Optional[GridSchema] = field(default_factory=GridSchema)  # noqa: UP045 (OmegaConf needs it)
    clips: list[str] = field(default_factory=list)
    clip_fps: float = allowed(POSITIVE, default=10.0)
    clip_yaw_deg: float = allowed(ANY, default=-90.0)
    clip_in_place: bool = True
    clip_turns_deg: list[float] = allowed(ANY, each=True, default=[0.0])
    clip_copies: int = allowed(Range(0, 1000), default=0)
    clip_jitter_deg: float = allowed(NON_NEGATIVE, default=10.0)
    seed: int = allowed(Range(0, 2**32 - 1), default=0)
    min_joint_deg: float = allowed(NON_NEGATIVE, default=5.0)


@dataclass
class FilterSchema:
    """tracker/tbf/filter.py: eq 10's sigma in units of the cost's neighbour step, the pruning threshold (of
    a level's best posterior), frame 0's prior width (radians)."""

    likelihood_sigma: float = allowed(POSITIVE, default=1.0)
    prune_fraction: float = allowed(Range(0.0, 1.0, high_open=True), default=0.01)
    initial_sigma: float = allowed(POSITIVE, default=0.3)


@dataclass
class TbfSchema:
    """Paper 2's silhouette tree-based filter (tracker/tbf/tracker.py); needs cost=... and motion=..."""

    _target_: str = "tracker.tbf.tracker.TbfTracker.from_config"
    samples: SamplesSchema = field(default_factory=SamplesSchema)
    thresholds: list[float] = allowed(POSITIVE, each=True, length=3, default=[0.006, 0.002, 0.001])
    filter: FilterSchema = field(default_factory=FilterSchema)
    initial_yaw_deg: float = allowed(ANY, default=-90.0)
    cache_dir: str = ".cache/tbf"
    body_triangles: int = allowed(Range(500, 30000), default=4500)


@dataclass
class RecordSchema:
    images: bool = True
    weight_maps: bool = True  # body scenes: the wXOR / nwXOR weight maps as float images (600 KB a frame)
    jpeg_quality: int = allowed(Range(0, 100), default=90)  # 0 stores RGB losslessly


@dataclass
class RenderSchema:
    """The synthetic camera. noise_std, gain_*: sensor noise and illumination change (tracker/render/nuisance.py);
    0 leaves the rendered image as it is."""

    background_rgb: list[int] = allowed(BYTE, each=True, length=3, default=[40, 40, 48])
    ambient: float = allowed(Range(0.0, 1.0), default=0.35)
    noise_std: float = allowed(Range(0.0, 64.0), default=0.0)
    gain_amplitude: float = allowed(Range(0.0, 0.5), default=0.0)
    gain_period_frames: float = allowed(POSITIVE, default=150.0)


@dataclass
class SilhouetteSchema:
    """Background subtraction for body scenes (tracker/observe/silhouettes.py), learnt from
    ``background_frames`` frames of the empty scene."""

    chroma_threshold: float = allowed(POSITIVE, default=5.0)
    color_threshold: float = allowed(POSITIVE, default=60.0)
    min_chroma_std: float = allowed(POSITIVE, default=0.004)
    cleanup_px: int = allowed(Range(0, 15), default=3)
    background_frames: int = allowed(Range(2, 1000), default=20)


@dataclass
class RunSchema:
    model: Any = MISSING
    scene: Any = MISSING
    rig: Any = MISSING
    tracker: Any = MISSING
    cost: Any = None
    motion: Any = None
    frames: int = allowed(COUNT, default=60)
    seed: int = allowed(Range(0, 2**32 - 1), default=0)
    render: RenderSchema = field(default_factory=RenderSchema)
    silhouette: SilhouetteSchema = field(default_factory=SilhouetteSchema)
    record: RecordSchema = field(default_factory=RecordSchema)


GROUP_SCHEMAS: dict[str, dict[str, type]] = {
    "model": {"dsq_arm": DSQArmSchema, "body_mesh": BodyMeshSchema},
    "scene": {"arm_swing": ArmSwingSceneSchema, "bvh": BvhSceneSchema},
    "rig": {"orthogonal3": Orthogonal3Schema, "mono": MonoSchema, "body_side": MonoSchema, "body_front": MonoSchema},
    "tracker": {"render_only": RenderOnlySchema, "abis": AbisSchema, "tbf": TbfSchema},
    "cost": {"xor": CostSchema, "wxor": CostSchema, "nwxor": CostSchema},
    "motion": {"dm1": MotionModelSchema, "dm2": MotionModelSchema},
}


def register_schemas() -> None:
    """Store the run schema as ``schema_run`` and each group option's schema as ``<group>/schema_<option>``."""
    store = ConfigStore.instance()
    store.store(name="schema_run", node=RunSchema)
    for group, options in GROUP_SCHEMAS.items():
        for option, schema in options.items():
            store.store(group=group, name=f"schema_{option}", node=schema)


register_schemas()  # importing the schemas makes them available to composition; storing again is harmless


class ConfigError(ValueError):
    """An invalid configuration; the message is one line naming the key, the value and what is allowed."""


def check_ranges(node: Any, path: str = "") -> None:
    """Check every field with ``allowed`` metadata in a tree of schema dataclasses; raise `ConfigError`."""
    if not dataclasses.is_dataclass(node):
        return
    for spec in dataclasses.fields(node):
        value = getattr(node, spec.name)
        key = f"{path}.{spec.name}" if path else spec.name
        if "allowed" in spec.metadata:
            _check_field(key, value, spec.metadata)
        if isinstance(value, list):
            for index, item in enumerate(value):
                check_ranges(item, f"{key}[{index}]")
        else:
            check_ranges(value, key)


def _check_field(key: str, value: Any, metadata: dict) -> None:
    if value is None and metadata["optional"]:
        return
    if isinstance(metadata["allowed"], tuple):
        if value not in metadata["allowed"]:
            raise ConfigError(f"{key}={value!r} is not allowed: allowed {', '.join(metadata['allowed'])}")
        return
    length = metadata["length"]
    if length is not None and len(value) != length:
        raise ConfigError(f"{key}={list(value)!r} has {len(value)} values: allowed exactly {length}")
    try:
        if metadata["each"]:
            for index, item in enumerate(value):
                check_in_range(f"{key}[{index}]", item, metadata["allowed"])
        else:
            check_in_range(key, value, metadata["allowed"])
    except ValueError as error:
        raise ConfigError(str(error)) from None


def check_config(cfg: DictConfig, choices: dict[str, str]) -> None:
    """What composition cannot check: numeric ranges, and which options go together (scene=bvh, tracker=tbf)."""
    run_cfg = cfg.copy()  # keeps the schema type (a masked copy would not)
    with open_dict(run_cfg):
        run_cfg.pop("hydra", None)
    check_known_keys(run_cfg)
    check_ranges(OmegaConf.to_object(run_cfg))
    if choices.get("scene") == "bvh":
        check_bvh_scene(cfg, choices)
    check_tbf_choices(choices)


def check_tbf_choices(choices: dict[str, str]) -> None:
    """tracker=tbf tracks the body with a cost and a motion model; those two serve nothing else."""
    tracker, cost, motion, model = (choices.get(k) for k in ("tracker", "cost", "motion", "model"))
    if tracker == "tbf":
        if model != "body_mesh":
            raise ConfigError(f"tracker=tbf tracks the body: it needs model=body_mesh, not model={model}")
        if not cost or not motion:
            raise ConfigError(f"tracker=tbf needs a cost and a motion model: add{'' if cost else ' cost=nwxor'}"
                              f"{'' if motion else ' motion=dm2'} (allowed cost=xor|wxor|nwxor, motion=dm1|dm2)")
    else:
        for group, option in (("cost", cost), ("motion", motion)):
            if option:
                raise ConfigError(f"{group}={option} serves tracker=tbf only, not tracker={tracker}: add "
                                  f"tracker=tbf (and model=body_mesh)")  # fmt: skip


def check_bvh_scene(cfg: DictConfig, choices: dict[str, str]) -> None:
    """scene=bvh: it drives the body, its file is a readable CMU-style clip long enough for ``frames``."""
    from tracker.models.body_mesh import JOINT_NAMES
    from tracker.motion.bvh import BvhError, read_bvh
    from tracker.motion.mocap import available_frames

    if choices.get("model") != "body_mesh":
        raise ConfigError(f"scene=bvh drives the body: it needs model=body_mesh, not model={choices.get('model')}")
    path = cfg.scene.path
    try:
        clip = read_bvh(path)
        missing = [name for name in JOINT_NAMES if name not in clip.names]
        if missing:
            raise BvhError(f"{path}: not a CMU-style skeleton, missing joints {', '.join(missing)}")
        available = available_frames(clip, cfg.scene.start_s, cfg.scene.fps)
    except BvhError as error:  # its message names the file, as the key already does
        message = str(error)
        for named, pronoun in ((f"{Path(path)}: ", ""), (f"{Path(path)} is ", "it is ")):
            message = pronoun + message.removeprefix(named) if message.startswith(named) else message
        raise ConfigError(f"scene.path={path}: {message}") from None
    if cfg.frames > available:
        raise ConfigError(f"frames={cfg.frames}: scene.path={path} has {available} frames at {cfg.scene.fps:g} fps "
                          f"from scene.start_s={cfg.scene.start_s}; allowed at most {available}")  # fmt: skip


def check_known_keys(node: Any, path: str = "") -> None:
    """Reject keys a schema does not have (Hydra lets ``+key=value`` append them to a schema-backed node)."""
    if isinstance(node, DictConfig):
        schema = OmegaConf.get_type(node)
        if dataclasses.is_dataclass(schema):
            known = [f.name for f in dataclasses.fields(schema)]
            for key in node:
                if key not in known:
                    allowed_keys = ", ".join(name for name in known if not name.startswith("_"))
                    raise ConfigError(f"{path}{key}: unknown key, allowed keys here: {allowed_keys}")
        for key in node:
            check_known_keys(node._get_node(key), f"{path}{key}.")
    elif isinstance(node, ListConfig):
        for index in range(len(node)):
            check_known_keys(node._get_node(index), f"{path[:-1]}[{index}].")
