"""What every benchmark shares: the default scene built as a run builds it, this process's resident memory, and the
machine a report names."""

from __future__ import annotations

import logging
import os
import platform
from pathlib import Path

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
    log.info(
        "machine: %s, %d cores, %s; OpenGL platform %s",
        platform.processor() or platform.machine(),
        os.cpu_count(),
        platform.python_implementation() + " " + platform.python_version(),
        os.environ.get("PYOPENGL_PLATFORM"),
    )
