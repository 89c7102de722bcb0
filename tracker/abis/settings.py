"""AbIS's settings (paper 1's Analysis-by-Image-Synthesis), for the arm of deformable superquadrics and the skinned
body alike (`tracker.abis.arm_sequence`, `tracker.abis.body_sequence`): what each means, its default and why."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np

from tracker.abis.anchoring import AnchorSettings
from tracker.abis.fitting import FitSettings
from tracker.models.dsq import PARAM_INDEX
from tracker.observe.features import FeatureSettings
from tracker.ranges import NonNegative, Positive, Range


@dataclass(frozen=True)
class InitialNoise:
    """Frame 0's estimate is the truth plus Gaussian noise of these sizes (standard deviations): the paper aligns
    the model with a user's help."""

    translation_m: NonNegative = 0.003  # root position
    rotation_rad: NonNegative = 0.01  # every part's r
    scale_fraction: NonNegative = 0.01  # every part's a, relative


@dataclass(frozen=True)
class PriorSigmas:
    """How much each parameter may plausibly change from one frame to the next (one sigma; inf: unconstrained).

    One pixel of image residual weighs as much as one sigma of change (`tracker.abis.fitting.Prior`).
    """

    scale: Positive = 0.002  # a (m) and a1..a3
    roundness: Positive = 0.01  # eps1, eps2
    tapering: Positive = 0.01  # t1, t2
    # b1 (m), b2, b3. Bending trades against the rotation about the joint (both swing the far end), so a loose
    # prior lets b1 wander with r. 5 mm is a little above the arm-swing scene's fastest b1 change (3.9 mm/frame).
    bending: Positive = 0.005
    translation_m: Positive = 0.01  # the root's c
    rotation_rad: Positive = 0.1  # r

    def vector(self) -> np.ndarray:
        groups = {
            "scale": ("a", "a1", "a2", "a3"),
            "roundness": ("eps1", "eps2"),
            "tapering": ("t1", "t2"),
            "bending": ("b1", "b2", "b3"),
            "translation_m": ("c1", "c2", "c3"),
            "rotation_rad": ("r1", "r2", "r3"),
        }
        sigmas = np.full(len(PARAM_INDEX), np.inf)
        for group, names in groups.items():
            sigmas[[PARAM_INDEX[name] for name in names]] = getattr(self, group)
        return sigmas


@dataclass(frozen=True)
class AbisSettings:
    """Paper 1's Analysis-by-Image-Synthesis: KLT features, z-buffer visibility, pairs, top-down fitting."""

    fit: FitSettings = field(default_factory=lambda: FitSettings(huber_px=1.0))
    features: FeatureSettings = field(default_factory=FeatureSettings)
    prior: PriorSigmas | None = field(default_factory=PriorSigmas)  # None: eq 8 alone
    pairing_radius_px: Positive = 2.0  # a feature pairs with the nearest visible sample within this
    refined_tolerance_px: Positive = 0.5  # ... and keeps the pair if its own point then lies this close under it
    # Features this close to a silhouette or occlusion edge do not pair (their window holds the background or
    # another part; 3 px: with pairs anchored to the texture, the forearm's narrow image keeps more of them).
    boundary_margin_px: Annotated[int, Range(0, 50)] = 3
    # The model image predicts occlusion: a pair whose point another part's visible samples come this close to,
    # plus their image motion relative to the point over the last frame, is discarded for occlusion before that
    # part's edge reaches it: its feature's Lucas-Kanade window (`features.window_px`) would straddle two surfaces
    # moving differently, and bottom-up tracking would lose it or slide onto the occluder. No new pair forms this
    # close to an occluding edge either.
    occlusion_margin_px: Annotated[int, Range(0, 50)] = 7
    max_residual_px: Positive = 2.0  # after fitting, a pair farther off is a false match
    # Which samples a view sees: the z-buffer of the estimate (paper 1), or, as bottom-up tracking would, any that
    # faces the camera (the ablation: nothing discarded for occlusion, new pairs on hidden parts too).
    selection: Literal["zbuffer", "none"] = "zbuffer"
    # Pairs anchored where the model's texture says their feature's material point is (None: a new pair's point
    # stays under its feature on the estimate, which carries the estimate's error into the pair).
    anchor: AnchorSettings | None = field(default_factory=AnchorSettings)
    # ... and every pair again every this many frames (a share of them each frame, by feature id), against the
    # features' drift; 0: never
    reanchor_every: Annotated[int, Range(0, 100)] = 3
    initial_noise: InitialNoise = field(default_factory=InitialNoise)
