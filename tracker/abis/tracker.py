"""The AbIS tracker (paper 1): features -> pairs -> top-down per-part fitting -> visibility -> pair upkeep, on the
DSQ arm (`tracker.abis.arm_sequence.ArmAbis`) or a body (`tracker.abis.body_sequence.BodyAbis`), whose frame loop
they share (`tracker.abis.frame_steps.AbisSequence`).

Per frame t it sees only the views' RGB images. Frame 0 starts from the initial pose with noise (the paper aligns
the model with a user's help) and pairs features with visible samples. Every later frame:
    1. features are tracked; pairs whose feature was lost are dropped ("lost"), the rest carry over ("tracked");
    2. parts are fitted top-down (root first, each child against its freshly fitted parent), eq 8;
    3. a z-buffer render of the new estimate decides visibility: pairs whose point is now hidden, or that another
       part's edge is about to reach (the model's prediction of occlusion), are discarded ("discarded_occlusion"),
       then pairs whose residual exceeds `max_residual_px` ("discarded_error"); on the arm the rest are anchored
       again to the material point their feature shows (`tracker.abis.anchoring`), against the features' drift;
    4. unpaired features are paired with visible samples not yet taken ("new"), placed under their feature.
``selection=none`` is the ablation of steps 3-4's model image (`tracker.abis.selection`): nothing is discarded for
occlusion, and features pair with samples facing the camera, as bottom-up tracking would.
So per part and view: pairs(t) = pairs(t-1) - lost - discarded_occlusion - discarded_error + new.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from tracker.abis.arm_sequence import ArmAbis
from tracker.abis.body_sequence import BodyAbis
from tracker.abis.frame_steps import AbisResult, AbisSequence
from tracker.abis.settings import AbisSettings
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.models.dsq_arm import DSQArm
from tracker.presentation import STAGES_PANEL, Panel, Presentation, paper_part_first, part_panels
from tracker.protocol import Observation, Tracker
from tracker.registry import TRACKERS, Fit
from tracker.render.offscreen import SceneRenderer

# Paper 1's three orthogonal views, or more; the body by the features of its textured skin, from 3 or 4 views at
# 640x480 (at 320x240 the margins kept from silhouettes and occlusion edges leave too few features to pair).
ABIS_FITS = {
    "dsq_arm": Fit((1, 4)),
    "body_mesh": Fit((3, 4), rig="body_multi_vga", settings=(("model.texture_seed", 0),)),
}
ABIS_LOOK = Presentation(
    panels=lambda parts: [
        *(Panel(f"{part} pairs", f"metrics/correspondences/{part}") for part in paper_part_first(parts)),
        *part_panels("cost (eq 8, px^2)", "metrics/cost", parts),
        STAGES_PANEL,
    ],
    state_colors={
        "tracked": (0, 220, 0),
        "new": (0, 160, 255),
        "discarded": (255, 40, 40),
        "unpaired": (150, 150, 150),
    },
    point_colors={"estimate": (255, 255, 0)},
)


@TRACKERS.register("abis", settings=AbisSettings, models=ABIS_FITS, presentation=ABIS_LOOK)
class AbisTracker(Tracker):
    """`start` with the model, the cameras and the frame-0 pose; then `step` once per frame; `close`."""

    name: ClassVar[str] = "abis"

    def __init__(self, settings: AbisSettings | None = None) -> None:
        self.settings = settings or AbisSettings()
        self._renderer: SceneRenderer | None = None
        self._sequence: AbisSequence | None = None

    def start(
        self, model: DSQArm | BodyMesh, cameras: Sequence[Camera], initial: np.ndarray, rng: np.random.Generator
    ) -> None:
        """Begin a sequence: frame 0's estimate is ``initial`` with the configured `InitialNoise` drawn from ``rng``
        (the paper's user-assisted alignment); after that the tracker sees images only. The arm is tracked by
        `ArmAbis`, a body by `BodyAbis`."""
        if self._renderer is None:
            self._renderer = SceneRenderer(cameras[0].width, cameras[0].height)
        sequence = BodyAbis if isinstance(model, BodyMesh) else ArmAbis
        self._sequence = sequence(self.settings, model, cameras, initial, rng, self._renderer)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def step(self, observation: Observation) -> AbisResult:
        return self._sequence.step(observation)
