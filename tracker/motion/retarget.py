"""Retargeting a BVH skeleton onto the body's CMU rig (`tracker.models.body_skeleton`): a table per skeleton.

A `Skeleton` names, for every CMU joint of the body, the file's joint whose motion it takes (``sources``): the CMU
joint turns in the world by the same rotation from the T-pose of frame 0 as that joint, ``W_k(t) = G_s(t) G_s(0)^T``
(`tracker.motion.mocap`). Where the two skeletons' T-poses hold a bone differently (the DAZ conversion's arms are
level, the CMU rig's 8 degrees down; its forearm bone points 17 degrees forward), ``rest_bones`` names the bone
in both skeletons and the CMU joint's rotation starts with the smallest rotation taking the rig's T-pose bone onto
the file's (``C_k``): ``W_k(t) = G_s(t) G_s(0)^T C_k``, so every listed bone keeps the file's direction in the
world at every frame (a bone's twist about itself is not measured, and stays the rig's).
A CMU joint the file lacks (the CMU rig's third spine bone, its toe) follows a neighbour (``sources``).

`SKELETONS` holds the known tables; `skeleton_of` picks the one whose joints a file has (first match).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from tracker.models.body_skeleton import JOINT_INDEX, JOINT_NAMES, mirror_name
from tracker.tol import ZERO_LENGTH


@dataclass(frozen=True)
class Skeleton:
    """How one BVH skeleton drives the CMU rig."""

    name: str
    sources: Mapping[str, str]  # CMU joint -> the file's joint it follows (every one of `JOINT_NAMES`)
    leg: tuple[str, str, str]  # the file's hip, knee and ankle joints (metres per file unit: the leg's length)
    # CMU joint -> (CMU joint at its bone's end, the file's bone as (start joint, end joint)): T-poses matched.
    rest_bones: Mapping[str, tuple[str, tuple[str, str]]] = field(default_factory=dict)
    motion_from: int = 1  # the file's first frame of the motion itself (frame 0 is the T-pose)

    def __post_init__(self) -> None:
        missing = [name for name in JOINT_NAMES if name not in self.sources]
        if missing:
            raise ValueError(f"skeleton {self.name}: no source for CMU joints {', '.join(missing)}")

    def joints(self) -> set[str]:
        """The file joints this table reads."""
        bones = {joint for _, bone in self.rest_bones.values() for joint in bone}
        return set(self.sources.values()) | set(self.leg) | bones

    def rest_corrections(
        self, file_t_pose: np.ndarray, names: tuple[str, ...], rig_t_pose: np.ndarray, file_to_body: np.ndarray
    ) -> np.ndarray:
        """``(J, 3, 3)`` each CMU joint's ``C_k`` in the body frame (identity where no bone is matched), from the
        file's joint positions at its T-pose ``(file joints, 3)`` and the rig's ``(J, 3)``."""
        corrections = np.broadcast_to(np.eye(3), (len(JOINT_NAMES), 3, 3)).copy()
        for joint, (end, (start_file, end_file)) in self.rest_bones.items():
            rig = rig_t_pose[JOINT_INDEX[end]] - rig_t_pose[JOINT_INDEX[joint]]
            file = file_to_body @ (file_t_pose[names.index(end_file)] - file_t_pose[names.index(start_file)])
            corrections[JOINT_INDEX[joint]] = smallest_rotation(rig, file)
        return corrections


def smallest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The ``(3, 3)`` rotation about ``a x b`` taking direction ``a`` onto direction ``b``."""
    a, b = np.asarray(a, float) / np.linalg.norm(a), np.asarray(b, float) / np.linalg.norm(b)
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis), float(a @ b)
    if sine < ZERO_LENGTH:
        if cosine > 0:
            return np.eye(3)
        raise ValueError("opposite bone directions: no smallest rotation")
    return Rotation.from_rotvec(axis / sine * np.arctan2(sine, cosine)).as_matrix()


CMU = Skeleton("cmu", {name: name for name in JOINT_NAMES}, ("LeftUpLeg", "LeftLeg", "LeftFoot"))


def _right(name: str) -> str:
    """A left joint's right twin: a CMU joint's by the rig's own naming (`mirror_name`), a DAZ ``l*`` joint's
    ``r*``."""
    if mirror_name(name) != name:
        return mirror_name(name)
    return "r" + name[1:] if name[:1] == "l" and name[1:2].isupper() else name


def _both_sides(table: dict) -> dict:
    """A table of left joints with its mirrored right half added."""

    def mirrored(value):
        return _right(value) if isinstance(value, str) else tuple(mirrored(item) for item in value)

    return {**table, **{_right(key): mirrored(value) for key, value in table.items()}}


# Bruce Hahne's "DAZ-friendly" conversion of the CMU clips: 43 joints rooted at ``hip``, two spine bones, no toes.
# Every file of it eases from its T-pose into the motion over frames 1-8: in all 21 staged clips the joints' mean
# step (root-relative, file units) is up to 15 between frames 1 and 5, then falls to the motion's own by frame 9
# (at most 1.3 in 95 % of each clip's first 120 frames of motion, median 0.12): those frames are the conversion's.
DAZ = Skeleton(
    "daz",
    sources={
        "Hips": "hip",
        "LowerBack": "abdomen",
        "Spine": "chest",
        "Spine1": "chest",
        "Neck": "neck",
        "Neck1": "neck",
        "Head": "head",
        **_both_sides(
            {
                "LHipJoint": "hip",
                "LeftUpLeg": "lThigh",
                "LeftLeg": "lShin",
                "LeftFoot": "lFoot",
                "LeftToeBase": "lFoot",
                "LeftShoulder": "lCollar",
                "LeftArm": "lShldr",
                "LeftForeArm": "lForeArm",
                "LeftHand": "lHand",
                "LeftFingerBase": "lHand",
                "LeftHandIndex1": "lHand",
                "LThumb": "lHand",
            }
        ),
    },
    leg=("lThigh", "lShin", "lFoot"),
    rest_bones=_both_sides(
        {
            "LeftShoulder": ("LeftArm", ("lCollar", "lShldr")),
            "LeftArm": ("LeftForeArm", ("lShldr", "lForeArm")),
            "LeftForeArm": ("LeftHand", ("lForeArm", "lHand")),
            "LeftUpLeg": ("LeftLeg", ("lThigh", "lShin")),
            "LeftLeg": ("LeftFoot", ("lShin", "lFoot")),
        }
    ),
    motion_from=9,
)

SKELETONS = (CMU, DAZ)


def skeleton_of(names: Iterable[str]) -> Skeleton | None:
    """The first of `SKELETONS` whose joints are all among ``names`` (None: no known table fits)."""
    present = set(names)
    return next((skeleton for skeleton in SKELETONS if skeleton.joints() <= present), None)
