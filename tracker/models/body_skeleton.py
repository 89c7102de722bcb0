"""The body's skeleton and conventions (paper 2's model): the CMU joints, the body parts, pose vectors, frames.

Body frame: metres, z up, the body faces -y in its rest pose, +x is the body's left; the feet's lowest point at
rest is z = 0.

Pose vector (``POSE_SIZE`` = 3 + 3 * 31 float64): the root (``Hips``) joint's position in the world (m), then per
joint of `JOINT_NAMES` a rotation vector (axis * angle, radians): the joint's rotation relative to its parent,
measured from the reference T-pose and expressed in the body frame. The zero rotations are the T-pose: arms out
sideways, legs straight down, facing -y, as frame 0 of the CMU clips (`T_POSE_DIRECTIONS`). Joint 0's rotation
is the whole body's orientation.

Parts (`PART_NAMES`): label k + 1 in label images is part k; each takes the faces of its bones (`PART_BONES`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

# The CMU BVH joints in file order (parents first); the rig says LeftHandFinger1 where the BVH says LeftHandIndex1.
JOINT_NAMES = tuple(
    "Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase RHipJoint RightUpLeg RightLeg RightFoot RightToeBase "
    "LowerBack Spine Spine1 Neck Neck1 Head LeftShoulder LeftArm LeftForeArm LeftHand LeftFingerBase LeftHandIndex1 "
    "LThumb RightShoulder RightArm RightForeArm RightHand RightFingerBase RightHandIndex1 RThumb".split()
)
JOINT_INDEX = {name: k for k, name in enumerate(JOINT_NAMES)}
POSE_SIZE = 3 + 3 * len(JOINT_NAMES)

_SIDES = (("Left", "Right"), ("LHip", "RHip"), ("LThumb", "RThumb"))


def mirror_name(name: str) -> str:
    """A joint's mirror twin's name: left <-> right; the spine, head and root are their own."""
    for left, right in _SIDES:
        for this, other in ((left, right), (right, left)):
            if name.startswith(this):
                return other + name[len(this) :]
    return name


MIRROR_JOINTS = tuple(JOINT_INDEX[mirror_name(name)] for name in JOINT_NAMES)  # each joint's twin across x = 0

# Body parts of the label image (value = index + 1) and the bones whose faces they take.
PART_BONES = {
    "head": ("Neck", "Neck1", "Head"),
    "torso": ("LowerBack", "Spine", "Spine1", "LeftShoulder", "RightShoulder"),
    "pelvis": ("Hips", "LHipJoint", "RHipJoint"),
    "left_upper_arm": ("LeftArm",),
    "right_upper_arm": ("RightArm",),
    "left_forearm": ("LeftForeArm",),
    "right_forearm": ("RightForeArm",),
    "left_hand": ("LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb"),
    "right_hand": ("RightHand", "RightFingerBase", "RightHandIndex1", "RThumb"),
    "left_thigh": ("LeftUpLeg",),
    "right_thigh": ("RightUpLeg",),
    "left_shin": ("LeftLeg",),
    "right_shin": ("RightLeg",),
    "left_foot": ("LeftFoot", "LeftToeBase"),
    "right_foot": ("RightFoot", "RightToeBase"),
}
PART_NAMES = tuple(PART_BONES)
FOOT_BONES = ("LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase")  # whose vertices stand on the floor
# Label-image colours (recordings): left parts warm, right parts cool, trunk grey.
PART_COLORS = ((230, 200, 170), (160, 160, 160), (120, 120, 120), (240, 130, 60), (60, 140, 240), (250, 170, 40),
               (40, 190, 230), (250, 210, 0), (0, 220, 200), (200, 80, 80), (80, 80, 200), (230, 110, 110),
               (110, 110, 230), (160, 60, 40), (40, 60, 160))  # fmt: skip

# Bone directions (head to tail, body frame) in the reference T-pose: frame 0 of the CMU clips (subject 69's
# skeleton; the four clips agree within 2 degrees). Bones not listed keep their rest direction.
T_POSE_DIRECTIONS = {
    "LeftUpLeg": (-0.017, 0.0, -1.0), "LeftLeg": (-0.017, 0.0, -1.0), "LeftFoot": (-0.003, -0.98, -0.197),
    "RightUpLeg": (0.017, 0.0, -1.0), "RightLeg": (0.017, 0.0, -1.0), "RightFoot": (0.006, -0.945, -0.327),
    "LeftShoulder": (0.951, 0.07, 0.301), "LeftArm": (0.99, 0.0, -0.139), "LeftForeArm": (0.99, 0.0, -0.139),
    "LeftHand": (0.99, 0.0, -0.139), "RightShoulder": (-0.955, 0.103, 0.276), "RightArm": (-0.99, 0.0, -0.139),
    "RightForeArm": (-0.99, 0.0, -0.139), "RightHand": (-0.99, 0.0, -0.139),
}  # fmt: skip
# The CMU BVH frame (y up, facing +z) in the body frame: x stays, y -> z, z -> -y.
BVH_TO_BODY = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def joint_angle_differences(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., J)`` degrees between the joint rotations of pose vectors ``a`` and ``b`` (broadcast)."""
    qa, qb = joint_quaternions(a), joint_quaternions(b)
    cosine = np.abs(np.einsum("...jk,...jk->...j", qa, qb))
    return np.degrees(2 * np.arccos(np.clip(cosine, 0.0, 1.0)))


def joint_quaternions(poses: np.ndarray) -> np.ndarray:
    """``(..., J, 4)`` each joint rotation of pose vectors ``poses`` as a quaternion (x, y, z, w)."""
    poses = np.asarray(poses, dtype=np.float64)
    rotvecs = poses[..., 3:].reshape(*poses.shape[:-1], len(JOINT_NAMES), 3)
    return Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_quat().reshape(*rotvecs.shape[:-1], 4)


def turned_about_vertical(poses: np.ndarray, angle: float) -> np.ndarray:
    """A copy of pose vectors ``poses`` (``(..., POSE_SIZE)``) with the whole body turned in place by ``angle``
    (radians, counter-clockwise seen from above) about the vertical through its root: joint 0's rotation
    composed after the turn, the root's position and every other joint kept."""
    turned = np.array(poses, dtype=np.float64)
    turned[..., 3:6] = (Rotation.from_euler("z", angle) * Rotation.from_rotvec(turned[..., 3:6])).as_rotvec()
    return turned
