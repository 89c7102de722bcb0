"""How each component's outputs look in the Rerun viewer, keyed by its registered name, and the default layout.

A `Presentation` gives a model's or a tracker's time-series panels (its own questions first) and the colours of
its 2-D points: per state for points with states (AbIS's features: tracked, new, discarded, unpaired), per overlay
name for points without. A component with none gets the defaults: no panels of its own, a fixed palette. A user's
component may register one with `register_presentation`, in its own module.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import rerun.blueprint as rrb

RGB = tuple[int, int, int]
# States without a colour of their own take these, in order.
PALETTE: tuple[RGB, ...] = ((0, 220, 0), (0, 160, 255), (255, 40, 40), (150, 150, 150), (255, 200, 0), (200, 0, 200))
POINTS = (255, 255, 0)  # points of no state, unless a presentation names a colour


def _no_panels(part_names: Sequence[str]) -> list:
    return []


@dataclass(frozen=True)
class Presentation:
    panels: Callable[[Sequence[str]], list] = _no_panels  # part names -> time-series views
    state_colors: Mapping[str, RGB] = field(default_factory=dict)  # a point state -> its colour
    point_colors: Mapping[str, RGB] = field(default_factory=dict)  # an overlay of stateless points -> its colour


_PRESENTATIONS: dict[str, Presentation] = {}


def register_presentation(name: str, presentation: Presentation) -> None:
    _PRESENTATIONS[name] = presentation


def presentation(name: str) -> Presentation:
    return _PRESENTATIONS.get(name, Presentation())


def _series(name: str, origin: str, *leaves: str) -> rrb.TimeSeriesView:
    """A plot of the series under ``origin`` (only those at ``leaves``, glob patterns, when given)."""
    contents = [f"$origin/{leaf}" for leaf in leaves] if leaves else ["$origin/**"]
    return rrb.TimeSeriesView(name=name, origin=origin, contents=contents)


def _paper_part_first(parts: Sequence[str]) -> list[str]:
    """The parts with paper 1's part 2 (the second) first: its pairs and errors are the ones Fig 8-9 show."""
    return [parts[1], parts[0], *parts[2:]] if len(parts) > 1 else list(parts)


register_presentation(
    "abis",
    Presentation(
        panels=lambda parts: [
            *(_series(f"{part} pairs", f"metrics/correspondences/{part}") for part in _paper_part_first(parts)),
            _series("cost (eq 8, px^2)", "metrics/cost"),
        ],
        state_colors={
            "tracked": (0, 220, 0),
            "new": (0, 160, 255),
            "discarded": (255, 40, 40),
            "unpaired": (150, 150, 150),
        },
        point_colors={"estimate": (255, 255, 0)},
    ),
)
register_presentation(
    "tbf",
    Presentation(
        panels=lambda parts: [
            _series("tree: nodes evaluated and kept per level", "metrics/tree", "level*/**"),
            _series("posterior entropy (nats)", "metrics/tree", "entropy"),
        ]
    ),
)
register_presentation(
    "dsq_arm",
    Presentation(
        panels=lambda parts: [
            _series(
                f"{_paper_part_first(parts)[0]}: b1 (m) and r2 (rad), Fig 8",
                f"metrics/params/{_paper_part_first(parts)[0]}",
                "b1/*",
                "r2/*",
            ),
            _series("rotation error (geodesic, deg)", "metrics/error", "*/rotation_error_deg"),
            _series("surface error, same (eta, omega) (mm)", "metrics/error", "*/surface_error_mm"),
            _series("point-to-surface (mm)", "metrics/error", "*/surface_distance_mm"),
        ]
    ),
)
register_presentation(
    "body_mesh",
    Presentation(
        panels=lambda parts: [
            _series("right arm swing (deg)", "metrics/params/swing"),
            _series("joint error (mm; root-aligned: posture)", "metrics/error"),
            _series(
                "right arm joints (deg from the T-pose)",
                "metrics/params/joints",
                "RightArm_deg/*",
                "RightForeArm_deg/*",
            ),
        ]
    ),
)


def default_blueprint(
    views: Sequence[str],
    part_names: Sequence[str],
    shown: Sequence[str],
    silhouettes: bool = False,
    weight_maps: Sequence[str] = (),
) -> rrb.Blueprint:
    """Each view's image with its overlays on top (with ``silhouettes``: beside it the extracted silhouette and the
    ``weight_maps`` of those costs); below, the 3-D scene and the time series: those of the ``shown`` components
    (tracker first, then model), the silhouettes' quality, the visible pixels and the timings."""
    panes = []
    for view in views:
        panes.append(rrb.Spatial2DView(name=view, origin=f"world/cameras/{view}/image"))
        if silhouettes:
            panes.append(
                rrb.Spatial2DView(
                    name=f"{view} silhouette", origin=f"world/cameras/{view}/image", contents=["$origin/silhouette"]
                )
            )
            panes += [
                rrb.Spatial2DView(name=f"{view} {cost} weights", origin=f"capture/{view}/weights/{cost}")
                for cost in weight_maps
            ]
    series = [panel for name in shown for panel in presentation(name).panels(part_names)]
    if silhouettes:
        series.append(rrb.TimeSeriesView(name="silhouette IoU", origin="metrics/silhouette_iou"))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(*panes),
            rrb.Horizontal(
                rrb.Spatial3DView(
                    name="3-D: truth (model colours), estimate (yellow)",
                    origin="world",
                    contents=["$origin/truth/**", "$origin/estimate/**"],
                ),  # framed on the subject
                rrb.Tabs(
                    *series,
                    rrb.TimeSeriesView(name="visible pixels", origin="metrics/visible_px"),
                    rrb.TimeSeriesView(name="timing (ms)", origin="metrics/timing"),
                ),
            ),
            row_shares=[1.0, 1.3],
        ),
        collapse_panels=True,
    )
