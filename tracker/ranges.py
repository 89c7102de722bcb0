"""Allowed values of numeric settings, declared in their types and checked at the boundary.

A setting's type says what it allows: ``Annotated[float, Range(...)]`` (the aliases below name the common ones),
``Literal["sd", "lm"]`` for a choice, ``tuple[float, float, float]`` for a fixed length, ``Annotated[..., Rule(...)]``
for a condition on the whole value. `tracker.settings`
reads these types; `check_in_range` words the message: the key, the value and the range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any


@dataclass(frozen=True)
class Range:
    """An interval; each end closed unless marked open. Infinite ends are allowed."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def contains(self, value: float) -> bool:
        if not math.isfinite(value):  # NaN and infinities are never a valid parameter
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def describe(self) -> str:
        low, high = _number(self.low), _number(self.high)
        if self.high == math.inf and self.low == -math.inf:
            return "a finite number"
        if self.high == math.inf:
            return f"{'>' if self.low_open else '>='} {low}"
        if self.low == -math.inf:
            return f"{'<' if self.high_open else '<='} {high}"
        return f"in {'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"


@dataclass(frozen=True)
class Rule:
    """A condition on a whole value (``Annotated[tuple[...], Rule(...)]``): ``holds(value)``, worded ``says``."""

    holds: Callable[[Any], bool]
    says: str


def _number(value: float) -> str:
    """Integers exactly (``4294967295``, not ``4.29497e+09``), other numbers compactly."""
    return str(int(value)) if math.isfinite(value) and float(value).is_integer() else f"{value:g}"


def check_in_range(name: str, value: float, allowed: Range) -> None:
    """Raise ``ValueError`` naming ``name``, ``value`` and the range unless ``value`` lies in it."""
    if not allowed.contains(float(value)):
        raise ValueError(f"{name}={value!r} is out of range: allowed {allowed.describe()}")


ANY = Range()
POSITIVE = Range(0.0, math.inf, low_open=True)
NON_NEGATIVE = Range(0.0, math.inf)

# Types of settings, with what they allow.
Finite = Annotated[float, ANY]
Positive = Annotated[float, POSITIVE]
NonNegative = Annotated[float, NON_NEGATIVE]
Count = Annotated[int, Range(1, math.inf)]  # one or more
Fraction = Annotated[float, Range(0.0, 1.0)]
Byte = Annotated[int, Range(0, 255)]
ImageSide = Annotated[int, Range(16, 4096)]  # pixels
Seed = Annotated[int, Range(0, 2**32 - 1)]
Vector3 = tuple[Finite, Finite, Finite]
# A grid axis: [start, stop, step], stop included (`tracker.tbf.sample_spec.span_values`).
Span = Annotated[
    tuple[Finite, Finite, Positive],
    Rule(lambda span: span[0] <= span[1], "allowed [start, stop, step] with start <= stop"),
]
RGB = tuple[Byte, Byte, Byte]
