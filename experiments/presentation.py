"""The recording's default layout (a Rerun blueprint), from the presentations the components registered
(`tracker.presentation`): each view's image with its overlays, the 3-D scene framed on the subject, and the time
series (the estimate's errors and the run's timings first, then the components' own panels), each series a colour
of its own in its plot. Points without a colour of their own take the palette here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import rerun.blueprint as rrb

from experiments.components import Components
from experiments.schemas import RecordSettings
from tracker.presentation import MOST_SERIES, RGB, Panel, Presentation, part_panels
from tracker.registry import COSTS

# The 3-D view's eye stands where the sphere round every place the subject takes fills this half-angle of the view
# (Rerun's eye sees about 27 degrees above and below its axis: a margin for wide and tall panels alike), looking a
# little down (`EYE_ELEVATION_DEG`) from the first camera's side.
EYE_HALF_ANGLE_DEG = 20.0
EYE_ELEVATION_DEG = 15.0
EYE_FRAMES = 16  # the frames, spread over the run, whose truth surfaces bound the subject

# A plot's series take these, in order, each a colour no other series of the plot has (a series named after a
# part or a point state takes its colour when it is free): one a series, `MOST_SERIES` at most.
SERIES_PALETTE: tuple[RGB, ...] = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
    (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207), (255, 255, 255), (255, 215, 0),
)  # fmt: skip
SERIES_WIDTH_PX = 2.0  # a plot's lines: thin ones of near colours blur together on the viewer's dark background

# States without a colour of their own take these, in order.
PALETTE: tuple[RGB, ...] = ((0, 220, 0), (0, 160, 255), (255, 40, 40), (150, 150, 150), (255, 200, 0), (200, 0, 200))
POINTS = (255, 255, 0)  # points of no state, unless a presentation names a colour


def subject_eye(components: Components) -> rrb.EyeControls3D:
    """The 3-D view's eye, framing the subject's truth surfaces at `EYE_FRAMES` frames spread over the run."""
    model, scene, frames = components.model, components.scene, components.settings.frames
    picked = np.unique(np.linspace(0, frames - 1, EYE_FRAMES).round().astype(int))
    points = np.concatenate(
        [mesh.vertices for frame in picked for mesh in model.surface_meshes(scene.params(model, int(frame)))]
    )
    low, high = points.min(axis=0), points.max(axis=0)
    center, radius = (low + high) / 2, max(float(np.linalg.norm(high - low)) / 2, 1e-3)
    side = components.cameras[0].position[:2] - center[:2]
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-9 else np.array([0.0, -1.0])
    up = np.radians(EYE_ELEVATION_DEG)
    direction = np.array([*(np.cos(up) * side), np.sin(up)])
    position = center + direction * radius / np.sin(np.radians(EYE_HALF_ANGLE_DEG))
    return rrb.EyeControls3D(position=position, look_target=center, eye_up=(0.0, 0.0, 1.0))


def time_series(panel: Panel) -> rrb.TimeSeriesView:
    """A panel as a plot of the series under its origin (only those at its contents, when it names them)."""
    contents = [f"$origin/{leaf}" for leaf in panel.contents] or ["$origin/**"]
    return plot(name=panel.title, origin=panel.origin, contents=contents)


def plot(**view) -> rrb.TimeSeriesView:
    """A time-series view with its legend in the top left corner (a run's series start near 0 and grow)."""
    return rrb.TimeSeriesView(**view, plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftTop))


def views_of(container) -> list:
    """A blueprint container's views, depth first (a view has an origin; a container holds views or containers)."""
    if hasattr(container, "origin"):
        return [container]
    return [view for item in container.contents for view in views_of(item)]


def shows(view, entity: str) -> bool:
    """Whether ``view`` shows ``entity`` by Rerun's entity filter rules: a path matches itself; ``path/**`` matches
    it and everything below; no other wildcard is supported (a rule that uses one matches nothing, as in Rerun); a
    rule ``- <path>`` leaves out what it matches."""
    origin = "/" + str(view.origin).strip("/")
    contents = view.contents or "$origin/**"
    lines = contents.splitlines() if isinstance(contents, str) else contents  # one query string, or a list
    entity, included, excluded = "/" + entity.strip("/"), False, False
    for line in lines:
        line = line.strip()
        rule = line.removeprefix("+ ").removeprefix("- ").replace("$origin", origin)
        path = "/" + rule.strip("/").removesuffix("/**").strip("/")
        if "*" not in path and (entity == path or (rule.endswith("/**") and entity.startswith(path + "/"))):
            excluded |= line.startswith("- ")
            included |= not line.startswith("- ")
    return included and not excluded


