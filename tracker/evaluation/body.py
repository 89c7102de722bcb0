"""How an estimate of the body is judged (paper 2): swing by swing (Fig 4c, by a fixed rule instead of by eye) and
by MPJPE.

Right-arm angle: the upper arm's (shoulder -> elbow) elevation in the body's sagittal plane, degrees from hanging
straight down, + in front of the body (`tracker.models.body_mesh.BodyMesh.right_arm_swing_deg`).

Swings: the truth's angle trace is cut where it crosses 0 upwards (the arm passes the vertical moving forward);
each complete cycle between two such crossings is one swing (`split_swings`). Per swing, with the estimate's
angle trace over the same frames (`score_swing`):
    Fail     the estimate did not follow: its range covers less than ``follow_fraction`` of the truth's on either
             side of the vertical (forward peak, backward trough), or its trace does not go the same way
             (correlation with the truth below ``min_correlation``);
    Error    it followed, but the largest error over the swing exceeds ``max_error_deg``;
    Success  it followed, with every frame within ``max_error_deg``.
Each swing's frames, whether it was followed and its largest error go to ``metrics.json`` too
(``swing_details``), so a reader can score the run at any other bound (`count_outcomes`).

Columns per frame (`BodyEvaluation.columns`): ``truth_pose`` and ``est_pose`` (pose vectors, lists),
``swing_truth_deg``, ``swing_est_deg``, ``joint_error_mm``, ``joint_error_aligned_mm``, ``joint_error_pa_mm``,
``joint_angle_error_deg`` and ``root_orientation_error_deg``.

MPJPE: the mean over frames of the mean distance (mm) between estimated and true positions of the 15
HumanEva-style joints (`MPJPE_JOINTS`); the root-aligned MPJPE first moves the estimate's pelvis onto the
truth's, so it measures the posture alone (the sample sets are postures in place); the PA-MPJPE (the field's
usual second protocol, e.g. Human3.6M's "protocol 2") first maps the estimate's joints onto the truth's by the
similarity (rotation, uniform scale, translation) that fits them best in least squares (`procrustes_aligned`,
Umeyama 1991), so it measures the posture without its place, facing or size.

Root orientation error: the angle (degrees) between the estimated and the true rotation of the root (``Hips``)
in the world: the facing the root-aligned MPJPE keeps and the joint-angle error leaves out.

Joint-angle error (as silhouette-based pose regression reports it, e.g. Agarwal and Triggs, PAMI 2006): the mean
over frames and over the posture joints that place the MPJPE joints (`ANGLE_JOINTS`: spine, neck, collars,
shoulders, elbows, hips, knees; the root's orientation left out, as the root-aligned MPJPE leaves out its place)
of the angle (degrees) between the estimated and the true rotation of the joint relative to its parent.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracker.evaluation import register_evaluation
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_INDEX, joint_angle_differences
from tracker.protocol import SampleDictionary

OUTCOMES = ("fail", "error", "success")
_VERTICAL_TOLERANCE_DEG = 1e-6
# Head, thorax (neck), pelvis, shoulders, elbows, wrists, hips, knees, ankles.
MPJPE_JOINTS = tuple(
    "Head Neck Hips LeftArm RightArm LeftForeArm RightForeArm LeftHand RightHand LeftUpLeg RightUpLeg LeftLeg "
    "RightLeg LeftFoot RightFoot".split()
)
ANGLE_JOINTS = tuple(
    "LowerBack Spine Spine1 Neck Neck1 LeftShoulder LeftArm LeftForeArm RightShoulder RightArm RightForeArm "
    "LeftUpLeg LeftLeg RightUpLeg RightLeg".split()
)


@dataclass(frozen=True)
class SwingRule:
    max_error_deg: float = 20.0
    follow_fraction: float = 0.5
    min_correlation: float = 0.5


def split_swings(truth_deg: np.ndarray) -> list[slice]:
    """Frame ranges of the complete swings in a truth angle trace (see the module docstring)."""
    truth_deg = np.asarray(truth_deg, dtype=np.float64)
    at_or_above = truth_deg >= -_VERTICAL_TOLERANCE_DEG  # float noise at the vertical counts as on it
    starts = np.flatnonzero(at_or_above[1:] & ~at_or_above[:-1]) + 1
    if len(truth_deg) and at_or_above[0] and (len(truth_deg) < 2 or truth_deg[1] > truth_deg[0]):
        starts = np.r_[0, starts]  # the trace starts at the vertical moving forward
    return [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:], strict=True)]


def followed(truth_deg: np.ndarray, estimate_deg: np.ndarray, rule: SwingRule = SwingRule()) -> bool:
    """Whether the estimate followed one swing (not a Fail; see the module docstring)."""
    truth_deg, estimate_deg = np.asarray(truth_deg, float), np.asarray(estimate_deg, float)
    forward, backward = truth_deg.max(), truth_deg.min()
    reaches = (
        estimate_deg.max() >= rule.follow_fraction * forward and estimate_deg.min() <= rule.follow_fraction * backward
    )
    spread = np.std(estimate_deg) > 0 and np.std(truth_deg) > 0
    correlation = float(np.corrcoef(truth_deg, estimate_deg)[0, 1]) if spread else 0.0
    return bool(reaches and correlation >= rule.min_correlation)


def outcome(followed_swing: bool, max_error_deg: float, bound_deg: float) -> str:
    """A swing's verdict from whether it was followed and its largest error, at the rule's bound."""
    if not followed_swing:
        return "fail"
    return "success" if max_error_deg <= bound_deg else "error"


def score_swing(truth_deg: np.ndarray, estimate_deg: np.ndarray, rule: SwingRule = SwingRule()) -> str:
    error = float(np.abs(np.asarray(estimate_deg, float) - np.asarray(truth_deg, float)).max())
    return outcome(followed(truth_deg, estimate_deg, rule), error, rule.max_error_deg)


def swing_details(truth_deg: np.ndarray, estimate_deg: np.ndarray, rule: SwingRule = SwingRule()) -> dict[str, list]:
    """Per complete swing of the truth trace: its frames (``start`` up to ``stop``, excluded), whether it was
    followed and its largest error (degrees): enough to score it at any bound (`outcome`)."""
    truth_deg, estimate_deg = np.asarray(truth_deg, float), np.asarray(estimate_deg, float)
    swings = split_swings(truth_deg)
    errors = [float(np.abs(estimate_deg[swing] - truth_deg[swing]).max()) for swing in swings]
    return {
        "start": [swing.start for swing in swings],
        "stop": [swing.stop for swing in swings],
        "followed": [followed(truth_deg[swing], estimate_deg[swing], rule) for swing in swings],
        "max_error_deg": errors,
    }


def score_swings(truth_deg: np.ndarray, estimate_deg: np.ndarray, rule: SwingRule = SwingRule()) -> dict[str, int]:
    """Counts of `OUTCOMES` over the complete swings of the truth trace."""
    return count_outcomes(swing_details(truth_deg, estimate_deg, rule), rule.max_error_deg)


def count_outcomes(details: Mapping[str, list], bound_deg: float) -> dict[str, int]:
    """Counts of `OUTCOMES` over the swings of `swing_details`, at the bound ``bound_deg``."""
    counts = dict.fromkeys(OUTCOMES, 0)
    for followed_swing, error in zip(details["followed"], details["max_error_deg"], strict=True):
        counts[outcome(followed_swing, error, bound_deg)] += 1
    return counts


def joint_error_mm(body: BodyMesh, truth: np.ndarray, estimate: np.ndarray, root_aligned: bool = False) -> float:
    """Mean distance (mm) between the estimated and true positions of `MPJPE_JOINTS` in one frame; with
    ``root_aligned``, after moving the estimate so that its pelvis ("Hips") is on the truth's (posture only)."""
    return joint_errors_mm(body, truth, estimate)["aligned" if root_aligned else "absolute"]


