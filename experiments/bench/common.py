"""What every benchmark shares: the default scene built as a run builds it, this process's resident memory, the
machine a report names, and the one JSON line a script reads (``--json``)."""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

from eval.runs import machine_facts
from experiments.components import Components, build, compose

log = logging.getLogger(__name__)


def default_scene(width: int, height: int, *overrides: str) -> Components:
    """The default run's components (the arm, its swing, the orthogonal rig) at ``width`` x ``height``, built as a
    run builds them."""
    return build(compose([f"rig.width={width}", f"rig.height={height}", *overrides]))


def resident_mb() -> float:
    """Resident memory of this process (Linux ``/proc``), in MB."""
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def report_machine() -> None:
    about = machine_facts()
    log.info(
        "machine: %s, %d cores, %s; OpenGL platform %s",
        about["processor"],
        about["cores"],
        about["python"],
        os.environ.get("PYOPENGL_PLATFORM"),
    )


def json_line(target: str, figures: dict) -> str:
    """``figures`` of benchmark ``target`` with the machine, as one line of JSON (numpy scalars as numbers)."""
    record = {"target": target, "machine": machine_facts(), "figures": figures}
    return json.dumps(record, default=lambda value: value.item() if hasattr(value, "item") else str(value))
