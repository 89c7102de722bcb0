"""Config schemas derived from the registries (`tracker.registry`), stored in Hydra's ConfigStore.

Every option file ``conf/<group>/<option>.yaml`` starts from the schema of the component it builds (its defaults
list names ``schema_<component>``): a dataclass generated from the component's settings (`tracker.settings`) with
the core's defaults, plus ``_target_``, the factory's import path, which names the component. So a mistyped key or
a value of the wrong type fails at composition, and no default is written twice. Tuples become lists, ``Literal``
choices strings, ``Annotated`` ranges their base type: OmegaConf's types; the ranges are checked by
`experiments.checks`. The run itself (frames, seed, the synthetic camera, the recording) is `RunSettings`.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import functools
import importlib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from tracker import catalog  # noqa: F401  (registers the built-in components)
from tracker.observe.silhouettes import SilhouetteSettings
from tracker.ranges import Count, Range, Seed
from tracker.registry import REGISTRIES, Entry
from tracker.render.settings import RenderSettings
from tracker.settings import REQUIRED, Setting, settings_of

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"
CONFIG_NAME = "config"
GROUPS = tuple(REGISTRIES)  # model, scene, rig, tracker, cost, motion
SCHEMA_PREFIX = "schema_"


@dataclass(frozen=True)
class RecordSettings:
    """What ``run.rrd`` holds besides the tracker's and the evaluation's series: the images, the meshes, the
    parameters, and the weight maps of the silhouette costs."""

    images: bool = True  # each view's RGB (as video), part labels, extracted silhouette, the tracker's overlays
    weight_maps: bool = False  # silhouette scenes: each cost's weight map d_P as a float image (300 KB a frame)
    video_quality: Annotated[int, Range(0, 63)] = 30  # the RGB video's constant quality (AV1's crf: lower is finer)
    # The truth and estimate meshes every this many frames (0: none); series, images and tables keep every frame.
    # A subject whose every part moves non-rigidly costs ~30 KB of vertices a frame.
    meshes_every: Annotated[int, Range(0, 1_000_000)] = 1
    parameters: bool = True  # every parameter of every part, truth and estimate, as series (~1 MB per 1,000 frames)


@dataclass(frozen=True)
class RunSettings:
    """One run (besides its components, `GROUP_SETTINGS`): ``frames`` frames from ``seed``, the synthetic camera,
    background subtraction, what the recording holds."""

    frames: Count = 60
    seed: Seed = 0
    render: RenderSettings = field(default_factory=RenderSettings)
    silhouette: SilhouetteSettings = field(default_factory=SilhouetteSettings)
    record: RecordSettings = field(default_factory=RecordSettings)
    plugins: tuple[str, ...] = ()  # modules to import first: they register components of their own


RUN_SETTINGS = settings_of(RunSettings)
# The components: required, but for a tracker's cost and motion model (the groups `tracker.registry` names).
GROUP_SETTINGS = tuple(Setting(group, Any, None if group in ("cost", "motion") else REQUIRED) for group in GROUPS)


def entry_schema(entry: Entry) -> type:
    """The schema of a registered component: its settings and its ``_target_``."""
    return _entry_schema(entry.kind, entry.name, entry.factory.__module__)


@functools.cache
def _entry_schema(kind: str, name: str, module: str) -> type:
    importlib.import_module(module)  # in a sweep launcher's worker: the registration of a plugin's component
    entry = REGISTRIES[kind][name]
    return _schema(f"{kind}_{name}", entry.fields, ("entry", kind, name, module), entry.target)


@functools.cache
def dataclass_schema(settings_class: type) -> type:
    return _dataclass_schema(settings_class.__module__, settings_class.__qualname__)


@functools.cache
def _dataclass_schema(module: str, qualname: str) -> type:
    settings_class = functools.reduce(getattr, qualname.split("."), importlib.import_module(module))
    return _schema(qualname, settings_of(settings_class), ("settings", module, qualname))


@functools.cache
def run_schema() -> type:
    return _schema("run", GROUP_SETTINGS + RUN_SETTINGS, ("run",))


def _schema(name: str, settings: tuple[Setting, ...], identity: tuple[str, ...], target: str | None = None) -> type:
    """A generated schema, importable from this module by a name that says how to generate it again (`__getattr__`):
    sweep launchers pickle the ConfigStore by reference to their workers, which may not have made it yet."""
    fields = [("_target_", str, field(default=target))] if target else []
    fields += [(s.name, _omegaconf_type(s.hint), _schema_default(s)) for s in settings]
    schema = dataclasses.make_dataclass(f"{name.title().replace('_', '').replace('.', '')}Schema", fields)
    schema.__module__, schema.__qualname__ = __name__, "··".join(part.replace(".", "·") for part in identity)
    return schema


def __getattr__(qualname: str) -> type:
    """A generated schema by its `_schema` qualified name (``entry··<kind>··<name>··<module>``, ...)."""
    kind, *parts = qualname.split("··")
    makers = {"entry": _entry_schema, "settings": _dataclass_schema, "run": run_schema}
    if kind not in makers:
        raise AttributeError(f"module {__name__!r} has no attribute {qualname!r}")
    return makers[kind](*(part.replace("·", ".") for part in parts))


def _omegaconf_type(hint: Any) -> Any:
    origin, arguments = typing.get_origin(hint), typing.get_args(hint)
    if origin is Annotated:
        return _omegaconf_type(hint.__origin__)
    if origin is Literal:
        return type(arguments[0])
    if origin in (Union, types.UnionType):
        return Optional[_omegaconf_type(next(a for a in arguments if a is not type(None)))]  # noqa: UP045
    if origin in (tuple, list, collections.abc.Sequence):
        return list[_omegaconf_type(arguments[0])]
    if dataclasses.is_dataclass(hint):
        return dataclass_schema(hint)
    return hint


def _schema_default(setting: Setting) -> Any:
    if setting.required:
        return field(default=MISSING)
    value = _schema_value(setting.hint, setting.default)
    return (
        field(default_factory=lambda: _schema_value(setting.hint, setting.default))
        if isinstance(value, list | dict) or dataclasses.is_dataclass(value)
        else field(default=value)
    )


def _schema_value(hint: Any, value: Any) -> Any:
    """A core default as the schema's: settings dataclasses as schema instances, tuples as lists."""
    if dataclasses.is_dataclass(value):
        schema = dataclass_schema(type(value))
        return schema(**{s.name: _schema_value(s.hint, getattr(value, s.name)) for s in settings_of(type(value))})
    if isinstance(value, tuple | list):
        return [_schema_value(None, item) for item in value]
    return value


def register_schemas() -> None:
    """Store ``schema_run`` and every registered component's ``<group>/schema_<name>`` (again after plugins)."""
    store = ConfigStore.instance()
    store.store(name=f"{SCHEMA_PREFIX}run", node=run_schema())
    for kind, registry in REGISTRIES.items():
        for entry in registry:
            store.store(group=kind, name=f"{SCHEMA_PREFIX}{entry.name}", node=entry_schema(entry))


register_schemas()
