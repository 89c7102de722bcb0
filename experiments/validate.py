"""Check a command line before Hydra runs it: compose every combination a sweep names, check ranges.

Each failure becomes a `ConfigError` whose message is one line: the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import os
import re
import shutil
import tempfile
from pathlib import Path

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, MissingConfigException, OverrideParseException
from omegaconf.errors import (
    ConfigAttributeError,
    ConfigKeyError,
    MissingMandatoryValue,
    OmegaConfBaseException,
    ValidationError,
)

from experiments.checks import ConfigError, check_config, unknown_key
from experiments.schemas import SCHEMA_PREFIX
from tracker.atomic import nearest_folder

# Flags after which Hydra runs nothing (help, printing the config, shell completion): nothing to validate.
_INFORMATIONAL_FLAGS = set(
    "--help -h --hydra-help --cfg -c --info -i --version --shell-completion -sc --resolve --package -p".split()
)
_MULTIRUN_FLAGS = {"--multirun", "-m"}
# Free space a run's folder must have at start (its recording alone is a few MB to tens of MB): on a full disk
# Rerun's file writer stops and waits for ever, so a run there would hang rather than fail.
MIN_FREE_BYTES = 32 * 2**20


def _jobs(argv: list[str]) -> tuple[list[str], bool] | None:
    """The command line's overrides and whether it sweeps; None when Hydra runs no job (help, printing the
    config, shell completion) or handles the flags itself (unknown ones, with its own usage message)."""
    flags = {arg.split("=", 1)[0] for arg in argv if arg.startswith("-")}
    if flags & _INFORMATIONAL_FLAGS or flags - _MULTIRUN_FLAGS:
        return None
    return [arg for arg in argv if not arg.startswith("-")], bool(flags & _MULTIRUN_FLAGS)


def validate_command_line(argv: list[str], config_dir: Path, config_name: str) -> None:
    """Raise `ConfigError` unless every job the command line describes composes and passes `check_config`."""
    if (jobs := _jobs(argv)) is None:
        return
    overrides, multirun = jobs
    if multirun:
        check_sweep_settings(overrides, config_dir, config_name)
    for combination in sweep_combinations(overrides):
        cfg = _compose(config_dir, config_name, combination)
        check_output_dir(
            "hydra.sweep.dir" if multirun else "hydra.run.dir", cfg.hydra.sweep.dir if multirun else cfg.hydra.run.dir
        )
        choices = {k: v for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra") and v is not None}
        for group, option in choices.items():
            if option.startswith(SCHEMA_PREFIX):
                raise ConfigError(
                    f"{group}={option} is a schema, not an option: allowed {', '.join(_options(config_dir, group))}"
                )
        try:
            check_config(cfg, choices)
        except OmegaConfBaseException as error:
            raise ConfigError(_describe(error)) from None


def check_sweep_settings(overrides: list[str], config_dir: Path, config_name: str) -> None:
    """A sweep's settings compose before its swept options: Hydra first composes the command line without them (for
    its own settings), so a setting of an option that only a swept preset or group picks fails there."""
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except OverrideParseException:
        return  # `sweep_combinations` says why, in one line
    swept = [text for override, text in zip(parsed, overrides, strict=True) if override.is_sweep_override()]
    if not swept:
        return
    try:
        _compose(config_dir, config_name, [text for text in overrides if text not in swept])
    except ConfigError as error:
        keys = ", ".join(_key(text) for text in swept)
        raise ConfigError(
            f"{error} (a sweep composes this before its swept {keys}: name the option it belongs to)"
        ) from None


def _key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~")


def check_output_dir(key: str, value: str) -> None:
    """The run's output folder can be made: its nearest existing ancestor is a writable folder."""
    try:
        existing = nearest_folder(value)
    except ValueError as error:
        raise ConfigError(f"{key}={value}: {error}") from None
    try:  # a trial folder, removed at once (permissions alone do not tell: root may not write in /proc either)
        os.rmdir(tempfile.mkdtemp(prefix=".write-check-", dir=existing))
    except OSError as error:
        raise ConfigError(f"{key}={value}: cannot make it, {existing} is not writable ({error.strerror})") from None
    free = shutil.disk_usage(existing).free
    if free < MIN_FREE_BYTES:
        raise ConfigError(
            f"{key}={value}: {existing} has {free / 2**20:.1f} MiB free; a run needs at least "
            f"{MIN_FREE_BYTES / 2**20:.0f} MiB"
        )


