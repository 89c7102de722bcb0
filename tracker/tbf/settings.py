"""Tree-based filtering's settings (paper 2, `tracker=tbf`): what each means, its default and why, and the check of
them before a run."""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass, field
from typing import Annotated, Literal

from tracker.atomic import nearest_folder
from tracker.models.makehuman import Triangles
from tracker.motion.mocap import read_body_clip
from tracker.ranges import Finite, Positive, Range
from tracker.tbf.arm_dictionary import ArmGridSpec
from tracker.tbf.build_workers import BuildSettings
from tracker.tbf.chains import ChainSettings
from tracker.tbf.filter import FilterSettings
from tracker.tbf.sample_spec import SampleSpec, clip_files

Share = Annotated[float, Range(0.0, 1.0, low_open=True)]


@dataclass(frozen=True)
class TbfSettings:
    """Paper 2's silhouette tree-based filter: pose samples, a tree of them by silhouette distance, Bayesian
    filtering down the tree with pruning."""

    samples: SampleSpec = field(default_factory=SampleSpec)
    # T_l: XOR distance (fraction of the window) at 80x60, 160x120, 320x240.
    thresholds: tuple[Positive, Positive, Positive] = (0.006, 0.002, 0.001)
    # Or T_l chosen for the sample set at hand: each level holds this share of the samples as nodes
    # (`tracker.tbf.tree.thresholds_for_shares`; the paper's experiment A: 0.203, 0.882, 0.971). Replaces thresholds.
    node_shares: tuple[Share, Share, Share] | None = None
    filter: FilterSettings = field(default_factory=FilterSettings)
    # The estimate: the most probable sample (``map``, the paper's), or the mean of the joint rotations (the root's
    # among them) of the ``mean_of`` most probable samples weighted by their posterior (``mean``, the body's samples
    # only), placed where the most probable sample is: a pose that may lie between the samples. It does not change
    # what the filter does next (its prior comes from its posterior).
    estimate: Literal["map", "mean"] = "map"
    mean_of: Annotated[int, Range(2, 10_000)] = 10
    # Or the end of the best chain of each frame's most likely samples (`tracker.tbf.chains`; with
    # ``filter.jump_share`` 1, a search by the likelihood alone): ``chain.candidates`` > 0; its ``mean``, of the
    # candidates near that end (``chain.mean_radius_m``), weighted by their chains' probabilities.
    chain: ChainSettings = field(default_factory=ChainSettings)
    initial_yaw_deg: Finite = -90.0  # the initial pose: upright, arms down, facing this way (the body faces -y)
    # Frame 0's prior centred on that upright pose (``upright``: paper 2's start), or on the frame-0 pose the run gives,
    # its joint rotations and the root's orientation, in place (``given``: paper 1's user-assisted start, as AbIS
    # starts and the hybrid's ``start_from=initial``). One silhouette does not say whether a person faces the camera
    # or turns his back to it: a wrong start can last the whole clip.
    initial_pose: Literal["upright", "given"] = "upright"
    cache_dir: str = ".cache/tbf"  # sample sets and trees, keyed by everything that affects them
    # How much of a cached sample set is read to trust it: a sampled digest of each array, or every byte.
    cache_check: Literal["sampled", "full"] = "sampled"
    build: BuildSettings = field(default_factory=BuildSettings)  # shards, processes, joblib backend
    body_triangles: Triangles = 4500  # the tracker's model: the standard body (the subject may differ)
    # Which standard body: MakeHuman's base mesh, or the one of `STANDARD_BODIES` nearest to the subject's
    # stature and chest girth, measured on the subject as a tailor would (paper 2, section 7).
    body: Literal["base", "nearest_standard"] = "base"
    # The observed silhouette as it is, or moved by whole pixels so that its feet stand where the samples' do,
    # the estimate's root moved back by as much (`tracker.tbf.alignment`): a person who steps about. Or placed on
    # the floor: scaled by its feet's depth and moved onto the samples' feet, the root estimated on the ground from
    # where the feet stand (`tracker.tbf.alignment.GroundPlacement`): a person who walks about.
    align: Literal["none", "feet", "ground"] = "none"
    # With ``align=ground`` from one camera: every sample scored on the observation as placed on the reference
    # sample's feet (``reference``), or each as if it had been placed on the sample's own anchor, its silhouette's
    # centroid column over its lowest row (``own``; several views always score each sample from its own spot).
    # Placed on one sample's feet, the observation looks like that sample's side (`tracker.tbf.alignment
    # .sample_anchors`): a run stays on whichever side of the camera's depth ambiguity it stands.
    placed_on: Literal["reference", "own"] = "reference"
    # The DSQ arm's pose samples (model=dsq_arm; `tracker.tbf.arm_dictionary`): a grid of its parameters.
    arm_samples: ArmGridSpec = field(default_factory=ArmGridSpec)


def check_cache_dir(folder: str, key: str) -> None:
    """The cache folder is a folder, or can be made one: its nearest existing ancestor is a writable folder."""
    try:
        existing = nearest_folder(folder)
    except ValueError as error:
        raise ValueError(f"{key}={folder}: {error}") from None
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{key}={folder}: {existing} is not writable")


def check_settings(settings: TbfSettings, frames: int, key: str, model: str) -> None:
    """Before a run: the cache folder can be made, Ray is here if it is asked for, every clip the samples come from
    is a readable clip of a known skeleton, and the arm is not placed on a floor."""
    check_cache_dir(settings.cache_dir, f"{key}.cache_dir")
    if settings.build.backend == "ray" and importlib.util.find_spec("ray") is None:
        raise ValueError(f"{key}.build.backend=ray: Ray is not installed here (make ray installs it); allowed loky")
    if model == "dsq_arm" and settings.align != "none":
        raise ValueError(f"{key}.align={settings.align}: the arm stands on no floor, allowed none")
    if settings.placed_on == "own" and settings.align != "ground":
        raise ValueError(
            f"{key}.placed_on=own: the samples' anchors stand on the floor, {key}.align={settings.align} places "
            "nobody there (align=ground does); allowed reference"
        )
    if model == "dsq_arm" and settings.filter.flip_share > 0:
        share = settings.filter.flip_share
        raise ValueError(f"{key}.filter.flip_share={share}: the arm's grid has no flips, allowed 0")
    if settings.chain.candidates > 0 and model == "dsq_arm":
        raise ValueError(
            f"{key}.chain.candidates={settings.chain.candidates}: the arm's grid has no joints to chain, allowed 0"
        )
    if model == "dsq_arm" and settings.estimate != "map":
        raise ValueError(f"{key}.estimate={settings.estimate}: the arm's grid is not averaged, allowed map")
    for index, path, rate in clip_files(settings.samples, key):
        pattern = settings.samples.clips[index]
        read_body_clip(path, f"{key}.samples.clips[{index}]" + (f" ({pattern})" if path != pattern else ""), rate)
