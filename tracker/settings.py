"""Settings: the keyword arguments a component is built from, with their defaults and allowed values in one place.

A component's settings are the init fields of its settings dataclass, or the keyword-only parameters of its
factory function. Each setting's type says what it allows (`tracker.ranges`): ``Annotated[float, Range(...)]``,
``Literal["sd", "lm"]``, ``tuple[X, X, X]`` (exactly three) or ``tuple[X, ...]`` (any number), ``X | None``, or a
nested settings dataclass. From that one declaration:

- `check` raises ``ValueError`` with one line naming the key, the value and what is allowed;
- `from_plain` turns plain values (as a config file gives them: lists, mappings) into the declared types;
- the experiment layer derives the config schema of every option (`experiments.schemas`).

A settings dataclass calls `validate(self)` in its ``__post_init__`` to check itself the same way.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import functools
import inspect
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union

from tracker.ranges import Range, Rule, check_in_range

REQUIRED = dataclasses.MISSING  # the default of a setting without one


@dataclass(frozen=True)
class Setting:
    """One keyword argument: its name, its type (with what it allows) and its default (`REQUIRED` for none)."""

    name: str
    hint: Any
    default: Any

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@functools.cache
def settings_of(factory: Callable[..., Any]) -> tuple[Setting, ...]:
    """The settings of a dataclass (its init fields) or of a function (its keyword-only parameters)."""
    hints = typing.get_type_hints(factory, include_extras=True)
    if dataclasses.is_dataclass(factory):
        return tuple(Setting(f.name, hints[f.name], _field_default(f)) for f in dataclasses.fields(factory) if f.init)
    parameters = inspect.signature(factory).parameters.values()
    return tuple(
        Setting(p.name, hints.get(p.name, Any), REQUIRED if p.default is p.empty else p.default)
        for p in parameters
        if p.kind is p.KEYWORD_ONLY
    )


def _field_default(spec: dataclasses.Field) -> Any:
    if spec.default is not dataclasses.MISSING:
        return spec.default
    if spec.default_factory is not dataclasses.MISSING:
        return spec.default_factory()
    return REQUIRED


def validate(instance: Any) -> None:
    """Check a settings dataclass instance against its fields' types (call from ``__post_init__``)."""
    for setting in settings_of(type(instance)):
        check(setting.hint, getattr(instance, setting.name), setting.name)


def check_values(settings: tuple[Setting, ...], values: Mapping[str, Any], prefix: str = "") -> None:
    """Check plain ``values`` (missing keys take their defaults) against ``settings``; keys read ``prefix + name``."""
    for setting in settings:
        if setting.name in values:
            check(setting.hint, values[setting.name], prefix + setting.name)


def check(hint: Any, value: Any, key: str) -> None:
    """Raise ``ValueError`` unless ``value`` is allowed by ``hint`` (see the module docstring)."""
    hint, ranges = _unannotated(hint)
    origin, arguments = typing.get_origin(hint), typing.get_args(hint)
    if value is None:
        if not _optional(hint):
            raise ValueError(f"{key}=None is not allowed: a value is required")
        return
    if origin in (Union, types.UnionType):
        check(next(a for a in arguments if a is not type(None)), value, key)
    elif origin is Literal:
        if value not in arguments:
            raise ValueError(f"{key}={value!r} is not allowed: allowed {', '.join(map(str, arguments))}")
    elif dataclasses.is_dataclass(hint):
        values = value if isinstance(value, Mapping) else to_plain(value)
        check_values(settings_of(hint), values, f"{key}.")
    elif origin in (tuple, list, collections.abc.Sequence):
        _check_items(hint, list(value), key)
    for allowed in ranges:
        if isinstance(allowed, Rule):
            if not allowed.holds(value):
                raise ValueError(f"{key}={_plain_repr(value)} is not allowed: {allowed.says}")
        else:
            check_in_range(key, value, allowed)


def _check_items(hint: Any, items: list, key: str) -> None:
    arguments = typing.get_args(hint)
    fixed = typing.get_origin(hint) is tuple and Ellipsis not in arguments
    if fixed and len(items) != len(arguments):
        raise ValueError(f"{key}={items!r} has {len(items)} values: allowed exactly {len(arguments)}")
    for index, item in enumerate(items):
        check(arguments[index] if fixed else arguments[0], item, f"{key}[{index}]")


def from_plain(hint: Any, value: Any) -> Any:
    """``value`` (plain: numbers, strings, lists, mappings) as the type ``hint`` declares: nested settings
    dataclasses built, sequences as tuples, integers as floats where floats are declared."""
    hint, _ = _unannotated(hint)
    origin, arguments = typing.get_origin(hint), typing.get_args(hint)
    if value is None:
        return None
    if origin in (Union, types.UnionType):
        return from_plain(next(a for a in arguments if a is not type(None)), value)
    if dataclasses.is_dataclass(hint):
        if isinstance(value, hint):
            return value
        return hint(**{s.name: from_plain(s.hint, value[s.name]) for s in settings_of(hint) if s.name in value})
    if origin in (tuple, list, collections.abc.Sequence):
        fixed = origin is tuple and Ellipsis not in arguments
        return tuple(from_plain(arguments[k] if fixed else arguments[0], item) for k, item in enumerate(value))
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def to_plain(value: Any) -> Any:
    """A settings value as plain data: dataclasses as dicts of their init fields, tuples as lists."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {s.name: to_plain(getattr(value, s.name)) for s in settings_of(type(value))}
    if isinstance(value, tuple | list):
        return [to_plain(item) for item in value]
    return value


def allowed_ranges(hint: Any) -> list[Range]:
    """The ranges an ``Annotated`` type declares (none for other types)."""
    return [allowed for allowed in _unannotated(hint)[1] if isinstance(allowed, Range)]


def _unannotated(hint: Any) -> tuple[Any, list[Range | Rule]]:
    if typing.get_origin(hint) is Annotated:
        return hint.__origin__, [m for m in hint.__metadata__ if isinstance(m, Range | Rule)]
    return hint, []


def _plain_repr(value: Any) -> str:
    return repr(list(value)) if isinstance(value, tuple) else repr(value)


def _optional(hint: Any) -> bool:
    return hint is Any or (typing.get_origin(hint) in (Union, types.UnionType) and type(None) in typing.get_args(hint))
