"""Every figure that applies to a run, beside its outputs: ``python -m eval.figures <run_dir> [...]``.

A figure applies when the run's table has the columns it draws, its ``metrics.json`` the figures it reads, and its
recording the images it shows (`RUN_FIGURES`), whatever the tracker and the model:
    views.png                     each view's recorded images at four frames          any run with images
    fig6_input_views.png,         paper 1's Fig 6 and 7: the input, and the estimated  the DSQ arm estimated
    fig7_estimated_views.png      model rendered from the same views
    fig8_part2_b1_r2.png          paper 1's Fig 8: part 2's b1 and r2                 the DSQ arm estimated
    fig9_part2_correspondences.png  paper 1's Fig 9: part 2's pairs                   AbIS's pairs on the arm
    fig5_strip.png                paper 2's Fig 5: the estimated skeleton over the    the body estimated
                                  input at seven frames
    error_against_floor.png       the joint error per frame, against the dictionary's the body estimated
                                  floor where the tracker searched one
    fig4c_swings.png              Fig 4(c)'s evidence: the right arm's angle, truth   the body's arm swings
                                  against estimate, each swing's verdict
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from eval.arm_figures import fig6_fig7_sheets, fig8_part2_b1_r2, fig9_part2_correspondences
from eval.body_figures import error_against_floor, fig5_strip, swing_traces
from eval.plotting import views_sheet

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunFigure:
    """A figure of one run: what draws it into the run's folder (its paths), and what it needs of the run: the
    ``frames.parquet`` columns it draws, the ``metrics.json`` keys it reads, and whether the recording's images."""

    draw: Callable[[Path], list[Path]]
    columns: frozenset[str] = frozenset()
    metrics: frozenset[str] = frozenset()
    images: bool = False

    def applies(self, columns: set[str], metrics: dict) -> bool:
        recorded = metrics.get("config", {}).get("record", {}).get("images", False)
        return self.columns <= columns and self.metrics <= metrics.keys() and (recorded or not self.images)


def _swings(run: Path) -> list[Path]:
    """Fig 4(c)'s evidence for a run whose truth made at least one complete right-arm swing."""
    if not json.loads((run / "metrics.json").read_text())["swing_details"]["start"]:
        return []
    return [swing_traces({run.name: run}, run / "fig4c_swings.png")]


_ARM_ESTIMATE = frozenset({"est_a", "est_b1", "est_r2", "truth_b1", "truth_r2"})
_BODY_ESTIMATE = frozenset({"truth_pose", "est_pose", "joint_error_mm", "joint_error_aligned_mm"})
_PAIRS = frozenset({"tracked", "new", "discarded_occlusion", "discarded_error", "lost"})
RUN_FIGURES = (
    RunFigure(lambda run: [views_sheet(run)], images=True),
    RunFigure(fig6_fig7_sheets, _ARM_ESTIMATE, images=True),
    RunFigure(lambda run: [fig8_part2_b1_r2(run)], _ARM_ESTIMATE, frozenset({"part2_b1_rms"})),
    RunFigure(lambda run: [fig9_part2_correspondences(run)], _ARM_ESTIMATE | _PAIRS),
    RunFigure(lambda run: [fig5_strip(run, run / "fig5_strip.png")], _BODY_ESTIMATE, images=True),
    RunFigure(lambda run: [error_against_floor(run, run / "error_against_floor.png")], _BODY_ESTIMATE),
    RunFigure(_swings, frozenset({"swing_truth_deg", "swing_est_deg"}), frozenset({"swing_details"})),
)


def write_figures(run_dir: str | Path) -> list[Path]:
    """Every figure of `RUN_FIGURES` that applies to the run, written into its folder; their paths."""
    import pyarrow.parquet as pq

    run_dir = Path(run_dir)
    columns = set(pq.read_schema(run_dir / "frames.parquet").names)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    return [path for figure in RUN_FIGURES if figure.applies(columns, metrics) for path in figure.draw(run_dir)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dirs", nargs="+", type=Path)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for run_dir in args.run_dirs:
        for path in write_figures(run_dir):
            log.info("wrote %s", path)


if __name__ == "__main__":
    main()
