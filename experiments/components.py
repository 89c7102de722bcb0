"""What a run is made of, built from a composed config through the registries (the benchmarks build the same way).

`build` turns each chosen option into its component (`tracker.registry`): the model, the scene (the truth
motion), the rig's cameras and the tracker, which receives the components it needs (a cost, a motion model).
`compose` gives the config of a command line without running it.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from hydra import compose as hydra_compose
from hydra import initialize_config_dir
from omegaconf import DictConfig, OmegaConf

from experiments.checks import without_hydra
from experiments.schemas import CONFIG_DIR, CONFIG_NAME, RUN_SETTINGS, RunSettings, register_schemas
from tracker.evaluation import evaluation_of
from tracker.geometry.cameras import Camera
from tracker.protocol import Model, Scene, Tracker
from tracker.registry import Entry, build_chosen, chosen_entries
from tracker.settings import from_plain


@dataclass(frozen=True)
class Components:
    model: Model
    scene: Scene
    cameras: tuple[Camera, ...]
    tracker: Tracker
    entries: dict[str, Entry]  # group -> the registered component chosen
    settings: RunSettings  # frames, seed, the synthetic camera, silhouettes, the recording

    @property
    def views(self) -> list[str]:
        return [camera.name for camera in self.cameras]

    @property
    def observes(self) -> set[str]:
        """What the run captures for the model and the tracker (e.g. "silhouettes")."""
        return {kind for group in ("model", "tracker") for kind in self.entries[group].observes}

    @property
    def evaluation(self) -> Any:
        """How the model's estimates are judged (`tracker.evaluation`), or None."""
        return evaluation_of(self.entries["model"].name)


def build(cfg: DictConfig) -> Components:
    plain = OmegaConf.to_container(without_hydra(cfg), resolve=True)
    import_plugins(plain.get("plugins", ()))
    built = build_chosen(plain)
    return Components(
        model=built["model"],
        scene=built["scene"],
        cameras=tuple(built["rig"]),
        tracker=built["tracker"],
        entries=chosen_entries(plain),
        settings=from_plain(RunSettings, {s.name: plain[s.name] for s in RUN_SETTINGS}),
    )


def import_plugins(modules: Iterable[str]) -> None:
    """Import the modules that register components of their own, and give those components their schemas."""
    modules = [module for module in modules if module]
    for module in modules:
        importlib.import_module(module)
    if modules:
        register_schemas()


def compose(overrides: Sequence[str] = ()) -> DictConfig:
    """The config a command line with ``overrides`` runs (with ``hydra``'s own node, for its choices)."""
    with initialize_config_dir(config_dir=str(CONFIG_DIR), version_base="1.3"):
        return hydra_compose(CONFIG_NAME, overrides=list(overrides), return_hydra_config=True)


def choices_of(cfg: DictConfig) -> dict[str, str]:
    """Group -> option of a composed config (Hydra's own groups left out)."""
    return {k: v for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra") and v is not None}
