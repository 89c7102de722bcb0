"""``scene=arm_swing``: an arm swinging, for either model. Paper 1's elbow swing drives the DSQ arm (`ArmSwing`) and
paper 2's right-arm swing (experiment A) the body (`BodySwing`); each keeps its settings in its own block."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tracker.motion.arm_swing import ArmSwing
from tracker.motion.body_swing import BodySwing
from tracker.registry import SCENES


@SCENES.register("arm_swing", models=("dsq_arm", "body_mesh"))
@dataclass(frozen=True)
class SwingScene:
    """An arm swinging: the DSQ arm's elbow (paper 1) or the body's right arm (paper 2), by the model."""

    arm: ArmSwing = field(default_factory=ArmSwing)
    body: BodySwing = field(default_factory=BodySwing)

    def params(self, model, frame: int) -> np.ndarray:
        swing = {"dsq_arm": self.arm, "body_mesh": self.body}[model.name]
        return swing.params(model, frame)
