"""Deformable superquadrics (DSQ): paper 1, eq 1 (superquadric), eq 2 (tapering and bending), eq 4 (parameters).

Convention:
    A part's 17 parameters are a ``(17,)`` float64 vector ``q`` ordered as `PARAM_NAMES` (eq 4):
    ``(a, a1, a2, a3, eps1, eps2, t1, t2, b1, b2, b3, c1, c2, c3, r1, r2, r3)``. Lengths (a, b1, b2, c) are metres,
    angles r radians (`tracker.geometry.rotations` convention); c and r place the part in its parent's frame.
    Surface coordinates: latitude ``eta`` in [-pi/2, pi/2] (the part's z axis runs from eta = -pi/2 to +pi/2) and
    longitude ``omega`` in [-pi, pi). Points are ``(n, 3)`` in the part's local frame.
    Eq 2's ``e3/(a a3)`` and ``(e3 + b2)/(a a3)`` are used literally: ``b2`` is added to e3 unscaled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Annotated

import numpy as np

from tracker.ranges import ANY, Finite, NonNegative, Positive, Range
from tracker.settings import allowed_ranges, settings_of, validate
from tracker.tol import TRIG_SNAP

PARAM_NAMES = ("a", "a1", "a2", "a3", "eps1", "eps2", "t1", "t2", "b1", "b2", "b3", "c1", "c2", "c3", "r1", "r2", "r3")
PARAM_INDEX = {name: i for i, name in enumerate(PARAM_NAMES)}
SHAPE_NAMES = PARAM_NAMES[:11]
ANGLE_NAMES = ("r1", "r2", "r3")

# Ranges of eq 1-2. The paper allows a >= 0 and a1..a3 in [0, 1]; zero is excluded here because a = 0 or a3 = 0
# divides by zero in eq 2 and a1 = 0 or a2 = 0 collapses the part to a sheet that can be neither seen nor fitted.
Aspect = Annotated[float, Range(0.0, 1.0, low_open=True)]
Signed = Annotated[float, Range(-1.0, 1.0)]


@dataclass(frozen=True)
class DSQShape:
    """The 11 shape parameters of a part (eq 1-2) with their ranges; the default is a unit sphere of radius a."""

    a: Positive = 0.1
    a1: Aspect = 1.0
    a2: Aspect = 1.0
    a3: Aspect = 1.0
    eps1: NonNegative = 1.0
    eps2: NonNegative = 1.0
    t1: Signed = 0.0
    t2: Signed = 0.0
    b1: Finite = 0.0
    b2: Signed = 0.0
    b3: Aspect = 1.0

    def __post_init__(self) -> None:
        validate(self)

    def to_params(self, translation=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The full ``(17,)`` parameter vector with pose ``c = translation``, ``r = rotation``."""
        shape = [getattr(self, name) for name in SHAPE_NAMES]
        return np.array([*shape, *translation, *rotation], dtype=np.float64)


# Every parameter's range (eq 4): the shape's as declared above, any value for the pose (c, r).
PARAM_RANGES: dict[str, Range] = {
    **{s.name: allowed_ranges(s.hint)[0] for s in settings_of(DSQShape)},
    **{name: ANY for name in ("c1", "c2", "c3", "r1", "r2", "r3")},
}


def _snap(x: np.ndarray) -> np.ndarray:
    return np.where(np.abs(x) < TRIG_SNAP, 0.0, x)


