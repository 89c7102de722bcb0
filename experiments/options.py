"""The table of config options (docs/configuration.md) and the compatibility table (README.md), made from the option
files and the registrations: ``python -m experiments.options`` prints them; ``--write`` puts them between their
markers (`experiments.generated`).

One row per option file ``conf/<group>/<option>.yaml``: the component it builds (`tracker.registry`), what that
component is (the first line of its docstring), its settings, and what it goes with (models, needs). Then which
tracker tracks which model from how many camera views, and what it needs there (each tracker's registered
`tracker.registry.Fit`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from omegaconf import OmegaConf

from experiments.generated import DOCS, README, write_block
from experiments.schemas import CONFIG_DIR, GROUPS, SCHEMA_PREFIX
from tracker.registry import MODELS, REGISTRIES, TRACKERS, Entry, Fit


def option_entries() -> list[tuple[str, str, Entry]]:
    """(group, option, the component it builds) for every option file, in group order."""
    return [
        (group, path.stem, REGISTRIES[group][_schema_of(path)])
        for group in GROUPS
        for path in sorted((CONFIG_DIR / group).glob("*.yaml"))
    ]


def _schema_of(path) -> str:
    """The component an option file builds: its schema's (``schema_mono``, ``/model/schema_x@model``), or, for an
    option that extends another of its group (``rig=body_multi_vga``: ``defaults: [body_multi]``), that one's."""
    defaults = [str(item) for item in OmegaConf.load(path).get("defaults", []) if str(item) != "_self_"]
    schema = next((item for item in defaults if SCHEMA_PREFIX in item), None)
    if schema is not None:
        return schema.split(SCHEMA_PREFIX)[1].split("@")[0]
    return _schema_of(path.with_name(f"{defaults[0]}.yaml"))


def goes_with(entry: Entry) -> str:
    parts = []
    if entry.models:
        parts.append("model=" + "\\|".join(entry.models))
    parts += [f"{group}=…" for group in entry.needs]
    return ", ".join(parts)


def compatibility_table() -> str:
    """Trackers by models: the camera views each combination uses, and the rig and settings it needs; — where it
    makes no sense."""
    models = MODELS.names()
    lines = ["| tracker | " + " | ".join(f"`model={m}`" for m in models) + " |", "|---" * (len(models) + 1) + "|"]
    for tracker in TRACKERS:
        fits = tracker.models or dict.fromkeys(models, Fit())
        cells = [_fit_cell(fits[m]) if m in fits else "—" for m in models]
        lines.append(f"| `tracker={tracker.name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _fit_cell(fit: Fit) -> str:
    needs = ([f"`rig={fit.rig}`"] if fit.rig else []) + [f"`{key}={value}`" for key, value in fit.settings]
    return fit.says.replace(" camera", "") + (", with " + " ".join(needs) if needs else "")


def table() -> str:
    lines = ["| group | option | builds | what it is | settings | goes with |", "|---|---|---|---|---|---|"]
    for group, option, entry in option_entries():
        settings = ", ".join(f"`{s.name}`" for s in entry.fields) or "none"
        lines.append(f"| `{group}` | `{option}` | `{entry.name}` | {entry.summary} | {settings} | {goes_with(entry)} |")
    return "\n".join(lines)


COMMAND = "python -m experiments.options --write"
CONFIGURATION = DOCS / "configuration.md"


def write() -> list[Path]:
    """The option table into docs/configuration.md and the compatibility table into the README."""
    write_block(CONFIGURATION, "options", COMMAND, table())
    write_block(README, "compatibility", COMMAND, compatibility_table())
    return [CONFIGURATION, README]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", action="store_true", help="write the tables into docs/configuration.md, README.md")
    if parser.parse_args().write:
        for path in write():
            print(f"wrote {path}")
    else:
        print(table(), compatibility_table(), sep="\n\n")


if __name__ == "__main__":
    main()
