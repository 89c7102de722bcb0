"""What composition cannot check, before a run: allowed values, which options go together, components' own checks.

Every rule comes from the registrations (`tracker.registry`): a setting's allowed values from its type, the models a
component goes with (for a tracker, from how many camera views and with what: `tracker.registry.Fit`) and the
tracker's needs. Each failure is a `ConfigError` whose message is one line naming the key, the value and what is
allowed, or what to add.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf, open_dict

from experiments.schemas import RUN_SETTINGS
from tracker.registry import REGISTRIES, Entry, chosen_entries
from tracker.settings import check_values


class ConfigError(ValueError):
    """An invalid configuration; the message is one line naming the key, the value and what is allowed."""


def check_config(cfg: DictConfig, choices: dict[str, str]) -> None:
    """Raise `ConfigError` unless the composed ``cfg`` (Hydra's ``choices``: group -> option) can run."""
    run_cfg = without_hydra(cfg)
    check_known_keys(run_cfg)
    plain = OmegaConf.to_container(run_cfg, resolve=True, throw_on_missing=True)
    try:
        check_values(RUN_SETTINGS, plain)  # first: a component's value may be one of these (${seed})
        entries = chosen_entries(plain)
        for group, entry in entries.items():
            check_values(entry.fields, plain[group], f"{group}.")
        for group, entry in entries.items():
            if entry.check is not None:
                entry.check(
                    entry.settings_of(plain[group]), frames=plain["frames"], key=group, model=entries["model"].name
                )
        check_combination(entries, choices, plain)
    except ValueError as error:
        raise ConfigError(str(error).splitlines()[0]) from None


def without_hydra(cfg: DictConfig) -> DictConfig:
    """The run's own config: a composed config without Hydra's node (a copy that keeps the schema types)."""
    run_cfg = cfg.copy()
    with open_dict(run_cfg):
        run_cfg.pop("hydra", None)
    return run_cfg


def _dotted(plain: dict[str, Any], key: str) -> Any:
    """The value at a dotted ``key`` (``model.texture_seed``) of a plain config; None where any step is missing."""
    for step in key.split("."):
        plain = plain.get(step) if isinstance(plain, dict) else None
    return plain


def check_combination(entries: dict[str, Entry], choices: dict[str, str], plain: dict[str, Any]) -> None:
    """The chosen options go together: each goes with the model, the tracker tracks it from the rig's number of
    views with what its fit needs set (`tracker.registry.Fit`), and it has what it needs and nothing it does not."""
    model, tracker = entries["model"].name, entries["tracker"]
    for group, entry in entries.items():
        if entry.models is not None and model not in entry.models:
            allowed = "|".join(entry.models)
            if group == "tracker":
                raise ValueError(f"tracker={tracker.name} does not track model={model}: allowed model={allowed}")
            raise ValueError(f"{group}={choices[group]} needs model={allowed}, not model={choices['model']}")
    fit = None if tracker.models is None else tracker.models[model]
    try:
        cameras = entries["rig"].build(plain["rig"])
    except ValueError as error:  # a camera that cannot be built
        raise ValueError(f"rig={choices['rig']}: {error}") from None
    views = len(cameras)
    width, height = tracker.min_image
    for camera in cameras:
        if camera.width < width or camera.height < height:
            raise ValueError(
                f"rig={choices['rig']}: camera {camera.name} is {camera.width}x{camera.height}, "
                f"tracker={tracker.name} needs at least {width}x{height} (set rig.width and rig.height)"
            )
    combination = f"tracker={choices['tracker']} tracks model={choices['model']}"
    if fit is not None and not fit.allows(views):
        advice = f"; add {fit.advice()}" if fit.rig else ""
        raise ValueError(f"{combination} from {fit.says}: rig={choices['rig']} has {views}{advice}")
    unset = [(key, value) for key, value in (fit.settings if fit else ()) if _dotted(plain, key) is None]
    if unset:
        keys = " and ".join(key for key, _ in unset)
        raise ValueError(f"{combination} with {keys} set: add {' '.join(f'{k}={v}' for k, v in unset)}")
    missing = [group for group in tracker.needs if group not in entries]
    if missing:
        allowed = ", ".join(f"{group}={'|'.join(REGISTRIES[group].names())}" for group in missing)
        add = " ".join(f"{group}={tracker.needs[group]}" for group in missing)
        raise ValueError(f"tracker={choices['tracker']} needs {' and '.join(missing)}: add {add} (allowed {allowed})")
    for group in entries.keys() - {"model", "scene", "rig", "tracker"} - tracker.needs.keys():
        users = [e.name for e in REGISTRIES["tracker"] if group in e.needs]
        raise ValueError(
            f"{group}={choices[group]} serves {' and '.join(f'tracker={u}' for u in users)} only, "
            f"not tracker={choices['tracker']}: add tracker={users[0]}"
        )


def unknown_key(key: str, schema: type) -> str:
    """The message for a key that the dataclass ``schema`` does not have."""
    known = [spec.name for spec in dataclasses.fields(schema) if not spec.name.startswith("_")]
    return f"{key}: unknown key, allowed keys here: {', '.join(known) or 'none'}"


def check_known_keys(node: Any, path: str = "") -> None:
    """Reject keys a schema does not have (Hydra lets ``+key=value`` append them to a schema-backed node)."""
    if isinstance(node, DictConfig):
        schema = OmegaConf.get_type(node)
        if dataclasses.is_dataclass(schema):
            known = [f.name for f in dataclasses.fields(schema)]
            for key in node:
                if key not in known:
                    raise ConfigError(unknown_key(f"{path}{key}", schema))
        for key in node:
            check_known_keys(node._get_node(key), f"{path}{key}.")
    elif isinstance(node, ListConfig):
        for index in range(len(node)):
            check_known_keys(node._get_node(index), f"{path[:-1]}[{index}].")
