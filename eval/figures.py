"""Figures from run directories. ``python -m eval.figures <run_dir>`` writes them beside the run's outputs."""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from eval.recordings import read_rgb_frames
from tracker.atomic import atomic_path

log = logging.getLogger(__name__)


def views_sheet(run_dir: str | Path, frames: Sequence[int] | None = None, out: str | Path | None = None) -> Path:
    """A PNG grid of the recorded RGB views: one column per view, one row per frame (default: 4 spread frames)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    views = json.loads((run_dir / "metrics.json").read_text())["views"]
    images = {view: read_rgb_frames(run_dir / "run.rrd", view) for view in views}
    available = sorted(images[views[0]])
    if frames is None:
        frames = [available[i] for i in np.linspace(0, len(available) - 1, min(4, len(available))).astype(int)]
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
    figure.tight_layout()
    out = Path(out) if out is not None else run_dir / "views.png"
    with atomic_path(out) as temporary:
        figure.savefig(temporary, format="png", dpi=80)
    plt.close(figure)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("run_dir", type=Path)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    log.info("wrote %s", views_sheet(args.run_dir))


if __name__ == "__main__":
    main()
