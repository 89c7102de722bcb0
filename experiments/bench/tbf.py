"""``python -m experiments.bench tbf [--experiment tbf_table4c|tbf_paper_scale] [--frames N] [overrides]``: the
tree-based filter per frame on the preset's scene, from every camera of its rig (``rig=body_multi``: three), the
observed silhouettes extracted first, outside the timing. For the nodes each frame evaluated, the same scoring
vectorised and naively node by node, their agreement, and the bytes the vectorised scoring read against the
machine's measured memory bandwidth.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import time

import numpy as np

from experiments.bench.common import report_machine
from experiments.components import Components, build, compose
from experiments.loop import frame_threads
from tracker.observe.silhouettes import SilhouetteCapture
from tracker.protocol import Observation
from tracker.sequence import background_frames, simulate
from tracker.tbf.alignment import shifted
from tracker.tbf.costs import window_pixels
from tracker.tbf.scoring import ObservationScorer, RunBoundaries, ShiftedRunBoundaries, SilhouetteRuns
from tracker.tol import ZERO_LENGTH

log = logging.getLogger(__name__)


def bench_tbf(frames: int, experiment: str, overrides: list[str]) -> dict[str, object]:
    """TBF estimation per frame with the composed ``experiment=<experiment>`` config (plus ``overrides``; e.g.
    tbf_table4c: the arm swing, tbf_paper_scale: a held-out CMU clip at the paper's scale): the filter's median,
    stepped through the frames back to back as a run steps it; then, on a second pass over the same frames, for the
    nodes each step evaluated the same scoring done naively, node by node (XOR of the two silhouettes, times the
    weights, summed), with the bytes the vectorised scoring read (the checks, run between the steps, would leave
    the next step's memory cold)."""
    run = build(compose([f"experiment={experiment}", *overrides]))
    tracker, frames = run.tracker, min(frames, run.settings.frames)  # a clip's preset runs it whole
    observed = observations(run, frames)
    start_tracker(run)
    with frame_threads():  # as a run steps it
        estimate_ms = [stepped_ms(tracker, observation) for observation in observed]
    start_tracker(run)  # again: the second pass steps through the same frames with the checks in between
    filter_ = tracker.filter
    top = filter_.tree.levels[0]
    top_runs = [stack.runs.subset(top.representatives) for stack in filter_.samples.silhouettes(top.resolution)]
    per_frame, worst = [], 0.0
    with frame_threads():
        for observation in observed:
            figures, difference = frame_figures(tracker, top_runs, observation)
            per_frame.append(figures)
            worst = max(worst, difference)
    return {
        "samples": len(filter_.samples),
        "nodes": filter_.tree.node_counts,
        "frames": frames,
        "views": len(run.cameras),
        "estimate_ms": statistics.median(estimate_ms),
        "estimate_ms_max": max(estimate_ms),
        **{key: statistics.median(f[key] for f in per_frame) for key in per_frame[0] if key != "stages_ms"},
        "bandwidth_gb_s": _memory_bandwidth_gb_s(),
        "max_relative_difference": worst,
        "first_frame_ms": per_frame[0]["stages_ms"],
    }


def start_tracker(run: Components) -> None:
    """(Re)start the run's tracker at frame 0."""
    run.tracker.start(run.model, run.cameras, run.scene.params(run.model, 0), np.random.default_rng(0))


def stepped_ms(tracker, observation: Observation) -> float:
    """Milliseconds of the tracker's whole step on ``observation`` (placing the silhouettes, then the filter)."""
    start = time.perf_counter()
    tracker.step(observation)
    return 1e3 * (time.perf_counter() - start)


def observations(run: Components, frames: int) -> list[Observation]:
    """The preset's first ``frames`` frames as the tracker observes them, silhouettes extracted (not timed)."""
    rig, render = run.cameras, run.settings.render
    nuisance, rng = render.nuisance(), np.random.default_rng(1)
    with render.renderer(rig[0].width, rig[0].height) as renderer:
        capture = SilhouetteCapture.learn(background_frames(rig, renderer, 20, nuisance, rng))
        return [
            frame.observation(capture.step({c.name: frame.views[c.name].rgb for c in rig}).silhouettes)
            for frame in simulate(run.model, run.scene, rig, renderer, frames, nuisance, rng)
        ]


def frame_figures(tracker, top_runs: list[SilhouetteRuns], observation: Observation) -> tuple[dict, float]:
    """One frame: the tracker's step, then the same scoring again, vectorised and naive, on the nodes it evaluated
    and on all of level 1 (seconds, bytes); and the largest relative difference between the two."""
    filter_ = tracker.filter
    result = tracker.step(observation)
    silhouettes = tracker.last_observation  # what the filter saw, per view
    totals, worst = np.zeros(4), 0.0  # weights, vectorised, naive (seconds), bytes
    for k, nodes in enumerate(filter_.last_evaluated):
        figures, difference = _compare_scoring(filter_, k, silhouettes, nodes)
        totals, worst = totals + figures, max(worst, difference)
    level1, difference = _compare_scoring(filter_, 0, silhouettes, np.arange(len(filter_.tree.levels[0])))
    runs_s, boundaries_s = _level1_ways(filter_, top_runs, silhouettes)
    return {
        "stages_ms": result.timings_ms,
        "nodes_evaluated": sum(len(nodes) for nodes in filter_.last_evaluated),
        "weights_ms": 1e3 * totals[0],
        "scoring_vectorised_ms": 1e3 * totals[1],
        "scoring_naive_ms": 1e3 * totals[2],
        "frame_bytes": totals[3],
        "level1_vectorised_ms": 1e3 * level1[1],
        "level1_naive_ms": 1e3 * level1[2],
        "level1_bytes": level1[3],
        "level1_runs_ms": 1e3 * runs_s,
        "level1_boundaries_ms": 1e3 * boundaries_s,
    }, max(worst, difference)


def _level1_ways(filter_, top_runs: list[SilhouetteRuns], silhouettes: tuple[np.ndarray, ...]) -> np.ndarray:
    """Seconds to score every level-1 node in every view from its runs (``top_runs``, per view), and from the
    filter's run boundaries, with the same scorers; they must agree to rounding."""
    seconds = np.zeros(2)
    for view, silhouette in enumerate(silhouettes):
        stack = filter_.samples.sets[view].silhouettes(filter_.tree.levels[0].resolution)
        scorer = ObservationScorer(filter_.cost, filter_.observation_at(0, silhouette), stack.window)
        scores = []
        for way, runs in enumerate((top_runs[view], filter_.top_boundaries[view])):
            start = time.perf_counter()
            if filter_.spot_pixels is None:
                scores.append(scorer.scores_of_runs(runs))
            elif way == 0:  # each node moved from its spot to the reference's, run by run
                shifts = filter_.shifts(0, view, filter_.tree.levels[0].representatives, filter_.reference)
                scores.append(scorer.scores_of_shifted(runs, np.arange(len(runs)), shifts))
            else:
                scores.append(filter_.scores_from(scorer, 0, view))
            seconds[way] += time.perf_counter() - start
        np.testing.assert_allclose(scores[1], scores[0], rtol=1e-9, atol=1e-12)
    return seconds


def _compare_scoring(
    filter_, level: int, silhouettes: tuple[np.ndarray, ...], nodes: np.ndarray
) -> tuple[np.ndarray, float]:
    """Scores ``nodes`` of ``level`` against each view's silhouette as the filter does (from the representatives'
    runs) and naively (per node: XOR of the two masks, times the weights, summed), after computing the
    observation's weight map once for both. Returns (weight-map s, vectorised s, naive s, bytes the vectorised
    scoring read), summed over the views, and the largest relative difference of the two."""
    figures, worst = np.zeros(4), 0.0
    for view, silhouette in enumerate(silhouettes):
        view_figures, difference = _compare_view_scoring(filter_, level, view, silhouette, nodes)
        figures, worst = figures + view_figures, max(worst, difference)
    return figures, worst


def _compare_view_scoring(
    filter_, level: int, view: int, silhouette: np.ndarray, nodes: np.ndarray
) -> tuple[np.ndarray, float]:
    """`_compare_scoring` for one view."""
    tree_level = filter_.tree.levels[level]
    stack = filter_.samples.sets[view].silhouettes(tree_level.resolution)
    observed = filter_.observation_at(level, silhouette)
    start = time.perf_counter()
    scorer = ObservationScorer(filter_.cost, observed, stack.window)
    weights_s = time.perf_counter() - start
    start = time.perf_counter()
    scores = filter_.scores_from(scorer, level, view, None if len(nodes) == len(tree_level) else nodes)
    vectorised_s = time.perf_counter() - start
    read = (
        _bytes_read(filter_.top_boundaries[view], nodes)
        if level == 0
        else _bytes_read(stack.runs, tree_level.representatives[nodes])
    ) + 8 * (window_pixels(stack.window) + 1)  # and the weights' prefix sums
    u0, v0, u1, v1 = stack.window
    weights, inside = scorer.weights, observed[v0:v1, u0:u1]
    representatives = tree_level.representatives[nodes]
    models = [stack.mask(rep) for rep in representatives]  # as bool masks before the clock
    if filter_.spot_pixels is not None:  # each moved from its spot to the reference's, as the filter scores it
        shifts = filter_.shifts(level, view, representatives, filter_.reference)
        models = [shifted(model, du, dv) for model, (du, dv) in zip(models, shifts, strict=True)]
    start = time.perf_counter()
    naive = np.array([(weights * (inside ^ model)).sum() / inside.size for model in models])
    naive_s = time.perf_counter() - start
    difference = float(np.max(np.abs(naive - scores) / np.maximum(np.abs(scores), ZERO_LENGTH))) if len(nodes) else 0.0
    return np.array([weights_s, vectorised_s, naive_s, read]), difference


def _bytes_read(runs: SilhouetteRuns | RunBoundaries | ShiftedRunBoundaries, rows: np.ndarray) -> int:
    """The bytes of ``rows``' runs that scoring reads: each run's start and end and the two int64 indices that
    gather them (the run's and its row's), or its two boundaries' columns and signs."""
    if isinstance(runs, RunBoundaries | ShiftedRunBoundaries):
        matrix = runs.matrix
        return int((matrix.indptr[rows + 1] - matrix.indptr[rows]).sum()) * (
            matrix.indices.itemsize + matrix.data.itemsize
        )
    return int((runs.ptr[rows + 1] - runs.ptr[rows]).sum()) * (
        runs.starts.itemsize + runs.ends.itemsize + 2 * np.dtype(np.int64).itemsize
    )


def _memory_bandwidth_gb_s() -> float:
    """Read+write bandwidth of one large copy (256 MB), best of 5, as a yardstick for bytes read per frame."""
    source = np.ones(32 * 2**20)  # 256 MB
    target = np.empty_like(source)
    best = min(_timed(lambda: np.copyto(target, source)) for _ in range(5))
    return 2 * source.nbytes / best / 1e9


def _timed(function) -> float:
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def run(args: argparse.Namespace) -> dict:
    """Bench the filter, log what it measured and return it."""
    figures = bench_tbf(args.frames, args.experiment, args.overrides)
    log.info(
        "TBF, experiment=%s %s: %d samples, tree %s nodes per level, %d view(s)",
        args.experiment,
        " ".join(args.overrides),
        figures["samples"],
        figures["nodes"],
        figures["views"],
    )
    log.info(
        "  estimation %.2f ms/frame median (max %.1f) over %d frames",
        figures["estimate_ms"],
        figures["estimate_ms_max"],
        figures["frames"],
    )
    _report_scoring(figures)
    report_machine()
    return figures


def _report_scoring(figures: dict) -> None:
    log.info(
        "  per frame, the observation's weight maps %.2f ms (shared), then scoring the %.0f nodes it "
        "evaluated: from runs %.3f ms, naive per-node loop %.2f ms: %.1fx",
        figures["weights_ms"],
        figures["nodes_evaluated"],
        figures["scoring_vectorised_ms"],
        figures["scoring_naive_ms"],
        figures["scoring_naive_ms"] / figures["scoring_vectorised_ms"],
    )
    log.info(
        "  scoring all %d level-1 nodes: from runs %.3f ms, naive per-node loop %.2f ms: %.1fx (%.2f MB read)",
        figures["nodes"][0],
        figures["level1_vectorised_ms"],
        figures["level1_naive_ms"],
        figures["level1_naive_ms"] / figures["level1_vectorised_ms"],
        figures["level1_bytes"] / 1e6,
    )
    log.info(
        "  all of level 1, every view: from its runs %.3f ms, from its run boundaries (as the filter scores "
        "it) %.3f ms: %.1fx",
        figures["level1_runs_ms"],
        figures["level1_boundaries_ms"],
        figures["level1_runs_ms"] / figures["level1_boundaries_ms"],
    )
    log.info(
        "  naive and vectorised scores agree to %.1e (relative); frame 0 stages (ms): %s",
        figures["max_relative_difference"],
        ", ".join(f"{k} {v:.1f}" for k, v in figures["first_frame_ms"].items()),
    )
    log.info(
        "  bytes read by the vectorised scoring: %.2f MB/frame = %.3f ms at the measured %.1f GB/s",
        figures["frame_bytes"] / 1e6,
        1e3 * figures["frame_bytes"] / (figures["bandwidth_gb_s"] * 1e9),
        figures["bandwidth_gb_s"],
    )
