"""Paper 1's figures from a run of the DSQ arm: Fig 6 and 7 (the input images, and the estimated model rendered from
the same views), Fig 8 (part 2's b1 and r2, estimated and true) and Fig 9 (part 2's pairs)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from eval.plotting import image_sheet, pyplot, save_png, views_sheet
from tracker.presentation import PAPER_PART


def fig6_fig7_sheets(run_dir: str | Path, frames: Sequence[int] | None = None) -> list[Path]:
    """Paper 1, Fig 6 and Fig 7: the input images, and the estimated model rendered from the same views, at the
    same frames (default: five spread over the run)."""
    from tracker import catalog  # noqa: F401  (registers the built-in components)
    from tracker.registry import REGISTRIES
    from tracker.render.offscreen import SceneRenderer

    run_dir = Path(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    config = metrics["config"]
    model = REGISTRIES["model"].build(metrics["choices"]["model"], config["model"])
    rigs = REGISTRIES["rig"]
    cameras = rigs.build(rigs.entry_for(config["rig"]["_target_"]).name, config["rig"])
    table = _estimates(run_dir, model)
    if frames is None:
        done = sorted(table)
        frames = sorted(set(np.linspace(done[0], done[-1], min(5, len(done))).round().astype(int).tolist()))
    with SceneRenderer(cameras[0].width, cameras[0].height) as renderer:
        estimated = {frame: renderer.render(cameras, model.surface_meshes(table[frame])) for frame in frames}
    images = {camera.name: {frame: views[camera.name].rgb for frame, views in estimated.items()} for camera in cameras}
    return [
        views_sheet(run_dir, frames, run_dir / "fig6_input_views.png"),
        image_sheet(images, frames, run_dir / "fig7_estimated_views.png"),
    ]


def _estimates(run_dir: Path, model) -> dict[int, np.ndarray]:
    """Frame -> the estimated ``(n_parts, 17)`` parameters of the DSQ arm, from the run's table."""
    import pandas as pd

    from tracker.models.dsq import PARAM_NAMES

    table = pd.read_parquet(run_dir / "frames.parquet")
    columns = [f"est_{name}" for name in PARAM_NAMES]
    return {
        int(frame): np.stack([rows[rows["part"] == part][columns].to_numpy()[0] for part in model.part_names])
        for frame, rows in table.groupby("frame")
    }


def fig8_part2_b1_r2(run_dir: str | Path, out: str | Path | None = None) -> Path:
    """Paper 1, Fig 8: part 2's bending b1 and rotation r2, estimated and true, over the frames."""
    plt = pyplot()
    run_dir = Path(run_dir)
    rows = _paper_part_rows(run_dir)
    figure, (bend, turn) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    bend.plot(rows["frame"], rows["truth_b1"], "k-", label="true")
    bend.plot(rows["frame"], rows["est_b1"], "C1.-", markersize=3, label="estimated")
    bend.set_ylabel("b1 (m)")
    turn.plot(rows["frame"], np.degrees(rows["truth_r2"]), "k-", label="true")
    turn.plot(rows["frame"], np.degrees(rows["est_r2"]), "C0.-", markersize=3, label="estimated")
    turn.set_ylabel("r2 (degrees)")
    turn.set_xlabel("frame")
    _shade_hidden(bend, rows), _shade_hidden(turn, rows)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    bend.set_title(
        f"part 2 ({rows['part'].iloc[0]}): b1 RMS {metrics['part2_b1_rms'] * 1e3:.1f} mm "
        f"(range {metrics['part2_b1_range'] * 1e3:.0f} mm), r2 RMS {metrics['part2_r2_rms_deg']:.2f} deg, "
        f"{_tracker_name(metrics)}",
        fontsize=9,
    )
    bend.legend(loc="upper right", fontsize=8)
    return save_png(plt, figure, Path(out) if out else run_dir / "fig8_part2_b1_r2.png")


def fig9_part2_correspondences(run_dir: str | Path, out: str | Path | None = None) -> Path:
    """Paper 1, Fig 9: part 2's new, discarded and tracked pairs per frame, over all views (top) and in each view
    (below; grey where part 2 is mostly hidden in that view)."""
    plt = pyplot()
    run_dir = Path(run_dir)
    rows = _paper_part_rows(run_dir)
    views = json.loads((run_dir / "metrics.json").read_text())["views"]
    figure, axes = plt.subplots(
        1 + len(views),
        1,
        figsize=(7, 3.8 + 1.6 * len(views)),
        sharex=True,
        gridspec_kw={"height_ratios": [2.2] + [1] * len(views)},
    )
    styles = {"tracked": "C2-", "new": "C0-", "discarded_occlusion": "C3-", "discarded_error": "C1--", "lost": "C7:"}
    for axis, view in zip(axes, [None, *views], strict=True):
        suffix = "" if view is None else f"_{view}"
        for count, style in styles.items():
            axis.plot(rows["frame"], rows[count + suffix], style, label=count.replace("_", " "))
        _shade_hidden(axis, rows, view)
        axis.set_ylabel("pairs of part 2" if view is None else view)
    axes[0].legend(fontsize=8, ncol=3)
    axes[-1].set_xlabel("frame")
    return save_png(plt, figure, Path(out) if out else run_dir / "fig9_part2_correspondences.png")


def _paper_part_rows(run_dir: Path):
    """Paper 1's part 2 (`tracker.presentation.PAPER_PART`), frame by frame."""
    import pandas as pd

    table = pd.read_parquet(run_dir / "frames.parquet")
    if "est_b1" not in table.columns:
        raise ValueError(f"{run_dir} has no estimates of the DSQ arm (run it with a tracker, e.g. tracker=abis)")
    part = table["part"].drop_duplicates().iloc[PAPER_PART]
    return table[table["part"] == part].sort_values("frame")


def _tracker_name(metrics: dict) -> str:
    """The run's tracker, with its optimiser where it has one (AbIS: lm or sd)."""
    optimizer = metrics["config"]["tracker"].get("fit", {}).get("optimizer")
    return f"tracker {metrics['choices']['tracker']}" + (f", optimizer {optimizer}" if optimizer else "")


def _shade_hidden(axis, rows, view: str | None = None) -> None:
    """Grey where part 2 is mostly hidden (under 20% of its largest visible area) in ``view``, or in any view."""
    columns = [c for c in rows.columns if c.startswith("visible_px_") and (view is None or c.endswith(f"_{view}"))]
    hidden = np.zeros(len(rows), bool)
    for column in columns:
        pixels = rows[column].to_numpy()
        hidden |= pixels < 0.2 * max(pixels.max(), 1)
    frames = rows["frame"].to_numpy()
    for frame in frames[hidden]:
        axis.axvspan(frame - 0.5, frame + 0.5, color="0.9", linewidth=0, zorder=0)
