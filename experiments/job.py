"""One run: check the config, build its components, run the frames, write the outputs.

Outputs in the job's directory, each written atomically: ``run.rrd`` (Rerun), ``frames.parquet`` (one row per
frame and part; columns in `experiments.outputs`), ``timings.json`` (per-stage medians, ms) and, last,
``metrics.json`` (choices, seed, frames, status, accuracy where the tracker estimates). Timings are kept out of
``metrics.json`` so that the same seed gives the same bytes; a complete ``metrics.json`` marks a finished job.
A failure inside the loop is recorded as ``status: "failed: <reason>"`` with every output still written.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import pandas as pd
from omegaconf import DictConfig, OmegaConf

from experiments.checks import check_config
from experiments.components import Components, build, import_plugins
from experiments.loop import run_frames
from experiments.outputs import RunLog, summarize, timing_summary
from experiments.recording import RunRecording
from experiments.recording_file import RecordingLost
from experiments.stopping import Interrupted, StopRequest
from tracker.atomic import write_json, write_parquet

log = logging.getLogger(__name__)


def run_job(
    cfg: DictConfig, output_dir: Path, choices: dict[str, str], sweep_stop: Path | None = None
) -> dict[str, Any]:
    """Run the configured scene for ``cfg.frames`` frames into ``output_dir``; return the metrics written. A stop
    (`StopRequest`: a signal, or the file ``sweep_stop`` appearing) ends the run early, its outputs marked
    interrupted; the caller decides whether to end the process (`StopRequest.received`): a sweep's worker must not
    raise, or its launcher kills the other jobs before their outputs are written."""
    import_plugins(cfg.get("plugins", ()))  # a launcher's worker process imports them too
    check_config(cfg, choices)  # an invalid config raises before any output exists
    remove_stale_temporaries(output_dir)
    frames = RunLog()
    components: Components | None = None
    recording: RunRecording | None = None
    status = "ok"
    stop = StopRequest.install(sweep_stop)
    try:
        components = build(cfg)
        recording = RunRecording(output_dir / "run.rrd", components, components.settings.record)
        run_frames(components, recording, stop, frames)
    except Interrupted:  # stopped at once while the tracker started; the outputs below say so
        pass
    except Exception as error:  # recorded, not raised: a sweep goes on and every output stays readable
        log.exception("run failed at frame %d", len(frames.timings))
        status = f"failed: {failure_reason(error)}"
    except BaseException:  # an exit or interrupt raised anyway: the outputs still say the run did not finish
        status = "failed: interrupted"
        raise
    finally:
        if components is not None:
            components.tracker.close()
        stop.restore()
        if stop.requested:
            status = f"failed: interrupted by {stop.requested}"
        if recording is not None:
            try:
                recording.close()
            except RecordingLost as lost:  # the other outputs are still written, and say why it is missing
                log.error("%s", lost)
                status = f"failed: {lost}"
        try:
            metrics = write_outputs(cfg, choices, components, output_dir, frames, status)
        except OSError as error:  # a full disk, or the folder gone: nothing half-written is left (tracker.atomic)
            raise OutputsLost(f"{output_dir}: the run's outputs could not be written: {error}") from None
    return metrics


class OutputsLost(OSError):
    """The run's tables could not be written (e.g. a full disk); its message is the one line the user sees."""


def write_outputs(
    cfg: DictConfig,
    choices: dict[str, str],
    components: Components | None,
    output_dir: Path,
    frames: RunLog,
    status: str,
) -> dict[str, Any]:
    """``frames.parquet``, ``timings.json`` and, last, ``metrics.json``; returns the metrics."""
    table = pd.DataFrame(frames.rows)
    write_parquet(output_dir / "frames.parquet", table)
    write_json(output_dir / "timings.json", timing_summary(frames.timings, components.views if components else []))
    metrics = summarize(cfg, choices, components, table, len(frames.timings), status, frames.tracker_columns)
    write_json(output_dir / "metrics.json", metrics)
    return metrics


def finished_metrics(cfg: DictConfig, output_dir: Path) -> dict[str, Any] | None:
    """The metrics of a finished job of this very config in ``output_dir`` (status ok, same resolved config), or
    None. A killed job never leaves a complete ``metrics.json`` (it is written last, atomically)."""
    try:
        metrics = json.loads((output_dir / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(metrics, dict) or metrics.get("status") != "ok":
        return None
    return metrics if metrics.get("config") == OmegaConf.to_container(cfg, resolve=True) else None


def remove_stale_temporaries(output_dir: Path) -> None:
    """Temporary files a killed job left behind (`tracker.atomic` names them ``.<name>.<random>.tmp``)."""
    for path in output_dir.glob(".*.tmp"):
        path.unlink(missing_ok=True)


def failure_reason(error: BaseException) -> str:
    """``Type: message`` on one line."""
    message = str(error).strip().splitlines()
    return f"{type(error).__name__}: {message[0]}" if message else type(error).__name__
