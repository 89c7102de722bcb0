"""Scenes that drive either model: ``scene=arm_swing`` is paper 1's elbow swing for the DSQ arm and paper 2's
right-arm swing (experiment A) for the body mesh; each keeps its settings in its own block."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tracker.models.body_mesh import BodyMesh
from tracker.motion.arm_swing import ArmSwing
from tracker.motion.body_swing import BodySwing


@dataclass(frozen=True)
class ArmSwingScene:
    arm: ArmSwing
    body: BodySwing

    @classmethod
    def from_config(cls, arm: dict[str, Any], body: dict[str, Any]) -> ArmSwingScene:
        return cls(ArmSwing(**arm), BodySwing(**body))

    def params(self, model: Any, frame: int) -> np.ndarray:
        motion = self.body if isinstance(model, BodyMesh) else self.arm
        return motion.params(model, frame)
