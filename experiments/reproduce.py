"""``make reproduce``: regenerate what the papers report, into ``reports/``.

So far (issue 2) that is paper 1's scene: the 3-part DSQ arm rendered from the front, left and top views and
recorded, with a contact sheet of the views. Later capabilities add the trackers' figures and tables here.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from eval.figures import views_sheet

REPORTS = Path("reports")


def run_experiment(name: str, *overrides: str) -> Path:
    """Run ``experiment=<name>`` through the real CLI into ``reports/<name>``; fail loudly if the run failed."""
    run_dir = REPORTS / name
    command = [sys.executable, "-m", "experiments.run", f"experiment={name}", f"hydra.run.dir={run_dir}", *overrides]
    subprocess.run(command, check=True)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    if metrics["status"] != "ok":
        raise SystemExit(f"{name}: {metrics['status']}")
    return run_dir


def main() -> None:
    start = time.perf_counter()
    run_dir = run_experiment("arm_scene")
    sheet = views_sheet(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    hidden = metrics["min_visible_fraction"]["forearm"]
    print(
        f"\nPaper 1 scene: {metrics['frames_done']} frames x {len(hidden)} views in {time.perf_counter() - start:.0f} s"
        f" (render {metrics['timing']['render_ms_per_view_median']:.1f} ms per view at 320x240).\n"
        f"Forearm at its most hidden, fraction of its pixels still visible: "
        + ", ".join(f"{view} {fraction:.2f}" for view, fraction in hidden.items())
        + f"\nViews at a glance: {sheet}\n"
        f"Recording:         {run_dir / 'run.rrd'}\n"
        f"Open it with:      .venv/bin/rerun {run_dir / 'run.rrd'}"
    )


if __name__ == "__main__":
    main()