def joint_errors_mm(body: BodyMesh, truth: np.ndarray, estimate: np.ndarray) -> dict[str, float]:
    """One frame's mean distance (mm) over `MPJPE_JOINTS`: ``absolute``, root-``aligned`` and Procrustes-aligned
    (``pa``), each as the module docstring defines it."""
    joints = [JOINT_INDEX[name] for name in MPJPE_JOINTS]
    estimated, true = body.joint_positions(estimate)[joints], body.joint_positions(truth)[joints]
    pelvis = MPJPE_JOINTS.index("Hips")
    return {
        "absolute": mean_distance_mm(estimated, true),
        "aligned": mean_distance_mm(estimated - estimated[pelvis] + true[pelvis], true),
        "pa": mean_distance_mm(procrustes_aligned(estimated, true), true),
    }


def mean_distance_mm(points: np.ndarray, reference: np.ndarray) -> float:
    """The mean distance (mm) between corresponding ``(n, 3)`` points given in metres."""
    return float(1e3 * np.linalg.norm(points - reference, axis=1).mean())


def procrustes_aligned(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``points`` ``(n, 3)`` moved by the similarity ``s R p + t`` (R a proper rotation) that brings them nearest
    ``reference`` in least squares: Umeyama's closed form (the SVD of the cross-covariance, a reflection refused)."""
    mean_p, mean_r = points.mean(axis=0), reference.mean(axis=0)
    centred_p, centred_r = points - mean_p, reference - mean_r
    u, singular, vt = np.linalg.svd(centred_r.T @ centred_p)
    sign = np.ones(3)
    sign[2] = np.sign(np.linalg.det(u @ vt)) or 1.0
    rotation = (u * sign) @ vt
    spread = (centred_p**2).sum()
    scale = (singular * sign).sum() / spread if spread > 0 else 1.0
    return scale * centred_p @ rotation.T + mean_r


def root_orientation_error_deg(truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """The angle (degrees) between the estimated and true rotations of the root (``Hips``) per pose (broadcast)."""
    return joint_angle_differences(np.asarray(truth, float), np.asarray(estimate, float))[..., JOINT_INDEX["Hips"]]


def joint_angle_error_deg(truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """The mean angle (degrees) between estimated and true rotations of `ANGLE_JOINTS` per pose (broadcast)."""
    joints = [JOINT_INDEX[name] for name in ANGLE_JOINTS]
    return joint_angle_differences(np.asarray(truth, float), np.asarray(estimate, float))[..., joints].mean(axis=-1)


def nearest_in_3d(
    body: BodyMesh,
    truths: np.ndarray,
    candidate_body: BodyMesh,
    candidates: np.ndarray,
    candidate_joints: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """For each truth pose ``(n, POSE_SIZE)`` of ``body``: the candidate pose (of ``candidate_body``) nearest in 3-D
    — the smallest root-aligned mean distance over `MPJPE_JOINTS` — and that distance (mm). The dictionary's own
    floor when the candidates are a tracker's samples (``candidate_joints``: their ``joint_positions``, if known)."""
    joints = [JOINT_INDEX[name] for name in MPJPE_JOINTS]
    pelvis = MPJPE_JOINTS.index("Hips")
    true = body.joint_positions(np.asarray(truths, dtype=np.float64))[:, joints]
    true = true - true[:, pelvis : pelvis + 1]
    if candidate_joints is None:
        candidate_joints = candidate_body.joint_positions(np.asarray(candidates, dtype=np.float64))
    known = candidate_joints[:, joints]
    known = known - known[:, pelvis : pelvis + 1]
    nearest, distance = np.empty(len(true), dtype=np.int64), np.empty(len(true))
    for k, frame in enumerate(true):
        errors = np.linalg.norm(known - frame, axis=2).mean(axis=1)
        nearest[k] = int(np.argmin(errors))
        distance[k] = 1e3 * errors[nearest[k]]
    return nearest, distance


@dataclass(frozen=True)
class BodyEvaluation:
    rule: SwingRule = field(default_factory=SwingRule)
    # Columns the recording plots.
    series: tuple[str, ...] = (
        "joint_error_mm",
        "joint_error_aligned_mm",
        "joint_error_pa_mm",
        "joint_angle_error_deg",
        "root_orientation_error_deg",
    )

    def columns(self, body: BodyMesh, truth: np.ndarray, estimate: np.ndarray | None) -> tuple[dict, dict]:
        frame: dict[str, Any] = {"truth_pose": truth.tolist(), "swing_truth_deg": body.right_arm_swing_deg(truth)}
        if estimate is not None:
            errors = joint_errors_mm(body, truth, estimate)
            frame.update(
                est_pose=estimate.tolist(),
                swing_est_deg=body.right_arm_swing_deg(estimate),
                joint_error_mm=errors["absolute"],
                joint_error_aligned_mm=errors["aligned"],
                joint_error_pa_mm=errors["pa"],
                joint_angle_error_deg=float(joint_angle_error_deg(truth, estimate)),
                root_orientation_error_deg=float(root_orientation_error_deg(truth, estimate)),
            )
        return {}, frame

    def summarize(self, body: BodyMesh, table: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """MPJPE (mm, absolute and root-aligned), the swing outcomes and the mean right-arm angle error."""
        if "joint_error_mm" not in table or not len(table["joint_error_mm"]):
            return {}
        frame = table["part"] == body.part_names[0]  # one row per frame
        truth, estimate = table["swing_truth_deg"][frame], table["swing_est_deg"][frame]
        details = swing_details(truth, estimate, self.rule)
        return {
            "mpjpe_mm": float(np.mean(table["joint_error_mm"][frame])),
            "mpjpe_root_aligned_mm": float(np.mean(table["joint_error_aligned_mm"][frame])),
            "pa_mpjpe_mm": float(np.mean(table["joint_error_pa_mm"][frame])),
            "joint_angle_error_deg": float(np.mean(table["joint_angle_error_deg"][frame])),
            "root_orientation_error_deg": float(np.mean(table["root_orientation_error_deg"][frame])),
            "swings": count_outcomes(details, self.rule.max_error_deg),
            "swing_details": details,
            "swing_error_deg_mean": float(np.mean(np.abs(estimate - truth))),
        }

    def floor(
        self, body: BodyMesh, dictionary: SampleDictionary, table: Mapping[str, np.ndarray]
    ) -> tuple[dict[str, Any], np.ndarray]:
        """Per frame the sample nearest the truth in 3-D (root-aligned, the dictionary's body against the
        subject's: `nearest_in_3d`), as MPJPE (``mpjpe_floor_mm``, per frame in ``floor_per_frame_mm``), as
        joint-angle error (``joint_angle_floor_deg``) and as Fig 4(c)'s swings had it been the estimate
        (``swings_floor``); and those samples."""
        truths = np.stack(table["truth_pose"][table["part"] == body.part_names[0]])
        known = None if dictionary.joint_positions is None else dictionary.joint_positions()
        nearest, distance_mm = nearest_in_3d(body, truths, dictionary.model, dictionary.poses, known)
        truth_deg = np.array([body.right_arm_swing_deg(pose) for pose in truths])
        floor_deg = np.array([dictionary.model.right_arm_swing_deg(dictionary.poses[k]) for k in nearest])
        figures = {
            "mpjpe_floor_mm": float(distance_mm.mean()),
            "floor_per_frame_mm": distance_mm.round(1).tolist(),
            "joint_angle_floor_deg": float(joint_angle_error_deg(truths, dictionary.poses[nearest]).mean()),
            "swings_floor": score_swings(truth_deg, floor_deg, self.rule),
        }
        return figures, nearest


register_evaluation("body_mesh", BodyEvaluation())
