"""How a component's outputs look in a run's recording, stated in its registration (`tracker.registry`) as plain data:
the time-series panels it adds to the default layout and the colours of its 2-D points. The experiment layer
turns them into the recording's blueprint (`experiments.presentation`); the core knows nothing of Rerun.

A panel plots the series under one entity path of the recording: ``metrics/<name>`` for a tracker's
`tracker.protocol.StepResult.series` and for the model's parameters (``metrics/params/...``) and errors
(``metrics/error/...``), and for its stages' timings (``metrics/timing/estimate/<stage>_ms``: `STAGES_PANEL`). Points
(`tracker.protocol.Points`) with states take their state's colour, points without their overlay's; what a presentation
leaves out takes the recording's palette.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

RGB = tuple[int, int, int]
PAPER_PART = 1  # paper 1's "part 2" (it counts from 1): the second part, whose pairs and errors Fig 8-9 show


@dataclass(frozen=True)
class Panel:
    """A time-series plot: its ``title``, the entity path it shows (``origin``) and, when given, only the series at
    these paths below it (``contents``, e.g. ``("entropy",)``; ``"level1/**"``: that path and all below it, the
    one wildcard Rerun's entity filters support: no other ``*``)."""

    title: str
    origin: str
    contents: tuple[str, ...] = ()
    of_estimate: bool = False  # it plots the estimate's errors: left out when the tracker estimates nothing


# The tracker's own stages of its estimate (`tracker.protocol.StepResult.timings_ms`), as the run records them.
STAGES_PANEL = Panel("the estimate's stages (ms)", "metrics/timing/estimate")


MOST_SERIES = 12  # a plot's series at most: more cannot be told apart


def part_panels(title: str, origin: str, parts: Sequence[str]) -> list[Panel]:
    """A plot of the series ``<origin>/<part>`` of every part, or where they are more than `MOST_SERIES`, as few
    plots as hold them, titled ``<title> (k/n)``."""
    if len(parts) <= MOST_SERIES:
        return [Panel(title, origin)]
    count = -(-len(parts) // MOST_SERIES)
    size = -(-len(parts) // count)
    groups = [tuple(parts[k : k + size]) for k in range(0, len(parts), size)]
    return [Panel(f"{title} ({k + 1}/{count})", origin, group) for k, group in enumerate(groups)]


def no_panels(part_names: Sequence[str]) -> tuple[Panel, ...]:
    return ()


@dataclass(frozen=True)
class Presentation:
    """A component's look: its panels for the model's part names (its own questions first), the colour of each
    point state (e.g. a feature's "tracked"), and of each overlay of stateless points (e.g. "estimate")."""

    panels: Callable[[Sequence[str]], Sequence[Panel]] = no_panels
    state_colors: Mapping[str, RGB] = field(default_factory=dict)
    point_colors: Mapping[str, RGB] = field(default_factory=dict)


def paper_part_first(parts: Sequence[str]) -> list[str]:
    """The parts with paper 1's part 2 (`PAPER_PART`) first: its pairs and errors are the ones Fig 8-9 show."""
    parts = list(parts)
    return [parts[PAPER_PART], *parts[:PAPER_PART], *parts[PAPER_PART + 1 :]] if len(parts) > PAPER_PART else parts