@dataclass(frozen=True, eq=False)
class SurfaceTrig:
    """What eq 1 takes of surface coordinates ``(n,)``: the cosines and sines of eta and omega (snapped to 0 near
    it), as signs and magnitudes, each four ``(n,)`` arrays: cos eta, sin eta, cos omega, sin omega. Made once where
    many parameter values pose the same coordinates (a fit's pairs): eq 1 then only raises them to eps1 and eps2."""

    sign: tuple[np.ndarray, ...]
    magnitude: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, eta: np.ndarray, omega: np.ndarray) -> SurfaceTrig:
        eta, omega = np.asarray(eta, np.float64), np.asarray(omega, np.float64)
        values = np.empty((4, len(eta)))  # the four snapped, signed and measured at once: a few calls, not twenty
        values[0], values[1], values[2], values[3] = np.cos(eta), np.sin(eta), np.cos(omega), np.sin(omega)
        values = _snap(values)
        return cls(tuple(np.sign(values)), tuple(np.abs(values)))

    @cached_property
    def log_magnitude(self) -> tuple[np.ndarray, ...]:
        """``ln|x|`` with 0 where x is 0: it multiplies a factor ``|x|^eps`` that is 0 there (x^eps ln x -> 0)."""
        return tuple(np.log(np.where(magnitude > 0, magnitude, 1.0)) for magnitude in self.magnitude)

    def signed_powers(self, eps1: float, eps2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Eq 1's ``sign(x) |x|^eps`` of each (``0^0 = 0``, so that eps -> 0 gives a box, never NaN)."""
        sign, magnitude = self.sign, self.magnitude
        return (
            sign[0] * magnitude[0] ** eps1,
            sign[1] * magnitude[1] ** eps1,
            sign[2] * magnitude[2] ** eps2,
            sign[3] * magnitude[3] ** eps2,
        )


def superquadric_points(q: np.ndarray, eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Eq 1: ``(n,)`` surface coordinates -> ``(n, 3)`` points of the undeformed superquadric."""
    return _superquadric(q, SurfaceTrig.of(eta, omega))


def _superquadric(q: np.ndarray, trig: SurfaceTrig) -> np.ndarray:
    a, a1, a2, a3, eps1, eps2 = q[:6]
    c_eta, s_eta, c_omega, s_omega = trig.signed_powers(eps1, eps2)
    points = np.empty((len(c_eta), 3))  # filled by column: np.stack's own cost outweighs the arithmetic
    points[:, 0], points[:, 1], points[:, 2] = a1 * c_eta * c_omega, a2 * c_eta * s_omega, a3 * s_eta
    points *= a
    return points


def deform(q: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Eq 2: tapering (t1, t2) along z and bending (b1, b2, b3) in x, applied to ``(n, 3)`` superquadric points."""
    a, a3 = q[0], q[3]
    t1, t2, b1, b2, b3 = q[6:11]
    half_length = a * a3
    z = e[:, 2]
    deformed = np.empty_like(e)
    deformed[:, 0] = (t1 * z / half_length + 1.0) * e[:, 0] + b1 * np.cos((z + b2) / half_length * math.pi * b3)
    deformed[:, 1] = (t2 * z / half_length + 1.0) * e[:, 1]
    deformed[:, 2] = z
    return deformed


def dsq_points(q: np.ndarray, eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Eq 1-2: surface coordinates -> ``(n, 3)`` DSQ points in the part's local frame."""
    return dsq_points_at(q, SurfaceTrig.of(eta, omega))


def dsq_points_at(q: np.ndarray, trig: SurfaceTrig) -> np.ndarray:
    """`dsq_points` of coordinates whose trigonometry is made."""
    q = np.asarray(q, dtype=np.float64)
    return deform(q, _superquadric(q, trig))


def pole_point(q: np.ndarray, top: bool) -> np.ndarray:
    """The deformed pole at eta = +pi/2 (``top``) or -pi/2: where a part meets its child or parent."""
    return _pole_point(np.asarray(q, dtype=np.float64)[: len(SHAPE_NAMES)].tobytes(), top).copy()


@lru_cache(maxsize=64)
def _pole_point(shape: bytes, top: bool) -> np.ndarray:
    """`pole_point` of the shape parameters in ``shape`` (float64 bytes), kept for the shapes last asked: AbIS's arm
    asks for a part's joint again after each part's fit (14 calls a frame, most for a shape already asked)."""
    eta = np.array([math.pi / 2 if top else -math.pi / 2])
    return dsq_points(np.frombuffer(shape, dtype=np.float64), eta, np.zeros(1))[0]


@dataclass(frozen=True, eq=False)
class SampleGrid:
    """Model samples at fixed (eta, omega): ``ids[k]`` names sample k for every parameter value, forever.

    ``ids = i * n_omega + j`` for latitude row i (eta at the row midpoint, bottom to top) and longitude column j.
    """

    n_eta: int
    n_omega: int
    eta: np.ndarray
    omega: np.ndarray
    ids: np.ndarray

    @cached_property
    def trig(self) -> SurfaceTrig:
        """The samples' trigonometry (`dsq_points_at`), made once."""
        return SurfaceTrig.of(self.eta, self.omega)


@lru_cache(maxsize=8)
def sample_grid(n_eta: int, n_omega: int) -> SampleGrid:
    """The (eta, omega) sample grid: row midpoints in eta (no pole duplicates), ``n_omega`` longitudes."""
    if n_eta < 1 or n_omega < 3:
        raise ValueError(f"sample grid {n_eta} x {n_omega}: need n_eta >= 1 and n_omega >= 3")
    eta = -math.pi / 2 + (np.arange(n_eta) + 0.5) * math.pi / n_eta
    omega = -math.pi + np.arange(n_omega) * 2 * math.pi / n_omega
    eta_grid, omega_grid = np.meshgrid(eta, omega, indexing="ij")
    ids = np.arange(n_eta * n_omega)
    for array in (eta_grid, omega_grid, ids):
        array.flags.writeable = False
    return SampleGrid(n_eta, n_omega, eta_grid.ravel(), omega_grid.ravel(), ids)


@dataclass(frozen=True, eq=False)
class MeshTopology:
    """A DSQ triangle mesh's fixed part: where each vertex sits in (eta, omega), faces and texture coordinates.

    Vertices form an ``n_eta x (n_omega + 1)`` grid with eta from -pi/2 to pi/2 inclusive and omega from -pi to pi
    inclusive, so the pole rows and the omega seam repeat vertices: that lets texture coordinates stay continuous.
    ``weld[k]`` is the canonical vertex of vertex k's position; faces re-indexed through ``weld`` form a closed,
    watertight, outward-wound surface. ``uv = ((omega + pi) / 2pi, (eta + pi/2) / pi)``.
    """

    eta: np.ndarray
    omega: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    weld: np.ndarray

    @cached_property
    def trig(self) -> SurfaceTrig:
        """The vertices' trigonometry (`dsq_points_at`), made once."""
        return SurfaceTrig.of(self.eta, self.omega)


@lru_cache(maxsize=8)
def mesh_topology(n_eta: int, n_omega: int) -> MeshTopology:
    if n_eta < 3 or n_omega < 3:
        raise ValueError(f"mesh {n_eta} x {n_omega}: need at least 3 x 3")
    eta = np.linspace(-math.pi / 2, math.pi / 2, n_eta)
    omega = np.linspace(-math.pi, math.pi, n_omega + 1)
    eta_grid, omega_grid = np.meshgrid(eta, omega, indexing="ij")
    cols = n_omega + 1
    index = np.arange(n_eta * cols).reshape(n_eta, cols)

    v00, v01 = index[:-1, :-1], index[:-1, 1:]
    v10, v11 = index[1:, :-1], index[1:, 1:]
    # Counter-clockwise seen from outside: d/domega x d/deta points outwards.
    lower = np.stack([v00, v01, v11], axis=-1)[1:]  # degenerate in the bottom row (v00, v01 are the pole)
    upper = np.stack([v00, v11, v10], axis=-1)[:-1]  # degenerate in the top row (v10, v11 are the pole)
    faces = np.concatenate([lower.reshape(-1, 3), upper.reshape(-1, 3)])

    weld = index.copy()
    weld[0, :] = index[0, 0]
    weld[-1, :] = index[-1, 0]
    weld[:, -1] = weld[:, 0]
    uv = np.stack([(omega_grid + math.pi) / (2 * math.pi), (eta_grid + math.pi / 2) / math.pi], axis=-1)
    return MeshTopology(eta_grid.ravel(), omega_grid.ravel(), faces, uv.reshape(-1, 2), weld.ravel())


def dsq_points_jacobian(q: np.ndarray, eta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``(n, 3, 11)``: derivatives of eq 1-2's local points with respect to the shape parameters `SHAPE_NAMES`.

    Derived by hand from eq 1-2, with ``S = e3 / (a a3) = sign(sin eta)|sin eta|^eps1`` (which does not depend
    on a or a3) and the bending angle ``theta = (S + b2 / (a a3)) pi b3``. Checked against finite differences.
    """
    return dsq_points_jacobian_at(q, SurfaceTrig.of(eta, omega))


def dsq_points_jacobian_at(q: np.ndarray, trig: SurfaceTrig) -> np.ndarray:
    """`dsq_points_jacobian` of coordinates whose trigonometry is made."""
    q = np.asarray(q, dtype=np.float64)
    a, a1, a2, a3, eps1, eps2, t1, t2, b1, b2, b3 = q[:11]
    c_eta, s_eta, c_omega, s_omega = trig.signed_powers(eps1, eps2)
    log_cos_eta, log_sin_eta, log_cos_omega, log_sin_omega = trig.log_magnitude
    half_length = a * a3
    e1, e2, e3 = a * a1 * c_eta * c_omega, a * a2 * c_eta * s_omega, half_length * s_eta
    taper1, taper2 = t1 * s_eta + 1.0, t2 * s_eta + 1.0
    theta = (s_eta + b2 / half_length) * math.pi * b3
    bend_slope = -b1 * np.sin(theta)  # d(b1 cos theta) / d theta

    # d/d eps of the signed powers: x^eps ln|x|.
    de1_eps1, de2_eps1 = e1 * log_cos_eta, e2 * log_cos_eta
    ds_eta_eps1 = s_eta * log_sin_eta
    de1_eps2, de2_eps2 = e1 * log_cos_omega, e2 * log_sin_omega
    derivatives = {  # (parameter, axis of the point): its derivative; every other entry is 0
        ("a", 0): taper1 * e1 / a + bend_slope * (-b2 * math.pi * b3 / (a * half_length)),
        ("a", 1): taper2 * e2 / a,
        ("a", 2): e3 / a,
        ("a1", 0): taper1 * e1 / a1,
        ("a2", 1): taper2 * e2 / a2,
        ("a3", 0): bend_slope * (-b2 * math.pi * b3 / (a3 * half_length)),
        ("a3", 2): e3 / a3,
        ("eps1", 0): t1 * ds_eta_eps1 * e1 + taper1 * de1_eps1 + bend_slope * math.pi * b3 * ds_eta_eps1,
        ("eps1", 1): t2 * ds_eta_eps1 * e2 + taper2 * de2_eps1,
        ("eps1", 2): half_length * ds_eta_eps1,
        ("eps2", 0): taper1 * de1_eps2,
        ("eps2", 1): taper2 * de2_eps2,
        ("t1", 0): s_eta * e1,
        ("t2", 1): s_eta * e2,
        ("b1", 0): np.cos(theta),
        ("b2", 0): bend_slope * math.pi * b3 / half_length,
        ("b3", 0): bend_slope * (s_eta + b2 / half_length) * math.pi,
    }
    jacobian = np.zeros((len(e1), 3, len(SHAPE_NAMES)))  # filled in place: stacking 33 columns cost more
    for (name, axis), derivative in derivatives.items():
        jacobian[:, axis, PARAM_INDEX[name]] = derivative
    return jacobian
