"""Fitting the skinned body to the views' observed silhouettes and feature pairs: the hybrid's continuous refinement.

Per view, the observed silhouette S (bool, the camera's pixels) gives (`tracker.hybrid.view_field.ViewField`)
``outside``, each pixel's distance to S (0 inside it), and its edge points (S's boundary pixels, evenly thinned).
With the body's vertices v_i (`BodyMesh.posed_vertices`) projected to pixels u_i (`Camera.project`), the cost sums, over
the views and the two terms, the mean of robust squares (``rho(r) = r^2`` up to ``robust_px``, linear beyond:
Huber) of
    region    ``outside(u_i)`` for every ``vertex_stride``-th vertex: the body stays within the silhouette;
    cover     for every edge point e, ``n_e . (u_k - e)`` for the body's outline vertex k nearest it in the image
              (n_e: the silhouette's outward normal at e; a vertex is on the outline where its normal is near
              square to the camera's ray, ``|n . ray| < outline_cos``): the body's outline reaches every part of
              the silhouette's (an ICP step, point to line);
a feature term, with the frame's pairs (`tracker.hybrid.feature_pairs`), ``features.weight`` times the mean robust
square (up to ``features.robust_px``) of each pair's point on the posed body projected, minus its feature's pixel
(``u`` and ``v``): the skin follows its texture where the outline cannot tell how a part turned;
and a prior ``prior_weight^2 |r_j - r_j^0|^2`` on each fitted joint's rotation vector, towards the starting pose
(a joint the silhouettes do not constrain, a limb's twist, stays where it was), and where a place for the root is
given, ``root_prior^2 |t - t^0|^2`` on its position (one view hardly sees depth). The parameters are the root's
position and the rotation vectors of `FIT_JOINTS` but the ``held_joints``, which keep the candidate's rotations:
by default the two hip bones (``LHipJoint``, ``RHipJoint``: pelvis to thigh), which no staged clip turns (CMU's
skeleton gives them no channels of motion, and the retargeting leaves them at rest) and which, turned, let the
pelvis float off the legs while the silhouettes stay explained. Levenberg-Marquardt steps them by the Gauss-Newton
system of the residuals' Jacobian, analytic: the image gradient of ``outside`` (for cover, the edge's normal) times
the projection's Jacobian (`tracker.geometry.cameras.projection_jacobian`) times the skinned vertices'
(`tracker.models.skinning_jacobian`; a pair's point: its face's corners' blended by its barycentric coordinates),
taken by the joints' levers (`tracker.hybrid.pose_terms.residual_rows`; the system itself is summed residual by
residual over the columns that move each, `normal_equations`).

`fit_cost` is the silhouettes' terms alone: what the hybrid compares candidates by (the same vertices and edge
points for every candidate, so the numbers compare). The pairs guide each candidate's fit but do not judge between
candidates: tied to the last estimate, they would keep a wrong one against a proposal that explains the views.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Literal, NamedTuple

import numba
import numpy as np

from tracker.geometry.cameras import Camera
from tracker.hybrid.feature_pairs import FeaturePairSettings, ViewPairs
from tracker.hybrid.pose_terms import FrameViews, PoseTerms, normal_equations, pose_terms, residual_rows
from tracker.hybrid.view_field import ViewField
from tracker.models.body_mesh import BodyMesh
from tracker.models.body_skeleton import JOINT_INDEX, JOINT_NAMES, POSE_SIZE
from tracker.ranges import NonNegative, Positive, Range
from tracker.render.mesh import vertex_normals
from tracker.settings import validate
from tracker.threads import TwoEndedJobs

# The joints fitted: every joint that moves the silhouette but the fingers', thumbs' and toes' (too small to see).
FIT_JOINTS = tuple(
    JOINT_INDEX[name]
    for name in (
        "Hips LowerBack Spine Spine1 Neck Neck1 Head LeftShoulder LeftArm LeftForeArm LeftHand RightShoulder "
        "RightArm RightForeArm RightHand LHipJoint LeftUpLeg LeftLeg LeftFoot RHipJoint RightUpLeg RightLeg RightFoot"
    ).split()
)
FitJoint = Literal[tuple(JOINT_NAMES[joint] for joint in FIT_JOINTS)]


def fit_columns(joints: Sequence[int]) -> np.ndarray:
    """The pose vector's entries a fit of ``joints`` steps: the root's position, then each joint's rotation vector."""
    return np.r_[np.arange(3), (3 + 3 * np.asarray(joints, dtype=np.int64)[:, None] + np.arange(3)).ravel()]


