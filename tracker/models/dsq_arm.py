"""The paper-1 object: a chain of DSQ parts, each joined at its bottom pole to its parent's top pole.

Part k (0-based index) has label k + 1 in label images; part names come from the config. The root's c and r place
it in the world; a child's r is its rotation relative to the parent and its c is *derived* from the joint
constraint (the child's bottom pole sits on the parent's top pole, eq 3 with the paper's single-point joints),
so joints stay connected for any shape or rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, ClassVar

import numpy as np

from tracker.geometry.rotations import euler_to_matrix, transform_points
from tracker.models.articulated import KinematicTree, forward_kinematics, jointed_translation, local_transforms
from tracker.models.dsq import (
    PARAM_INDEX,
    PARAM_NAMES,
    DSQShape,
    MeshTopology,
    SampleGrid,
    dsq_points,
    dsq_points_at,
    mesh_topology,
    pole_point,
    sample_grid,
)
from tracker.models.textures import block_noise_texture
from tracker.presentation import Panel, Presentation, paper_part_first
from tracker.ranges import RGB, Range, Seed
from tracker.registry import MODELS
from tracker.render.mesh import SurfaceMesh, vertex_normals

_C = slice(PARAM_INDEX["c1"], PARAM_INDEX["c3"] + 1)
_R = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)


CellCount = Annotated[int, Range(1, 256)]
GridSide = Annotated[int, Range(3, 1024)]


@dataclass(frozen=True)
class ArmPart:
    """A part of the arm: its rest shape, the colour its texture is tinted with and the texture's block count."""

    name: str
    shape: DSQShape = field(default_factory=DSQShape)
    tint: RGB = (220, 220, 220)
    texture_cells: tuple[CellCount, CellCount] = (12, 12)  # blocks along (eta, omega)


@dataclass(frozen=True)
class Resolution:
    """Grid sizes over (eta, omega)."""

    n_eta: GridSide
    n_omega: GridSide


def _arm_panels(parts) -> list[Panel]:
    first = paper_part_first(parts)[0]
    return [
        Panel(f"{first}: b1 (m) and r2 (rad), Fig 8", f"metrics/params/{first}", ("b1/**", "r2/**")),
        *(
            Panel(title, "metrics/error", tuple(f"{part}/{series}" for part in parts), of_estimate=True)
            for title, series in (
                ("rotation error (geodesic, deg)", "rotation_error_deg"),
                ("surface error, same (eta, omega) (mm)", "surface_error_mm"),
                ("point-to-surface (mm)", "surface_distance_mm"),
            )
        ),
    ]


