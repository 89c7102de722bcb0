"""Benchmarks, apart from the tests: ``python -m experiments.bench <target> [options]``, each target a module of this
package that says what it measures:

``render`` the off-screen renderer's passes; ``abis`` AbIS per frame, lm against sd; ``silhouettes`` sample-set
build, silhouette capture and the costs' scoring; ``samples`` label rendering and the paper-scale set built cold;
``tbf`` the tree-based filter per frame, vectorised scoring against naive; ``scale`` tree filtering's time, memory
and disk against its dictionary's size. ``python -m experiments.bench.sweeps``
times and resumes sweeps on each launcher. With ``--json`` each prints, as its last line, one JSON object of what
it measured (``{"target", "machine", "figures"}``) for scripts and CI to read.
"""

from __future__ import annotations

import argparse
import importlib
import logging

from experiments.bench.common import json_line
from experiments.cli_runs import exit_interrupted

TARGETS = ("render", "abis", "silhouettes", "samples", "tbf", "scale")


def _ints(text: str) -> list[int]:
    return [int(value) for value in text.split(",")]


def _names(text: str) -> list[str]:
    return text.split(",")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", choices=TARGETS)
    parser.add_argument("--poses", type=int, default=300, help="samples: poses rendered both ways")
    parser.add_argument("--build", action="store_true", help="samples: also build the whole set and tree cold")
    parser.add_argument("--ray", action="store_true", help="samples: also build on Ray, 1 and 2 workers (make ray)")
    parser.add_argument("--ray-address", default=None, help="samples --ray: a Ray cluster's address (else local)")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--samples", type=int, default=10_000, help="pose samples (silhouettes)")
    parser.add_argument("--experiment", default="tbf_table4c", help="tbf: the experiment preset")
    parser.add_argument("--turns", type=_ints, help="scale: turns per dictionary (1,2,...; the reproduce step's)")
    parser.add_argument("--experiments", type=_names, help="scale: presets (a,b; the reproduce step's)")
    parser.add_argument("--cell", action="store_true", help=argparse.SUPPRESS)  # scale: one measuring process
    parser.add_argument("overrides", nargs="*", help="samples, tbf, scale: config overrides on top of the experiment")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT of every view (render, abis)")
    parser.add_argument("--json", action="store_true", help="end with one JSON line of the figures")
    args = parser.parse_intermixed_args()  # overrides may come after options
    args.width, args.height = (int(v) for v in args.size.lower().split("x"))
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        figures = importlib.import_module(f"experiments.bench.{args.target}").run(args)
    except KeyboardInterrupt as interrupt:  # a measuring process under way was stopped and waited for
        exit_interrupted(interrupt)
    if args.json:
        print(json_line(args.target, figures), flush=True)


if __name__ == "__main__":
    main()