@dataclass(frozen=True)
class FitSettings:
    """The silhouette fit's iterations, terms and weights (see the module docstring)."""

    iterations: Annotated[int, Range(0, 100)] = 10
    vertex_stride: Annotated[int, Range(1, 100)] = 6  # the region term's vertices: every this many (outline: all)
    edge_points: Annotated[int, Range(8, 10_000)] = 400  # per view, the silhouette's edge points at most
    outline_cos: Annotated[float, Range(0.0, 1.0)] = 0.35
    robust_px: Positive = 8.0
    prior_weight: NonNegative = 2.0  # pixels per radian of a joint's rotation away from the starting pose
    root_prior: NonNegative = 20.0  # pixels per metre of the root away from where it is held (`refine`'s root)
    damping: Positive = 1e-3  # Levenberg-Marquardt's first lambda, relative to the system's diagonal
    tolerance: NonNegative = 0.02  # stop once an iteration lowers the cost by less than this fraction of it
    held_joints: tuple[FitJoint, ...] = ("LHipJoint", "RHipJoint")  # not fitted (see the module docstring)
    features: FeaturePairSettings = field(default_factory=FeaturePairSettings)

    def __post_init__(self) -> None:
        validate(self)

    @property
    def joints(self) -> tuple[int, ...]:
        """The joints fitted: `FIT_JOINTS` but the ``held_joints``."""
        return tuple(joint for joint in FIT_JOINTS if JOINT_NAMES[joint] not in self.held_joints)


def huber_weights(residuals: np.ndarray, scale: float) -> np.ndarray:
    """IRLS weights of the Huber rho: 1 within ``scale``, ``scale / |r|`` beyond."""
    size = np.abs(residuals)
    return np.where(size <= scale, 1.0, scale / np.maximum(size, 1e-12))


@numba.njit(cache=True, nogil=True)
def mean_huber(residuals: np.ndarray, scale: float) -> float:
    """The mean Huber rho of ``residuals`` (0 of none): ``r^2`` within ``scale``, ``2 scale |r| - scale^2`` beyond."""
    total = 0.0
    for residual in residuals:
        size = abs(residual)
        total += size * size if size <= scale else 2 * scale * size - scale * scale
    return total / len(residuals) if len(residuals) else 0.0


class Term(NamedTuple):
    """A block of the fit's residuals: their ``values``, their ``rows`` of the Jacobian by the fit's columns (None when
    not asked for), the Huber scale, the ``weight`` of their mean robust square in the cost, and that mean
    (``robust``, `mean_huber`); ``silhouette``: a silhouette's term (what `SilhouetteFit.fit_cost` counts), not the
    feature pairs'. Make one with `Term.of`."""

    values: np.ndarray
    rows: np.ndarray | None
    robust_px: float
    weight: float
    robust: float
    silhouette: bool = True

    @classmethod
    def of(cls, values: np.ndarray, robust_px: float, weight: float, silhouette: bool = True) -> Term:
        return cls(values, None, robust_px, weight, mean_huber(values, robust_px), silhouette)


