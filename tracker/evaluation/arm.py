"""How an estimate of the DSQ arm is judged (paper 1): every parameter of every part against the truth, the
surface, and Fig 8's figures for part 2.

Columns per part: ``truth_<param>`` and ``est_<param>`` (eq 4's parameters, radians for angles),
``surface_error_mm`` (the mean distance between the part's estimated and true model samples, matched by their
surface coordinates eta, omega: sliding along the surface counts), ``surface_distance_mm`` (the point-to-surface
distance usually quoted: each surface's model samples to the other surface's mesh, both ways, averaged; the meshes'
facets lie a fraction of a millimetre inside the true surface, so identical parts read a little above 0) and
``rotation_error_deg``: the angle of the rotation between the part's true and
estimated orientation in its parent's frame (the geodesic angle: eq 4's Euler angles are singular at r2 = 90
degrees, where r1 and r3 swing freely while the orientation barely moves). Figures: the RMS error of every parameter
of every part (angles wrapped to (-180, 180] degrees) and of the rotation (``rotation_deg``), the mean surface
error, and for paper 1's part 2 (`PAPER_PART`) b1's RMS and range and r2's RMS. A dictionary's floor (tree
filtering over a grid of the arm's poses): per frame the sample nearest the truth in the samples' space, each pose
component in the motion model's steps, and part 2's figures had it been the estimate.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracker.evaluation import register_evaluation
from tracker.geometry.rotations import euler_to_matrix, rotation_angle_deg
from tracker.geometry.surface_distance import point_mesh_distance
from tracker.models.dsq import ANGLE_NAMES, PARAM_INDEX, PARAM_NAMES
from tracker.presentation import PAPER_PART
from tracker.protocol import SampleDictionary

_R = slice(PARAM_INDEX["r1"], PARAM_INDEX["r3"] + 1)


def surface_distance_mm(
    estimated_points: np.ndarray,
    true_points: np.ndarray,
    estimated_vertices: np.ndarray,
    true_vertices: np.ndarray,
    faces: np.ndarray,
) -> float:
    """The point-to-surface distance both ways (mm): each surface's samples to the other surface's mesh (``faces``),
    averaged (`point_mesh_distance`)."""
    return 1e3 * float(
        np.concatenate(
            [
                point_mesh_distance(estimated_points, true_vertices, faces),
                point_mesh_distance(true_points, estimated_vertices, faces),
            ]
        ).mean()
    )


def part_surface_distances_mm(
    arm: Any, estimate: np.ndarray, truth: np.ndarray, estimated_points: list, true_points: list
) -> np.ndarray:
    """Per part, `surface_distance_mm` of ``estimate`` against ``truth`` (``(parts, params)``), given their model
    samples (``arm.sample_points`` of each: the caller has them)."""
    surfaces = zip(
        estimated_points, true_points, arm.surface_vertices(estimate), arm.surface_vertices(truth), strict=True
    )
    return np.array([surface_distance_mm(*surface, arm.topology.faces) for surface in surfaces])


@dataclass(frozen=True)
class ArmEvaluation:
    series: tuple[str, ...] = ("rotation_error_deg", "surface_error_mm", "surface_distance_mm")  # plotted

    def columns(self, arm: Any, truth: np.ndarray, estimate: np.ndarray | None) -> tuple[dict, dict]:
        part = {f"truth_{name}": truth[:, i].astype(np.float64) for i, name in enumerate(PARAM_NAMES)}
        if estimate is not None:
            part.update({f"est_{name}": estimate[:, i].astype(np.float64) for i, name in enumerate(PARAM_NAMES)})
            estimated_points, true_points = arm.sample_points(estimate), arm.sample_points(truth)
            pairs = zip(estimated_points, true_points, strict=True)
            part["surface_error_mm"] = np.array([1e3 * float(np.linalg.norm(e - t, axis=1).mean()) for e, t in pairs])
            part["surface_distance_mm"] = part_surface_distances_mm(arm, estimate, truth, estimated_points, true_points)
            part["rotation_error_deg"] = np.array(
                [
                    rotation_angle_deg(euler_to_matrix(true[_R]), euler_to_matrix(estimated[_R]))
                    for true, estimated in zip(truth, estimate, strict=True)
                ]
            )
        return part, {}

    def summarize(self, arm: Any, table: Mapping[str, np.ndarray]) -> dict[str, Any]:
        if "est_a" not in table or not len(table["est_a"]):
            return {}
        rms: dict[str, dict[str, float]] = {}
        for part in arm.part_names:
            rows = table["part"] == part
            rms[part] = {}
            for name in PARAM_NAMES:
                error = table[f"est_{name}"][rows] - table[f"truth_{name}"][rows]
                if name in ANGLE_NAMES:
                    error = np.degrees(np.angle(np.exp(1j * error)))  # wrapped to (-180, 180]
                rms[part][f"{name}_deg" if name in ANGLE_NAMES else name] = float(np.sqrt(np.mean(error**2)))
            rms[part]["rotation_deg"] = float(np.sqrt(np.mean(table["rotation_error_deg"][rows] ** 2)))
        figures: dict[str, Any] = {
            "rms": rms,
            "mean_surface_error_mm": float(np.mean(table["surface_error_mm"])),
            "mean_surface_distance_mm": float(np.mean(table["surface_distance_mm"])),
        }
        if len(arm.part_names) > PAPER_PART:
            part = arm.part_names[PAPER_PART]
            figures["part2_b1_rms"] = rms[part]["b1"]
            figures["part2_b1_range"] = float(np.ptp(table["truth_b1"][table["part"] == part]))
            figures["part2_r2_rms_deg"] = rms[part]["r2_deg"]
        return figures

    def floor(
        self, arm: Any, dictionary: SampleDictionary, table: Mapping[str, np.ndarray]
    ) -> tuple[dict[str, Any], np.ndarray]:
        """Per frame the sample nearest the truth in the samples' space (each component in the motion model's
        steps), and paper 1's figures for part 2 had it been the estimate (``floor_part2_b1_rms``,
        ``floor_part2_r2_rms_deg``); and those samples."""
        parts = arm.part_names
        truths = np.stack(
            [
                np.stack([table[f"truth_{name}"][table["part"] == part] for name in PARAM_NAMES], axis=1)
                for part in parts
            ],
            axis=1,
        )  # (frames, parts, 17)
        poses, steps = dictionary.poses, dictionary.steps
        nearest = np.array(
            [np.argmin(np.linalg.norm((poses - dictionary.pose_of(truth)) / steps, axis=1)) for truth in truths]
        )
        figures: dict[str, Any] = {}
        if len(parts) > PAPER_PART:
            floor = np.stack([dictionary.parameters(poses[k])[PAPER_PART] for k in nearest])
            truth = truths[:, PAPER_PART]
            b1, r2 = PARAM_INDEX["b1"], PARAM_INDEX["r2"]
            figures["floor_part2_b1_rms"] = float(np.sqrt(np.mean((floor[:, b1] - truth[:, b1]) ** 2)))
            wrapped = np.angle(np.exp(1j * (floor[:, r2] - truth[:, r2])))
            figures["floor_part2_r2_rms_deg"] = float(np.degrees(np.sqrt(np.mean(wrapped**2))))
        return figures, nearest


register_evaluation("dsq_arm", ArmEvaluation())