@MODELS.register("dsq_arm", presentation=Presentation(panels=_arm_panels))
@dataclass(eq=False)
class DSQArm:
    """Paper 1's object: deformable superquadrics joined pole to pole, textured (eq 1-4)."""

    name: ClassVar[str] = "dsq_arm"
    parts: tuple[ArmPart, ...]  # root first
    mesh: Resolution = field(default_factory=lambda: Resolution(40, 48))  # the rendered surface
    samples: Resolution = field(default_factory=lambda: Resolution(16, 24))  # model samples for fitting
    zbuffer: Resolution = field(default_factory=lambda: Resolution(24, 32))  # the visibility mesh
    seed: Seed = 0  # draws the textures
    # Derived in __post_init__:
    tree: KinematicTree = field(init=False, repr=False)
    topology: MeshTopology = field(init=False, repr=False)  # of the render mesh
    zbuffer_topology: MeshTopology = field(init=False, repr=False)
    sample_grid: SampleGrid = field(init=False, repr=False)  # model samples for fitting
    textures: list[np.ndarray] = field(init=False, repr=False)  # one per part

    def __post_init__(self) -> None:
        if len(self.parts) < 1:
            raise ValueError("an arm needs at least one part")
        names = [part.name for part in self.parts]
        if len(set(names)) != len(names):
            raise ValueError(f"arm part names must be unique, got {names}")
        self.tree = KinematicTree(tuple(names), (None, *range(len(self.parts) - 1)))
        self.topology = mesh_topology(self.mesh.n_eta, self.mesh.n_omega)
        self.zbuffer_topology = mesh_topology(self.zbuffer.n_eta, self.zbuffer.n_omega)
        self.sample_grid = sample_grid(self.samples.n_eta, self.samples.n_omega)
        seeds = np.random.SeedSequence(self.seed).spawn(len(self.parts))  # one stream per part
        self.textures = [
            block_noise_texture(np.random.default_rng(seed), part.texture_cells, part.tint)
            for seed, part in zip(seeds, self.parts, strict=True)
        ]

    @property
    def part_names(self) -> tuple[str, ...]:
        return self.tree.names

    @property
    def part_colors(self) -> list[tuple[int, int, int]]:
        return [part.tint for part in self.parts]

    def parameter_series(self, params: np.ndarray) -> dict[str, float]:
        """Named scalars of ``params`` for time series: ``<part>/<parameter>``."""
        return {
            f"{part}/{name}": float(params[k, i])
            for k, part in enumerate(self.part_names)
            for i, name in enumerate(PARAM_NAMES)
        }

    def rest_params(self) -> np.ndarray:
        """``(n_parts, 17)``: every part's rest shape with zero rotation, joints connected."""
        return self.connect(np.stack([part.shape.to_params() for part in self.parts]))

    def connect(self, params: np.ndarray) -> np.ndarray:
        """Set each child's c from the joint constraint; the root's c is kept. Returns a new array."""
        params = np.array(params, dtype=np.float64)
        for child, parent in enumerate(self.tree.parents):
            if parent is None:
                continue
            rotation = euler_to_matrix(params[child, _R])
            params[child, _C] = jointed_translation(
                rotation, pole_point(params[parent], top=True), pole_point(params[child], top=False)
            )
        return params

    def world_transforms(self, params: np.ndarray) -> np.ndarray:
        """``(n_parts, 4, 4)`` part -> world transforms (eq 3)."""
        return forward_kinematics(self.tree, local_transforms(params))

    def joint_positions(self, params: np.ndarray) -> np.ndarray:
        """``(n_parts - 1, 3)`` world positions of the joints, seen from the parent side (its top pole)."""
        world = self.world_transforms(params)
        joints = [
            transform_points(world[parent], pole_point(params[parent], top=True)[None])[0]
            for parent in self.tree.parents
            if parent is not None
        ]
        return np.array(joints).reshape(-1, 3)

    def part_points(
        self, params: np.ndarray, part: int, eta: np.ndarray, omega: np.ndarray, world: np.ndarray | None = None
    ) -> np.ndarray:
        """World points ``(n, 3)`` of part ``part`` at surface coordinates (eta, omega). Pass ``world`` (the
        parts' `world_transforms` for ``params``) when calling repeatedly for the same parameters."""
        world = self.world_transforms(params) if world is None else world
        return transform_points(world[part], dsq_points(params[part], eta, omega))

    def sample_points(self, params: np.ndarray) -> list[np.ndarray]:
        """Per part, the world positions ``(n_samples, 3)`` of its model samples (row k is sample id k)."""
        world = self.world_transforms(params)
        grid = self.sample_grid
        return [transform_points(world[k], dsq_points_at(params[k], grid.trig)) for k in range(len(self.parts))]

    def surface_vertices(self, params: np.ndarray) -> list[np.ndarray]:
        """Per part, the world positions of its mesh's vertices (faces: ``topology.faces``)."""
        world = self.world_transforms(params)
        trig = self.topology.trig
        return [transform_points(world[k], dsq_points_at(params[k], trig)) for k in range(len(self.parts))]

    def surface_meshes(self, params: np.ndarray) -> list[SurfaceMesh]:
        """The parts' textured meshes in the world, labels 1..n."""
        return [
            SurfaceMesh(
                key=part.name,
                label=k + 1,
                vertices=vertices,
                faces=self.topology.faces,
                normals=vertex_normals(vertices, self.topology.faces, self.topology.weld),
                color=part.tint,
                uv=self.topology.uv,
                texture=self.textures[k],
            )
            for k, (part, vertices) in enumerate(zip(self.parts, self.surface_vertices(params), strict=True))
        ]

    def zbuffer_meshes(self, params: np.ndarray) -> list[SurfaceMesh]:
        """Coarser, unlit meshes (labels 1..n) for visibility: a z-buffer needs neither texture nor normals."""
        world = self.world_transforms(params)
        topology = self.zbuffer_topology
        return [
            SurfaceMesh(
                key=f"{part.name}/zbuffer",
                label=k + 1,
                vertices=transform_points(world[k], dsq_points_at(params[k], topology.trig)),
                faces=topology.faces,
                normals=None,
                color=part.tint,
            )
            for k, part in enumerate(self.parts)
        ]
