"""A run folder as a row: every ``metrics.json`` under some folders, with its choices, overrides, numeric metrics and
stage timings, gathered into one table (`collect`), which every other table reads; and a table as markdown."""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import pandas as pd

_NOT_METRICS = {"seed", "frames", "frames_done"}


def collect(directories: list[Path]) -> pd.DataFrame:
    """One row per run: its choices, its overrides other than ``seed``, seed, status, every top-level numeric
    metric, the swing counts where it scored swings, and its stage timings (medians, ``timings.json``)."""
    rows = []
    for directory in directories:
        for path in sorted(Path(directory).rglob("metrics.json")):
            metrics = json.loads(path.read_text())
            swings = metrics.get("swings", {})
            numbers = {
                k: v
                for k, v in metrics.items()
                if isinstance(v, int | float) and not isinstance(v, bool) and k not in _NOT_METRICS
            }
            timings_path = path.parent / "timings.json"
            timings = json.loads(timings_path.read_text()) if timings_path.exists() else {}
            rows.append(
                {
                    **metrics.get("choices", {}),
                    "overrides": " ".join(_overrides(path.parent)),
                    "seed": metrics.get("seed"),
                    "status": metrics.get("status"),
                    "frames": metrics.get("frames_done"),
                    **numbers,
                    "fail": swings.get("fail"),
                    "error": swings.get("error"),
                    "success": swings.get("success"),
                    "samples": metrics.get("samples"),
                    **timings,
                    "run": str(path.parent),
                    "floor_success": metrics.get("swings_floor", {}).get("success"),
                    "swing_followed": metrics.get("swing_details", {}).get("followed", []),
                    "swing_max_error_deg": metrics.get("swing_details", {}).get("max_error_deg", []),
                }
            )
    return pd.DataFrame(rows)


def _overrides(run: Path) -> list[str]:
    """The job's command-line overrides (Hydra's ``.hydra/overrides.yaml``) other than ``seed``."""
    path = run / ".hydra" / "overrides.yaml"
    if not path.exists():
        return []
    lines = [line.removeprefix("- ").strip() for line in path.read_text().splitlines() if line.startswith("- ")]
    return sorted(line for line in lines if not line.startswith("seed="))


def markdown(table: pd.DataFrame) -> str:
    header = "| " + " | ".join(map(str, table.columns)) + " |"
    rule = "|" + "---|" * len(table.columns)
    lines = ["| " + " | ".join("" if pd.isna(v) else str(v) for v in row) + " |" for row in table.itertuples(False)]
    return "\n".join([header, rule, *lines])


def machine_facts() -> dict[str, object]:
    """This machine as a report names it: processor, cores, Python."""
    return {
        "processor": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "python": platform.python_implementation() + " " + platform.python_version(),
    }


def machine() -> str:
    facts = machine_facts()
    return f"{facts['processor']}, {facts['cores']} cores, Python {platform.python_version()}"
