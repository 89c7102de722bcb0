"""The recording's default layout (a Rerun blueprint), from the presentations the components registered
(`tracker.presentation`): each view's image with its overlays, the 3-D scene, and the time series, the tracker's
and the model's own panels first. Points without a colour of their own take the palette here.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from experiments.components import Components
from experiments.schemas import RecordSettings
from tracker.presentation import RGB, Panel, Presentation
from tracker.registry import COSTS

# States without a colour of their own take these, in order.
PALETTE: tuple[RGB, ...] = ((0, 220, 0), (0, 160, 255), (255, 40, 40), (150, 150, 150), (255, 200, 0), (200, 0, 200))
POINTS = (255, 255, 0)  # points of no state, unless a presentation names a colour


def time_series(panel: Panel) -> rrb.TimeSeriesView:
    """A panel as a plot of the series under its origin (only those at its contents, when it names them)."""
    contents = [f"$origin/{leaf}" for leaf in panel.contents] or ["$origin/**"]
    return rrb.TimeSeriesView(name=panel.title, origin=panel.origin, contents=contents)


def default_blueprint(
    views: Sequence[str],
    part_names: Sequence[str],
    looks: Sequence[Presentation],
    silhouettes: bool = False,
    weight_maps: Sequence[str] = (),
    estimates: bool = True,
) -> rrb.Blueprint:
    """Each view's image with its overlays on top (with ``silhouettes``: beside it the extracted silhouette and the
    ``weight_maps`` of those costs); below, the 3-D scene and the time series: those of the components' ``looks``
    (tracker first, then model; the estimate's errors only if the tracker ``estimates``), the silhouettes'
    quality, the visible pixels and the timings."""
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
    panels = [panel for look in looks for panel in look.panels(part_names) if estimates or not panel.of_estimate]
    series = [time_series(panel) for panel in panels]
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


def shown_looks(components: Components) -> list[Presentation]:
    """The presentations of the run's tracker and model, the tracker's first (its panels first)."""
    return [components.entries[kind].presentation for kind in ("tracker", "model")]


def weight_map_costs(components: Components, record: RecordSettings) -> list[str]:
    """The costs whose weight maps the recording holds (`RecordSettings.weight_maps`)."""
    return COSTS.names() if "silhouettes" in components.observes and record.weight_maps and record.images else []


def run_blueprint(components: Components, record: RecordSettings) -> rrb.Blueprint:
    """The run's default layout (`experiments.presentation.default_blueprint`)."""
    return default_blueprint(
        components.views,
        components.model.part_names,
        shown_looks(components),
        "silhouettes" in components.observes,
        weight_map_costs(components, record),
        getattr(components.tracker, "estimates", True),
    )
