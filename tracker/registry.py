"""Registries: every component a run is built from, by kind, each registered once under its name beside its code.

Kinds (the config groups): ``model`` (the tracked object), ``scene`` (the truth motion), ``rig`` (the cameras),
``tracker``, ``cost`` (a silhouette distance's weights) and ``motion`` (a tracker's motion model, e.g. DM1/DM2;
not the truth motion, which is the scene). A component registers with ``@TRACKERS.register("abis", ...)`` or
``COSTS.register("xor", xor)`` in its own module; `tracker.catalog` imports the built-in ones, and a user's module
registers its own the same way (``plugins=[my.module]`` on the command line imports it).

A registration is everything the layer above knows of a component, stated once beside its code: its settings
(`tracker.settings`: its config schema, defaults and allowed values), the other kinds it needs (a tracker's cost
and motion model), the models it goes with and, for a tracker, from how many camera views and with what (`Fit`),
what it observes (``silhouettes``), how it looks in the recording (`tracker.presentation`) and a start-time check.
The config schemas, the start-time checks, the README's option and compatibility tables and the recordings'
layouts are all derived from the registrations.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

from tracker.presentation import Presentation
from tracker.settings import Setting, from_plain, settings_of


@dataclass(frozen=True)
class Fit:
    """How a component goes with one model. For a tracker: from how many camera views (fewest, most; None: no most),
    and what it needs there that the model's usual config leaves out: ``rig``, the rig option to add when the
    composed rig has another number of views, and ``settings``, ``(key, value)`` pairs to set where the config
    leaves them null. A combination that lacks them fails at start with one line naming them."""

    views: tuple[int, int | None] = (1, None)
    rig: str | None = None
    settings: tuple[tuple[str, Any], ...] = ()

    def allows(self, views: int) -> bool:
        return self.views[0] <= views and (self.views[1] is None or views <= self.views[1])

    @property
    def says(self) -> str:
        low, high = self.views
        if high is None:
            return f"{low} or more camera views"
        return f"{low} camera view{'s' * (high > 1)}" if low == high else f"{low} to {high} camera views"

    def advice(self) -> str:
        """What to add to the command line for this fit: its rig and its settings."""
        return " ".join([f"rig={self.rig}"] * bool(self.rig) + [f"{key}={value}" for key, value in self.settings])


@dataclass(frozen=True)
class Entry:
    """One registered component.

    factory: builds it; with ``settings`` (a dataclass) as ``factory(settings, **needed)``, else from its own
    keyword-only settings as ``factory(**settings, **needed)``. For a kind that configures functions (costs), the
    build is the function with its settings bound (`Configured`).
    """

    kind: str
    name: str
    factory: Callable[..., Any]
    settings: type | None = None
    needs: Mapping[str, str] = field(default_factory=dict)  # kind -> the option suggested when it is missing
    # The models it goes with, each with its `Fit` (None: any model from any rig; registered as names alone, each
    # from any number of views).
    models: Mapping[str, Fit] | None = None
    observes: tuple[str, ...] = ()  # what the run must capture for it, e.g. "silhouettes"
    presentation: Presentation = field(default_factory=Presentation)  # its panels and colours in the recording
    min_image: tuple[int, int] = (1, 1)  # a tracker's smallest camera image (width, height) to track from
    # Before the run: check(settings, frames=..., key=..., model=...) raises ValueError naming the key (settings: the
    # settings dataclass, or the component's settings as attributes; key: its config group; model: the model's name).
    check: Callable[..., None] | None = None

    @property
    def target(self) -> str:
        """The factory's import path: the option's ``_target_`` in the config, which names this entry."""
        return f"{self.factory.__module__}.{self.factory.__qualname__}"

    @property
    def fields(self) -> tuple[Setting, ...]:
        return settings_of(self.settings or self.factory)

    @property
    def summary(self) -> str:
        """The first paragraph of the settings' (or factory's) docstring, on one line."""
        text = (self.settings or self.factory).__doc__ or ""
        return " ".join(text.strip().split("\n\n")[0].split())

    def settings_of(self, values: Mapping[str, Any]) -> Any:
        """What `check` is given: the settings dataclass built from plain ``values``; for a factory function, its
        settings as attributes (missing ones at their defaults)."""
        values = {k: v for k, v in values.items() if k != "_target_"}
        if self.settings is None and not dataclasses.is_dataclass(self.factory):
            return SimpleNamespace(**{s.name: from_plain(s.hint, values.get(s.name, s.default)) for s in self.fields})
        return from_plain(self.settings or self.factory, values)

    def build(self, values: Mapping[str, Any], configure: bool = False, **needed: Any) -> Any:
        """The component from plain setting ``values`` (missing ones take their defaults; ``_target_``, which
        names the component in a config, is passed over)."""
        unknown = set(values) - {s.name for s in self.fields} - {"_target_"}
        if unknown:
            raise TypeError(f"{self.kind}={self.name} has no setting {', '.join(sorted(unknown))}")
        if self.settings is not None:
            return self.factory(from_plain(self.settings, values), **needed)
        arguments = {s.name: from_plain(s.hint, values[s.name]) for s in self.fields if s.name in values}
        if configure:
            return Configured(self.name, self.factory, arguments)
        return self.factory(**arguments, **needed)


@dataclass(frozen=True)
class Configured:
    """A registered function with its settings bound: ``configured(*inputs)`` calls it."""

    name: str
    function: Callable[..., Any]
    settings: Mapping[str, Any] = field(default_factory=dict)

    def __call__(self, *inputs: Any) -> Any:
        return self.function(*inputs, **self.settings)


class Registry:
    """The components of one kind, by name, in registration order."""

    def __init__(self, kind: str, configure: bool = False) -> None:
        self.kind = kind
        self.configure = configure  # build functions with their settings bound, not called
        self._entries: dict[str, Entry] = {}
        REGISTRIES[kind] = self

    def register(self, name: str, factory: Callable[..., Any] | None = None, **traits: Any):
        """Register ``factory`` under ``name`` (or, without it, return a decorator that does)."""

        models = traits.get("models")
        if models is not None and not isinstance(models, Mapping):  # names alone: any number of views
            traits["models"] = {model: Fit() for model in models}

        def add(factory: Callable[..., Any]) -> Callable[..., Any]:
            entry = Entry(self.kind, name, factory, **traits)
            known = self._entries.get(name)
            if known is not None and known.target != entry.target:
                raise ValueError(f"{self.kind} {name!r} is registered already, by {known.target}")
            self._entries[name] = entry
            return factory

        return add if factory is None else add(factory)

    def __getitem__(self, name: str) -> Entry:
        if name not in self._entries:
            raise KeyError(f"{self.kind}={name}: no such {self.kind}, allowed {', '.join(self.names())}")
        return self._entries[name]

    def __contains__(self, name: str) -> bool:
        return name in self._entries

    def __iter__(self):
        return iter(self._entries.values())

    def names(self) -> list[str]:
        return list(self._entries)

    def entry_for(self, target: str) -> Entry | None:
        """The entry whose factory is ``target`` (an option's ``_target_``), or None."""
        return next((entry for entry in self._entries.values() if entry.target == target), None)

    def build(self, name: str, values: Mapping[str, Any], **needed: Any) -> Any:
        return self[name].build(values, self.configure, **needed)

    def defaults(self, name: str) -> Any:
        """The component built from its default settings."""
        return self.build(name, {})


REGISTRIES: dict[str, Registry] = {}
MODELS = Registry("model")
SCENES = Registry("scene")
RIGS = Registry("rig")
TRACKERS = Registry("tracker")
COSTS = Registry("cost", configure=True)
MOTION_MODELS = Registry("motion")


def chosen_entries(config: Mapping[str, Any]) -> dict[str, Entry]:
    """Kind -> the registered component each chosen option of a plain run config builds (named by its
    ``_target_``); kinds the config leaves out (a tracker without a cost) are left out. Raises ``ValueError`` for
    a ``_target_`` no component is registered under."""
    entries = {}
    for kind, registry in REGISTRIES.items():
        node = config.get(kind)
        if node is None:
            continue
        entry = registry.entry_for(node.get("_target_", ""))
        if entry is None:
            known = ", ".join(e.target for e in registry)
            raise ValueError(f"{kind}._target_={node.get('_target_')}: no registered {kind}, allowed {known}")
        entries[kind] = entry
    return entries


def build_chosen(config: Mapping[str, Any]) -> dict[str, Any]:
    """Kind -> each chosen component of a plain run config, built through the registries from its settings (the
    tracker given the components it needs: a cost, a motion model)."""
    entries = chosen_entries(config)
    built = {
        kind: entry.build(config[kind], REGISTRIES[kind].configure)
        for kind, entry in entries.items()
        if kind != "tracker"
    }
    tracker = entries["tracker"]
    built["tracker"] = tracker.build(config["tracker"], **{kind: built[kind] for kind in tracker.needs})
    return built
