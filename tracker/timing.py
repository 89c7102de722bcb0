"""Stage timings: milliseconds since a `time.perf_counter` reading."""

from __future__ import annotations

import time


def elapsed_ms(start: float) -> float:
    """Milliseconds since ``start`` (a `time.perf_counter` value)."""
    return 1e3 * (time.perf_counter() - start)
