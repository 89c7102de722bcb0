"""Drawing with matplotlib, off-screen (the Agg backend, loaded only when a figure is drawn), written atomically;
and sheets of a run's recorded images, a column per view and a row per frame."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from eval.recordings import read_rgb_frames
from tracker.atomic import atomic_path


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(plt, figure, out: Path) -> Path:
    figure.tight_layout()
    with atomic_path(out) as temporary:
        figure.savefig(temporary, format="png", dpi=100)
    plt.close(figure)
    return out


def views_sheet(run_dir: str | Path, frames: Sequence[int] | None = None, out: str | Path | None = None) -> Path:
    """A PNG grid of the recorded RGB views: one column per view, one row per frame (default: 4 spread frames)."""
    run_dir = Path(run_dir)
    views = json.loads((run_dir / "metrics.json").read_text())["views"]
    images = {view: read_rgb_frames(run_dir / "run.rrd", view) for view in views}
    available = sorted(images[views[0]])
    if frames is None:
        frames = [available[i] for i in np.linspace(0, len(available) - 1, min(4, len(available))).astype(int)]
    return image_sheet(images, frames, Path(out) if out is not None else run_dir / "views.png")


def image_sheet(images: dict[str, dict[int, np.ndarray]], frames: Sequence[int], out: Path) -> Path:
    """Images (view -> frame -> RGB) in a grid: one column per view, one row per frame."""
    plt = pyplot()
    views = list(images)
    figure, axes = plt.subplots(len(frames), len(views), figsize=(3.2 * len(views), 2.5 * len(frames)), squeeze=False)
    for row, frame in enumerate(frames):
        for column, view in enumerate(views):
            axis = axes[row, column]
            axis.imshow(images[view][frame])
            axis.set_xticks([]), axis.set_yticks([])
            if row == 0:
                axis.set_title(view)
            if column == 0:
                axis.set_ylabel(f"frame {frame}")
    return save_png(plt, figure, out)