def series_colors(blueprint: rrb.Blueprint, series: Sequence[str], named: Mapping[str, RGB]) -> dict[str, RGB]:
    """A colour for each of the ``series`` entities: plot by plot of ``blueprint``, each series not yet coloured
    takes the colour ``named`` after its name (its path's last part, e.g. a pair state) if no other series of the
    plot has it, else the first of `SERIES_PALETTE` the plot has not used."""
    colours: dict[str, RGB] = {}
    for view in views_of(blueprint.root_container):
        if not isinstance(view, rrb.TimeSeriesView):
            continue
        shown = sorted(entity for entity in series if shows(view, entity))
        taken = {colours[entity] for entity in shown if entity in colours}
        for entity in shown:
            if entity in colours:
                continue
            colour = named.get(entity.rsplit("/", 1)[-1])
            if colour is None or colour in taken:
                free = [c for c in SERIES_PALETTE if c not in taken]
                colour = free[0] if free else SERIES_PALETTE[len(taken) % len(SERIES_PALETTE)]
            colours[entity] = colour
            taken.add(colour)
    return colours


def default_blueprint(
    views: Sequence[str],
    part_names: Sequence[str],
    looks: Sequence[Presentation],
    silhouettes: bool = False,
    weight_maps: Sequence[str] = (),
    estimates: bool = True,
    eye: rrb.EyeControls3D | None = None,
) -> rrb.Blueprint:
    """Each view's image with its overlays on top (with ``silhouettes``, the extracted silhouette over it and the
    ``weight_maps`` of those costs in tabs behind it); below, the 3-D scene and the time series: those of the
    components' ``looks`` (tracker first, then model; the estimate's errors only if the tracker ``estimates``), the
    silhouettes' quality and the visible pixels; the estimate's errors, then the run's timings first. ``eye``: the
    3-D view's (`subject_eye`; None: Rerun's)."""
    panes = []
    for view in views:
        image = rrb.Spatial2DView(name=view, origin=f"world/cameras/{view}/image")  # the silhouette drawn over it
        weights = [
            rrb.Spatial2DView(name=f"{view} {cost} weights", origin=f"capture/{view}/weights/{cost}")
            for cost in (weight_maps if silhouettes else ())
        ]
        panes.append(rrb.Tabs(image, *weights, name=view) if weights else image)  # one pane a view
    panels = [panel for look in looks for panel in look.panels(part_names) if estimates or not panel.of_estimate]
    timing = plot(name="timing (ms)", origin="metrics/timing", contents=["$origin/**", "- $origin/estimate/**"])
    series = [time_series(panel) for panel in panels if panel.of_estimate]
    series += [timing, *(time_series(panel) for panel in panels if not panel.of_estimate)]
    if silhouettes:
        series.append(plot(name="silhouette IoU", origin="metrics/silhouette_iou"))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(*panes),
            rrb.Horizontal(
                rrb.Spatial3DView(
                    name="3-D: truth (model colours), estimate (yellow)",
                    origin="world",
                    contents=["$origin/truth/**", "$origin/estimate/**"],
                    eye_controls=eye,
                ),
                rrb.Tabs(*series, *visible_pixel_plots(views, part_names)),
            ),
            row_shares=[1.0, 1.3],
        ),
        collapse_panels=True,
    )


def visible_pixel_plots(views: Sequence[str], part_names: Sequence[str]) -> list[rrb.TimeSeriesView]:
    """The parts' visible pixels: one plot of every view's, or where that makes more than `MOST_SERIES` series, each
    view's parts over as few plots as hold them (`part_panels`)."""
    if len(views) * len(part_names) <= MOST_SERIES:
        return [plot(name="visible pixels", origin="metrics/visible_px")]
    return [
        time_series(panel)
        for view in views
        for panel in part_panels(f"visible pixels, {view}", f"metrics/visible_px/{view}", part_names)
    ]


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
        subject_eye(components),
    )
