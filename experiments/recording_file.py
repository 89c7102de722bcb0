"""A recording's file: Rerun's stream saved under a temporary name beside ``run.rrd`` and renamed once complete,
so a crashed run leaves no partial file, and a full disk fails it with `RecordingLost` rather than hanging it.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable
from pathlib import Path

import rerun as rr

from tracker.atomic import AtomicFile

APPLICATION_ID = "articulated-tracking"
# Rows wait in memory (up to 64 MiB) and go out in large chunks: a whole run of a series in one.
BATCHES = rr.ChunkBatcherConfig(
    flush_tick=datetime.timedelta(hours=1), flush_num_bytes=64 << 20, flush_num_rows=1 << 22
)
# The recording's last write may take this long; a writer that has not finished by then has failed (on a full disk
# Rerun's file writer stops, and a flush without a timeout waits for it for ever).
FLUSH_TIMEOUT_S = 60.0


class RecordingLost(OSError):
    """``run.rrd`` could not be written (nothing half-written is left: its temporary file is removed)."""


class RecordingFile:
    """``path``'s stream (``stream``), with ``blueprint`` as its layout; `close` flushes, closes and renames it.

    The layout is made active, not only the default: the viewer keeps one active layout per application, so a run of
    another model or rig opened after this one would otherwise show this one's views (empty, framed elsewhere).
    """

    def __init__(self, path: Path, recording_id: str, blueprint: rr.BlueprintLike) -> None:
        self.path = path
        self._file: AtomicFile | None = AtomicFile(path)
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, batcher_config=BATCHES)
        self.stream.save(self._file.temporary)
        self.stream.send_blueprint(blueprint, make_active=True, make_default=True)

    def close(self, last_writes: Callable[[], None] = lambda: None) -> None:
        """``last_writes``, then flush the stream (within `FLUSH_TIMEOUT_S`), close the file and give it its name
        (idempotent)."""
        if self._file is None:
            return
        file, self._file = self._file, None
        try:
            last_writes()
            self.stream.flush(timeout_sec=FLUSH_TIMEOUT_S)
            self.stream.disconnect()
            file.commit()
        except Exception as error:  # Rerun's writer failed (a full disk): its flush raises, or never returns
            file.discard()
            raise RecordingLost(f"{self.path} could not be written: {error}") from None