def plugins_named(argv: list[str]) -> list[str]:
    """The modules a ``plugins=[a.b,c]`` override names (none without one)."""
    overrides = [arg for arg in argv if not arg.startswith("-") and _key(arg) == "plugins"]
    if not overrides:
        return []
    try:
        value = OverridesParser.create().parse_overrides(overrides)[-1].value()
    except OverrideParseException as error:
        raise ConfigError(f"cannot parse {overrides[-1]!r}: {_first_line(error)}") from None
    modules = value if isinstance(value, list) else [value]
    for module in modules:
        if importlib.util.find_spec(str(module).split(".")[0]) is None:
            raise ConfigError(f"plugins={module}: no such module (it must be importable from here)")
    return [str(module) for module in modules]


def sweep_combinations(overrides: list[str]) -> list[list[str]]:
    """Enough jobs to try every value of every swept key: all first values, then each other value in turn."""
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except OverrideParseException as error:
        raise ConfigError(f"cannot parse the overrides {' '.join(overrides)!r}: {_first_line(error)}") from None
    choices = []
    for override, text in zip(parsed, overrides, strict=True):
        key = text.split("=", 1)[0]
        values = list(override.sweep_string_iterator()) if override.is_sweep_override() else None
        choices.append([f"{key}={value}" for value in values] if values else [text])
    combinations = [[options[0] for options in choices]]
    for index, options in enumerate(choices):
        for option in options[1:]:
            combination = list(combinations[0])
            combination[index] = option
            combinations.append(combination)
    return combinations


def _compose(config_dir: Path, config_name: str, overrides: list[str]):
    try:
        with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
            return compose(config_name, overrides=overrides, return_hydra_config=True)
    except MissingConfigException as error:
        group, _, option = (error.missing_cfg_file or "").rpartition("/")
        options = [o for o in (error.options or []) if not o.startswith(SCHEMA_PREFIX)]
        raise ConfigError(f"{group}={option}: no such option, allowed {', '.join(options)}") from None
    except HydraException as error:
        cause = error.__cause__ or error.__context__  # a user preset's unknown key: the context, not the cause
        message = _describe(cause) if isinstance(cause, OmegaConfBaseException) else _first_line(error)
        where = re.match(r"In '([^']+)'", str(error))
        raise ConfigError(f"{where.group(1)}.yaml: {message}" if where else message) from None
    except yaml.YAMLError as error:  # a user's YAML that does not parse
        raise ConfigError(_yaml_problem(error)) from None


def _yaml_problem(error: yaml.YAMLError) -> str:
    """Where a YAML file stops parsing and why, in one line (where what failed began, e.g. an unclosed bracket)."""
    mark = getattr(error, "context_mark", None) or getattr(error, "problem_mark", None)
    problem = getattr(error, "problem", None) or _first_line(error)
    if mark is None:
        return f"a YAML file does not parse: {problem}"
    context = getattr(error, "context", None)
    why = f"{context}: {problem}" if context else problem
    return f"{mark.name}, line {mark.line + 1}, column {mark.column + 1}: not valid YAML, {why}"


def _describe(error: OmegaConfBaseException) -> str:
    key = getattr(error, "full_key", None) or getattr(error, "key", None) or "?"
    schema = getattr(error, "object_type", None)
    if isinstance(error, (ConfigAttributeError, ConfigKeyError)) and dataclasses.is_dataclass(schema):  # unknown key
        return unknown_key(key, schema)
    if isinstance(error, MissingMandatoryValue):
        return f"{key}: missing value, it is required (add {key}=...)"
    if isinstance(error, ValidationError) and dataclasses.is_dataclass(schema):  # a value where settings belong
        expected = next((f.type for f in dataclasses.fields(schema) if f.name == getattr(error, "key", None)), None)
        if dataclasses.is_dataclass(expected):
            names = [f.name for f in dataclasses.fields(expected) if not f.name.startswith("_")]
            return (
                f"{key}={getattr(error, 'value', '?')}: expects its settings ({', '.join(names)}), not a "
                f"value; set one, e.g. {key}.{names[0]}=..."
            )
    message = getattr(error, "msg", None) or str(error)
    return f"{key}: {message.strip().splitlines()[0] if message.strip() else type(error).__name__}"


def _options(config_dir: Path, group: str) -> list[str]:
    return sorted(path.stem for path in (config_dir / group).glob("*.yaml"))


def _first_line(error: BaseException) -> str:
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
