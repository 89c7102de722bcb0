"""The Hydra entry point: ``python -m experiments.run [group=option ...] [key=value ...] [-m]``.

Before Hydra creates any output directory, the command line is composed with Hydra's Compose API and checked
(every value of a sweep included): a bad override exits with status 2 and one line on stderr naming the key, the
value and what is allowed, and leaves no files behind. Then `hydra.main` runs the job(s): a sweep (``-m``) runs on
the joblib launcher (one job per core) unless ``hydra/launcher=...`` says otherwise; re-running a sweep into the
same ``hydra.sweep.dir`` keeps every job already finished with the same config and redoes the rest.
``plugins=[my.module,...]`` imports modules that register components of their own (`tracker.registry`) first; their
option files join with ``hydra.searchpath=[file://<folder>]``.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from experiments.checks import ConfigError
from experiments.cli_runs import exit_interrupted
from experiments.components import import_plugins
from experiments.schemas import CONFIG_DIR, CONFIG_NAME
from experiments.stopping import Interrupted, StopRequest, SweepStop
from experiments.validate import plugins_named, validate_command_line

log = logging.getLogger(__name__)


@hydra.main(version_base="1.3", config_path=str(CONFIG_DIR), config_name=CONFIG_NAME)
def hydra_main(cfg: DictConfig) -> dict:
    # The run's machinery (rendering, recording, tables: a second of imports) only once the command line is checked:
    # a bad override is reported without it.
    from experiments.job import OutputsLost, finished_metrics, run_job

    hydra_cfg = HydraConfig.get()
    choices = {k: v for k, v in hydra_cfg.runtime.choices.items() if not k.startswith("hydra") and v is not None}
    output_dir = Path(hydra_cfg.runtime.output_dir)
    if hydra_cfg.mode == RunMode.MULTIRUN:
        if (metrics := finished_metrics(cfg, output_dir)) is not None:
            log.info("run finished earlier, kept: %s", output_dir)  # resuming a sweep redoes only the rest
            return metrics
        if SweepStop.stopping():
            log.info("not started, the sweep is stopping: %s", output_dir)
            return {"status": "not started: the sweep was stopped"}
    sweep_stop = SweepStop.file() if hydra_cfg.mode == RunMode.MULTIRUN else None
    try:
        metrics = run_job(cfg, output_dir, choices, sweep_stop)
    except OutputsLost as lost:
        log.error("%s", lost)
        if hydra_cfg.mode == RunMode.RUN:
            sys.exit(1)
        return {"status": f"failed: {lost}"}  # a sweep goes on to its next job
    if StopRequest.received and hydra_cfg.mode == RunMode.RUN:  # the outputs are written; stop as the signal asked
        raise Interrupted(StopRequest.received)
    log.info("run %s: %s", metrics["status"], output_dir)
    if metrics["status"] != "ok" and hydra_cfg.mode == RunMode.RUN:
        sys.exit(1)  # a single run reports failure by its exit code; a sweep goes on to its next job
    return metrics


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    logging.raiseExceptions = False  # a log line that cannot be written (a full disk) is dropped, not a traceback
    try:
        try:
            import_plugins(plugins_named(argv))  # their components and schemas, before anything is composed
            validate_command_line(argv, CONFIG_DIR, CONFIG_NAME)
        except ConfigError as error:
            print(f"error: {error}", file=sys.stderr)
            sys.exit(2)
        if {"-m", "--multirun"} & set(argv):
            SweepStop.install()
            # joblib's resource tracker (a process of its own) warns of the semaphores of workers a stop ended
            os.environ.setdefault("PYTHONWARNINGS", "ignore:resource_tracker:UserWarning")
        hydra_main()
        if StopRequest.received:  # a sweep whose running jobs stopped and wrote their outputs
            raise Interrupted(StopRequest.received)
    except KeyboardInterrupt as interrupt:  # the run's outputs are written and say so (experiments.job)
        exit_interrupted(interrupt)
    finally:
        SweepStop.remove_file()


if __name__ == "__main__":
    main()
