"""The DSQ arm as tree-based filtering sees it (``model=dsq_arm tracker=tbf``): a dictionary of arm poses over a
grid of chosen parameters, rendered as part labels per view as the body's samples are (`tracker.tbf.sample_build`).

A pose vector holds the grid's axes in their order (`ArmGridSpec.axes`): each one parameter of one part, an angle
(r1..r3, radians; given in degrees) or a length (the bends b1, b2 and any other, metres). Every other parameter
stays at the arm's rest shape; the root's bottom pole sits at ``shoulder`` and each child hangs from its parent's
top pole (`tracker.models.dsq_arm.DSQArm.connect`), so a pose vector gives the whole ``(parts, 17)`` parameters the
arm's evaluation reads. The motion models walk the vector with ``sigma`` on its angles and ``sigma_root_m`` on its
lengths (`ArmDictionary.space`); DM2 widens the axes of an occluded part.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

from tracker.geometry.rotations import euler_to_matrix, transform_points
from tracker.models.articulated import jointed_translation
from tracker.models.dsq import ANGLE_NAMES, PARAM_INDEX, dsq_points, pole_point
from tracker.models.dsq_arm import DSQArm
from tracker.ranges import Span, Vector3
from tracker.settings import to_plain
from tracker.tbf.motion import PoseSpace
from tracker.tbf.sample_spec import span_values

_C = slice(PARAM_INDEX["c1"], PARAM_INDEX["c3"] + 1)
_R = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)


@dataclass(frozen=True)
class ArmAxis:
    """One axis of the grid: a part's parameter over ``[start, stop, step]`` (degrees for r1..r3, else the
    parameter's own unit), stop included; start = stop holds it at that value."""

    part: str
    param: Literal["r1", "r2", "r3", "b1", "b2", "b3", "t1", "t2"]
    span: Span


@dataclass(frozen=True)
class ArmGridSpec:
    """The arm's pose samples: every combination of the axes' values. The default spans paper 1's arm as it moves
    (the upper arm held along +x and swaying about the vertical, the elbow from straight to 80°, the forearm bent
    both ways, the hand rocking): 4,725 poses."""

    axes: tuple[ArmAxis, ...] = (
        ArmAxis("upper_arm", "r2", (90.0, 90.0, 1.0)),
        ArmAxis("upper_arm", "r3", (-6.0, 6.0, 3.0)),
        ArmAxis("forearm", "r2", (0.0, 80.0, 4.0)),
        ArmAxis("forearm", "b1", (-0.04, 0.04, 0.02)),
        ArmAxis("hand", "r1", (-24.0, 24.0, 6.0)),
    )
    shoulder: Vector3 = (0.0, 0.0, 0.0)  # where the upper arm's bottom pole sits


def axis_values(axis: ArmAxis) -> np.ndarray:
    """The axis' values in the pose vector's units (radians for angles)."""
    values = span_values(axis.span)
    return np.radians(values) if axis.param in ANGLE_NAMES else values


@dataclass(eq=False)
class ArmDictionary:
    """Pose vectors of ``arm`` over ``spec``'s axes, and the arm's surface as the label renderer takes it (one mesh
    of every part's faces, each face labelled by its part), as `tracker.models.body_mesh.BodyMesh` offers it."""

    arm: DSQArm
    spec: ArmGridSpec = field(default_factory=ArmGridSpec)

    def __post_init__(self) -> None:
        names = self.arm.part_names
        for k, axis in enumerate(self.spec.axes):
            if axis.part not in names:
                raise ValueError(
                    f"tracker.arm_samples.axes[{k}].part={axis.part}: no such part, allowed {', '.join(names)}"
                )
        self._axes = [(names.index(axis.part), PARAM_INDEX[axis.param]) for axis in self.spec.axes]
        self._rest = self.arm.rest_params()

    @property
    def part_names(self) -> tuple[str, ...]:
        return self.arm.part_names

    @cached_property
    def space(self) -> PoseSpace:
        lengths = tuple(k for k, axis in enumerate(self.spec.axes) if axis.param not in ANGLE_NAMES)
        parts = tuple(
            tuple(k for k, (part, _) in enumerate(self._axes) if part == index) for index in range(len(self.part_names))
        )
        return PoseSpace(len(self._axes), lengths, parts)

    def poses(self) -> np.ndarray:
        """``(n, axes)``: every combination of the axes' values, the first axis slowest."""
        return np.array(list(itertools.product(*(axis_values(axis) for axis in self.spec.axes))), dtype=np.float64)

    def params(self, pose: np.ndarray) -> np.ndarray:
        """``(parts, 17)``: the arm at ``pose``, the root's bottom pole on the shoulder, the joints connected."""
        params = self._rest.copy()
        for value, (part, index) in zip(pose, self._axes, strict=True):
            params[part, index] = value
        root_rotation = euler_to_matrix(params[0, _R])
        params[0, _C] = jointed_translation(
            root_rotation, np.asarray(self.spec.shoulder, dtype=np.float64), pole_point(params[0], top=False)
        )
        return self.arm.connect(params)

    def pose_of(self, params: np.ndarray) -> np.ndarray:
        """The pose vector of ``(parts, 17)`` parameters (the axes' values read off)."""
        return np.array([params[part, index] for part, index in self._axes], dtype=np.float64)

    # The label renderer's view of the arm (`tracker.tbf.sample_build`).
    @cached_property
    def faces(self) -> np.ndarray:
        faces, count = self.arm.topology.faces, len(self.arm.topology.eta)
        return np.concatenate([faces + k * count for k in range(len(self.part_names))])

    @cached_property
    def face_parts(self) -> np.ndarray:
        return np.repeat(np.arange(len(self.part_names)), len(self.arm.topology.faces))

    @cached_property
    def rest_vertices(self) -> np.ndarray:
        return self.posed_vertices(self.poses()[:1])[0]

    closed = False  # a DSQ mesh's poles and seam repeat vertices: its faces are drawn from both sides

    @cached_property
    def source_key(self) -> str:
        """Names the arm's surfaces in caches: its parts' shapes, its mesh, the axes and the shoulder."""
        text = json.dumps(
            {
                "parts": [to_plain(part.shape) for part in self.arm.parts],
                "mesh": to_plain(self.arm.mesh),
                "spec": to_plain(self.spec),
            }
        )
        return "dsq-" + hashlib.sha256(text.encode()).hexdigest()[:16]

    def posed_vertices(self, poses: np.ndarray) -> np.ndarray:
        """``(n, vertices, 3)``: every part's render mesh at each pose, parts one after the other."""
        topology = self.arm.topology
        out = []
        for pose in poses:
            params = self.params(pose)
            world = self.arm.world_transforms(params)
            out.append(
                np.concatenate(
                    [
                        transform_points(world[k], dsq_points(params[k], topology.eta, topology.omega))
                        for k in range(len(self.part_names))
                    ]
                )
            )
        return np.array(out)
