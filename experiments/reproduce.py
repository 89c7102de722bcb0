"""``make reproduce``: regenerate what the papers report, into ``reports/``.

Paper 1 (AbIS): the 3-part DSQ arm tracked from 3 orthogonal views with Levenberg-Marquardt and with the paper's
steepest descent; Fig 8 and Fig 9 of the LM run in ``reports/``, each run's figures, recording and tables in
``reports/<run>/``. Paper 2 (silhouette tree-based filtering) joins with its issues.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from eval.figures import write_figures

REPORTS = Path("reports")


def run_experiment(name: str, run_name: str, *overrides: str) -> Path:
    """Run ``experiment=<name>`` through the real CLI into ``reports/<run_name>``; fail loudly if it failed."""
    run_dir = REPORTS / run_name
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    subprocess.run(command, check=True)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{run_name}: {metrics['status']}")
    return run_dir


def main() -> None:
    start = time.perf_counter()
    lines = []
    for optimizer in ("lm", "sd"):
        run_dir = run_experiment("abis_fig8_fig9", f"abis_{optimizer}", f"tracker.fit.optimizer={optimizer}")
        figures = write_figures(run_dir)
        metrics = json.loads((run_dir / "metrics.json").read_text())
        lines.append(
            f"  {optimizer}: part2_b1_rms {metrics['part2_b1_rms'] * 1e3:.1f} mm "
            f"({100 * metrics['part2_b1_rms'] / metrics['part2_b1_range']:.1f}% of the b1 range), "
            f"part2_r2_rms {metrics['part2_r2_rms_deg']:.2f} deg, "
            f"estimation {metrics['timing']['estimate_ms_median']:.0f} ms/frame (median), "
            f"recording {run_dir / 'run.rrd'}"
        )
        if optimizer == "lm":
            for figure in figures[1:]:
                shutil.copyfile(figure, REPORTS / figure.name)
    print(
        f"\nPaper 1 (AbIS), {metrics['frames_done']} frames x 3 views, in {time.perf_counter() - start:.0f} s:\n"
        + "\n".join(lines)
        + f"\nFig 8: {REPORTS / 'fig8_part2_b1_r2.png'}\nFig 9: {REPORTS / 'fig9_part2_correspondences.png'}\n"
        f"Open a recording with: .venv/bin/rerun {REPORTS / 'abis_lm' / 'run.rrd'}"
    )


if __name__ == "__main__":
    main()
