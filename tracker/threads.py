"""The process' worker threads: work that releases the GIL (OpenCV, NumPy on large arrays, SciPy's sparse
products) and is independent within a frame runs on them, one per core (at most `MAX_WORKERS`). A forked child
makes its own pool, as the parent's threads do not exist in it."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

MAX_WORKERS = 4

_pool: ThreadPoolExecutor | None = None


def worker_pool() -> ThreadPoolExecutor:
    """The process' pool (made at first use)."""
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(min(MAX_WORKERS, os.cpu_count() or 1), thread_name_prefix="worker")
    return _pool


def _forget_pool() -> None:
    global _pool
    _pool = None


os.register_at_fork(after_in_child=_forget_pool)