class SilhouetteFit:
    """The fit of ``body`` to the silhouettes of ``cameras`` (one frame's `ViewField` each: `observe`)."""

    # Poses whose terms `residuals` keeps: a frame's candidates costed as proposed (13 in hybrid_multi_view: with
    # 16, some were evicted before their screen and computed again), their screens' trials, the refining's steps.
    POSES_KEPT = 32

    def __init__(self, body: BodyMesh, cameras: Sequence[Camera], settings: FitSettings = FitSettings()) -> None:
        self.body, self.cameras, self.settings = body, tuple(cameras), settings
        self.joints = settings.joints
        self.columns = fit_columns(self.joints)
        self._joints = np.array(self.joints, dtype=np.int64)
        self.region = np.arange(0, len(body.rest_vertices), settings.vertex_stride)
        self.rest_normals = vertex_normals(body.rest_vertices, body.faces)
        self.fields: list[ViewField] = []
        self.pairs: list[ViewPairs] = []
        self._views = FrameViews.of([], [], body.faces)  # `observe`'s fields and pairs as `pose_terms` reads them
        self._asked: dict[bytes, tuple] = {}  # this frame's last poses asked (their bytes), and their `_terms`
        self._asking = threading.Lock()  # `refine` may run on several threads at once: `_asked` changes under it

    def observe(self, silhouettes: Sequence[np.ndarray], pairs: Sequence[ViewPairs] | None = None) -> None:
        """This frame's silhouettes and feature pairs (None: none), one per camera in the cameras' order. The views'
        fields are made here and on the worker threads (their distance transforms free the GIL)."""
        if len(silhouettes) != len(self.cameras):
            raise ValueError(f"{len(silhouettes)} silhouettes for {len(self.cameras)} views")
        self.fields = TwoEndedJobs(
            [
                functools.partial(ViewField, silhouette, camera, self.settings.edge_points)
                for silhouette, camera in zip(silhouettes, self.cameras, strict=True)
            ]
        ).results()
        self.pairs = list(pairs) if pairs is not None else [ViewPairs.empty() for _ in self.cameras]
        paired = self.pairs if self.settings.features.weight > 0 else [ViewPairs.empty() for _ in self.cameras]
        self._views = FrameViews.of(self.fields, paired, self.body.faces)
        self._asked = {}

    def residuals(self, pose: np.ndarray, jacobian: bool = True) -> list[Term]:
        """Per view, the region term, the cover term and, with pairs observed, the feature term (a pair's ``u`` then
        its ``v`` residual); with ``jacobian``, each term's rows by the fit's ``columns`` (else None).

        The terms of the frame's last `POSES_KEPT` poses are kept: Levenberg-Marquardt asks for the Jacobian where
        it has just taken a step, whose cost it computed to accept it, and the hybrid refines on, and judges, poses
        it screened."""
        pose = np.asarray(pose, dtype=np.float64)
        terms, found = self._kept_terms(pose[None])[0]
        if not jacobian:
            return list(terms)
        rows = residual_rows(self.body, pose, found, self._views, self.region, self._joints)
        ends = np.cumsum([len(term.values) for term in terms])[:-1]
        return [term._replace(rows=block) for term, block in zip(terms, np.split(rows, ends), strict=True)]

    def _normal_equations(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Gauss-Newton system of the terms at ``pose`` (`pose_terms.normal_equations`): ``J^T W J`` and
        ``J^T W r``, each residual weighted by its term's weight, its IRLS weight and one over the term's count."""
        terms, found = self._kept_terms(pose[None])[0]
        terms = [term for term in terms if len(term.values)]
        if not terms:
            return np.zeros((len(self.columns), len(self.columns))), np.zeros(len(self.columns))
        values = np.concatenate([term.values for term in terms])
        weights = np.concatenate(
            [term.weight * huber_weights(term.values, term.robust_px) / len(term.values) for term in terms]
        )
        return normal_equations(self.body, pose, found, self._views, self.region, self._joints, values, weights)

    def _kept_terms(self, poses: np.ndarray) -> list[tuple]:
        """`_terms` of ``poses`` ``(n, POSE_SIZE)``: those kept (`residuals`), the others made in one batch and
        kept."""
        keys = [pose.tobytes() for pose in poses]
        with self._asking:
            found = {key: self._asked[key] for key in keys if key in self._asked}
        missing = {key: pose for key, pose in zip(keys, poses, strict=True) if key not in found}  # each pose once
        found.update(zip(missing, self._terms(np.array(list(missing.values()))), strict=True))
        with self._asking:
            for key in missing:
                if len(self._asked) == self.POSES_KEPT:
                    del self._asked[next(iter(self._asked))]  # the oldest
                self._asked[key] = found[key]
        return [found[key] for key in keys]

    def _terms(self, poses: np.ndarray) -> list[tuple[list[Term], PoseTerms]]:
        """Per pose of ``poses`` ``(n, POSE_SIZE)`` (n may be 0): its terms without their rows, and what
        `pose_terms` made of it (what `residual_rows` reads), each pose in one compiled pass."""
        settings, features = self.settings, self.settings.features
        made = []
        for pose in poses:
            found = pose_terms(self.body, self.rest_normals, pose, self._views, self.region, settings.outline_cos)
            terms = []
            for k, pairs in enumerate(self.pairs):
                edges = slice(*self._views.edge_starts[k : k + 2])
                if len(found.cover_vertices[edges]) and found.cover_vertices[edges][0] < 0:  # no outline: no cover
                    edges = slice(0, 0)
                terms += [
                    Term.of(found.outside[k], settings.robust_px, 1.0),
                    Term.of(found.cover[edges], settings.robust_px, 1.0),
                ]
                if len(pairs) and features.weight > 0:
                    values = found.seen[slice(*self._views.pair_starts[k : k + 2])].ravel()  # u0, v0, u1, v1, ...
                    terms.append(Term.of(values, features.robust_px, features.weight, silhouette=False))
            made.append((terms, found))
        return made

    def fit_cost(self, pose: np.ndarray) -> float:
        """How well ``pose`` explains the views' silhouettes: their terms' cost (see the module docstring)."""
        return float(self.fit_costs([pose])[0])

    def fit_costs(self, poses: Sequence[np.ndarray]) -> np.ndarray:
        """`fit_cost` of each of ``poses``, those not yet asked made in one batch."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, POSE_SIZE)
        return np.array([self.cost(terms, silhouettes_only=True) for terms, *_ in self._kept_terms(poses)])

    @staticmethod
    def cost(terms: Sequence[Term], silhouettes_only: bool = False) -> float:
        """Each term's weight times its mean robust square, summed (over the silhouettes' terms only, or all)."""
        return float(sum(term.weight * term.robust for term in terms if term.silhouette or not silhouettes_only))

    def refine(
        self, start: np.ndarray, iterations: int | None = None, root: np.ndarray | None = None
    ) -> tuple[np.ndarray, float]:
        """``start`` refined by Levenberg-Marquardt (see the module docstring) for ``iterations`` at most (None: the
        settings'), the root's position held near ``root`` (None: free); the pose vector it ends at and its
        `fit_cost` (computed on the way)."""
        settings, pose = self.settings, np.asarray(start, dtype=np.float64).copy()
        anchor = pose[self.columns].copy()
        root_weight = 0.0 if root is None else settings.root_prior
        if root is not None:
            anchor[:3] = root
        prior_rows = np.r_[np.full(3, root_weight), np.full(len(self.columns) - 3, settings.prior_weight)]

        def total(candidate: np.ndarray) -> tuple[float, float]:
            """The cost with the feature pairs and the prior, and the `fit_cost` in it."""
            terms = self.residuals(candidate, jacobian=False)
            prior = float(((prior_rows * (candidate[self.columns] - anchor)) ** 2).sum())
            return self.cost(terms) + prior, self.cost(terms, silhouettes_only=True)

        (current, fitted), damping = total(pose), settings.damping
        for _ in range(settings.iterations if iterations is None else iterations):
            hessian, gradient = self._normal_equations(pose)
            hessian += np.diag(prior_rows**2)
            gradient += prior_rows**2 * (pose[self.columns] - anchor)
            while damping < 1e8:
                system = hessian + damping * np.diag(np.diag(hessian) + 1e-9)
                trial = pose.copy()
                trial[self.columns] -= np.linalg.solve(system, gradient)
                cost, trial_fitted = total(trial)
                if cost < current:
                    pose, current, fitted, damping, gain = (
                        trial,
                        cost,
                        trial_fitted,
                        max(damping / 10, 1e-9),
                        current - cost,
                    )
                    break
                damping *= 10
            else:
                break
            if gain < settings.tolerance * current:
                break
        return pose, fitted
