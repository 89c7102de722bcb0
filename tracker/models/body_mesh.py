"""A skinned human body mesh (paper 2's model): posing by linear-blend skinning, meshes per body part.

Conventions (body frame, pose vectors, parts): `tracker.models.body_skeleton`. The mesh comes from MakeHuman's
data (`tracker.models.makehuman.build_body`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np

from tracker.geometry.rotations import matrices_to_rotation_vectors, rotation_vectors_to_matrices
from tracker.models.body_skeleton import FOOT_BONES, JOINT_INDEX, JOINT_NAMES, PART_COLORS, PART_NAMES, POSE_SIZE
from tracker.models.textures import block_noise_texture
from tracker.render.mesh import SurfaceMesh, vertex_normals
from tracker.tol import ZERO_LENGTH

POSES_AT_ONCE = 4096  # poses whose joints `BodyMesh.joint_positions` computes together
SKIN_RGB = (214, 168, 140)  # the plain skin, and the tint of the textured one


@dataclass(frozen=True, eq=False)
class BodyMesh:
    """The decimated, skinned body at rest (the mesh's own pose, arms lowered) and its T-pose alignment."""

    name: ClassVar[str] = "body_mesh"

    rest_vertices: np.ndarray  # (V, 3) body frame
    faces: np.ndarray  # (F, 3) int32, counter-clockwise seen from outside
    weights: np.ndarray  # (V, J) float64, rows sum to 1
    parents: np.ndarray  # (J,) parent joint, -1 for the root
    rest_heads: np.ndarray  # (J, 3) each bone's head (its joint) at rest
    t_pose_alignment: np.ndarray  # (J, 3, 3) rotation of each bone from rest into the reference T-pose
    face_parts: np.ndarray  # (F,) index into PART_NAMES
    source_key: str  # hash of the source files and build settings (names the mesh in caches)
    texture_seed: int | None = None  # draws the skin's block-noise texture (None: plain skin)

    @property
    def part_names(self) -> tuple[str, ...]:
        return PART_NAMES

    @property
    def part_colors(self) -> tuple[tuple[int, int, int], ...]:
        return PART_COLORS

    def parameter_series(self, pose: np.ndarray) -> dict[str, float]:
        """Named scalars of a pose vector for time series: the root position (m), each joint's rotation angle from
        the T-pose (degrees) and the right arm's swing (degrees)."""
        series = {f"root/{axis}": float(pose[k]) for k, axis in enumerate("xyz")}
        angles = np.degrees(np.linalg.norm(np.asarray(pose[3:]).reshape(-1, 3), axis=1))
        series.update({f"joints/{name}_deg": float(angle) for name, angle in zip(JOINT_NAMES, angles, strict=True)})
        series["swing/right_arm_deg"] = self.right_arm_swing_deg(pose)
        return series

    def right_arm_swing_deg(self, pose: np.ndarray) -> float:
        """The right upper arm's (shoulder -> elbow) elevation in the body's sagittal plane: degrees from hanging
        straight down, + in front of the body (paper 2's experiment A swings it)."""
        heads = self.joint_positions(pose)
        upper = heads[JOINT_INDEX["RightForeArm"]] - heads[JOINT_INDEX["RightArm"]]
        # The body's own axes: forward is its -y, up its z, as turned by the root joint's rotation.
        root = rotation_vectors_to_matrices(pose[3:6])[0]
        forward, up = root @ np.array([0.0, -1.0, 0.0]), root @ np.array([0.0, 0.0, 1.0])
        return float(np.degrees(np.arctan2(upper @ forward, -(upper @ up))))

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

    def bone_transforms(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per bone the rotation from rest to the pose ``(J, 3, 3)`` and its posed head ``(J, 3)``; for ``(n,
        POSE_SIZE)`` poses, ``(n, J, 3, 3)`` and ``(n, J, 3)``."""
        poses = np.asarray(poses, dtype=np.float64)
        batch = poses.reshape(-1, POSE_SIZE)
        local = rotation_vectors_to_matrices(batch[:, 3:].reshape(-1, 3)).reshape(len(batch), -1, 3, 3)
        shape = (len(batch), len(self.parents))
        from_t_pose, rotations, heads = np.empty(shape + (3, 3)), np.empty(shape + (3, 3)), np.empty(shape + (3,))
        for joint, parent in enumerate(self.parents):  # parents first
            if parent < 0:
                from_t_pose[:, joint], heads[:, joint] = local[:, joint], batch[:, :3]
            else:
                from_t_pose[:, joint] = from_t_pose[:, parent] @ local[:, joint]
                heads[:, joint] = heads[:, parent] + rotations[:, parent] @ (
                    self.rest_heads[joint] - self.rest_heads[parent]
                )
            rotations[:, joint] = from_t_pose[:, joint] @ self.t_pose_alignment[joint]
        return (rotations[0], heads[0]) if poses.ndim == 1 else (rotations, heads)

    def joint_positions(self, pose: np.ndarray) -> np.ndarray:
        """``(J, 3)`` posed joint positions (``(n, J, 3)`` for ``n`` poses, `POSES_AT_ONCE` at a time: a sample
        set's 50,000 poses' bone rotations at once would take most of a gigabyte)."""
        pose = np.asarray(pose, dtype=np.float64)
        if pose.ndim == 1 or len(pose) <= POSES_AT_ONCE:
            return self.bone_transforms(pose)[1]
        return np.concatenate(
            [self.bone_transforms(pose[k : k + POSES_AT_ONCE])[1] for k in range(0, len(pose), POSES_AT_ONCE)]
        )

    def posed_vertices(
        self,
        poses: np.ndarray,
        subset: np.ndarray | None = None,
        transforms: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """``(V, 3)`` vertices by linear-blend skinning, ``v' = sum_j w_j (R_j (v - h_j) + h'_j)``; ``(n, V, 3)``
        for ``(n, POSE_SIZE)`` poses; only the vertices ``subset`` (indices) when given. ``transforms``: the poses'
        `bone_transforms`, when the caller has them."""
        poses = np.asarray(poses, dtype=np.float64)
        rotations, heads = transforms or self.bone_transforms(poses.reshape(-1, POSE_SIZE))
        rotations = rotations.reshape(-1, *rotations.shape[-3:])  # (n, J, 3, 3), one pose's transforms too
        heads = heads.reshape(-1, *heads.shape[-2:])  # (n, J, 3)
        count, joints = rotations.shape[:2]
        offsets = heads - np.einsum("njab,jb->nja", rotations, self.rest_heads)
        bones = np.concatenate([rotations, offsets[..., None]], axis=3)  # (n, J, 3, 4): x' = R x + o per bone
        # Each vertex's blend of its few bones, for every pose in one sparse product: (V, J) @ (J, n * 12).
        if subset is None:
            weights = self.sparse_weights
        else:
            weights = self._subset_weights(np.asarray(subset, dtype=np.int64).tobytes())
        blended = (weights @ bones.transpose(1, 0, 2, 3).reshape(joints, -1)).reshape(-1, count, 3, 4)
        rest = (self.rest_vertices if subset is None else self.rest_vertices[subset])[:, None, None, :]
        vertices = (
            blended[..., 3]
            + blended[..., 0] * rest[..., 0]
            + blended[..., 1] * rest[..., 1]
            + blended[..., 2] * rest[..., 2]
        )
        vertices = vertices.transpose(1, 0, 2)  # (n, V, 3)
        return vertices[0] if poses.ndim == 1 else vertices

    @cached_property
    def descendants(self) -> np.ndarray:
        """``(J, J)`` bool: ``[j, b]`` where turning joint j turns bone b (j itself and every bone below it)."""
        below = np.eye(len(self.parents), dtype=bool)
        for joint, parent in enumerate(self.parents):  # parents first
            ancestor = parent
            while ancestor >= 0:
                below[ancestor, joint] = True
                ancestor = self.parents[ancestor]
        return below

    def feet_heights(self, poses: np.ndarray) -> np.ndarray:
        """``(n,)`` the height (z, m) of the lowest vertex of the feet (those the foot and toe bones move most) at
        each of ``(n, POSE_SIZE)`` poses."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, POSE_SIZE)
        heights = np.empty(len(poses))
        for first in range(0, len(poses), 1024):  # in blocks: every foot vertex of every pose at once is large
            heights[first : first + 1024] = self.posed_vertices(poses[first : first + 1024], self._feet)[..., 2].min(1)
        return heights

    @cached_property
    def _feet(self) -> np.ndarray:
        bones = [JOINT_INDEX[name] for name in FOOT_BONES]
        return np.flatnonzero(np.isin(np.argmax(self.weights, axis=1), bones))

    @cached_property
    def sparse_weights(self):
        """`weights` as a CSR matrix: each vertex's few bones."""
        from scipy.sparse import csr_matrix

        return csr_matrix(self.weights)

    @functools.lru_cache(maxsize=64)  # noqa: B019 (a fit skins the same few vertices at every step: slicing once)
    def _subset_weights(self, subset: bytes):
        """The rows of `sparse_weights` of the vertices ``subset`` (int64 indices, their bytes)."""
        return self.sparse_weights[np.frombuffer(subset, dtype=np.int64)]

    def surface_meshes(self, pose: np.ndarray, color: tuple[int, int, int] = SKIN_RGB) -> list[SurfaceMesh]:
        """One lit mesh per body part (label = part index + 1), each with only its own vertices."""
        vertices = self.posed_vertices(pose)
        normals = vertex_normals(vertices, self.faces)
        textures = self.part_textures if self.texture_seed is not None else [(None, None)] * len(PART_NAMES)
        skin = "" if self.texture_seed is None else f"_texture{self.texture_seed}"  # the renderer keeps textures by key
        return [
            SurfaceMesh(
                key=f"body_{name}{skin}",
                label=k + 1,
                vertices=vertices[used],
                faces=faces,
                normals=normals[used],
                color=color,
                uv=uv,
                texture=texture,
            )
            for k, (name, (used, faces), (uv, texture)) in enumerate(
                zip(PART_NAMES, self.part_topology, textures, strict=True)
            )
            if len(faces)
        ]

    def label_meshes(self, vertices: np.ndarray) -> list[SurfaceMesh]:
        """The posed ``vertices`` ``(V, 3)`` as `surface_meshes` splits them, bare (no normals, texture): what a label
        pass, the z-buffer, draws."""
        return [
            SurfaceMesh(
                key=f"body_{name}", label=k + 1, vertices=vertices[used], faces=faces, normals=None, color=SKIN_RGB
            )
            for k, (name, (used, faces)) in enumerate(zip(PART_NAMES, self.part_topology, strict=True))
            if len(faces)
        ]

    @cached_property
    def part_textures(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per part, texture coordinates of its vertices (``part_topology``'s) and a block-noise texture drawn from
        ``texture_seed``: u the angle about the part's long axis at rest (its first principal direction), v the
        position along it. The seam where u wraps is a one-face smear, as on a DSQ part."""
        seeds = np.random.SeedSequence(self.texture_seed or 0).spawn(len(PART_NAMES))
        out = []
        for (used, _), seed in zip(self.part_topology, seeds, strict=True):
            points = self.rest_vertices[used] - self.rest_vertices[used].mean(axis=0)
            axes = np.linalg.svd(points, full_matrices=False)[2] if len(used) >= 3 else np.eye(3)
            along, side, across = points @ axes[0], points @ axes[1], points @ axes[2]
            span = np.ptp(along) if len(used) else 1.0
            uv = np.stack(
                [
                    (np.arctan2(across, side) + np.pi) / (2 * np.pi),
                    (along - (along.min() if len(used) else 0.0)) / max(span, ZERO_LENGTH),
                ],
                axis=1,
            )
            cells = (max(2, int(round(span / 0.03))), 12)  # blocks about 3 cm along the part, 12 around it
            out.append((uv, block_noise_texture(np.random.default_rng(seed), cells, SKIN_RGB)))
        return out

    @cached_property
    def closed(self) -> bool:
        """Every edge borders exactly two faces: a closed surface (the decimated MakeHuman body is one)."""
        edges = np.sort(self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        return bool((np.unique(edges, axis=0, return_counts=True)[1] == 2).all())

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
