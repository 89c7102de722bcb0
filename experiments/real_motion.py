"""``make reproduce SCALE=paper``'s real motion: paper 2's experiment B at its scale (``experiment=tbf_paper_scale``)
on every held-out clip, whole, with one row per part of the build taken away (the ablation), into
``reports/tbf_real/<clip>/<variant>/``; the table ``reports/tbf_real.md`` / ``.csv`` and, per clip, Fig 5's strip
and the error against the dictionary's floor per frame (`eval.real_motion`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from eval.body_figures import error_against_floor, fig5_strip
from eval.real_motion import real_motion_table
from eval.runs import collect, markdown
from eval.tables import write_table_6d
from experiments.cli_runs import LIGHT_RECORDING, run_experiment, write_text
from experiments.experiment_a import CONTROL, EXPERIMENT
from experiments.steps import Section, Step
from tracker.motion.mocap import available_frames, read_clip

# The project's own held-out clips: never among the preset's tracker.samples.clips.
HELD_OUT = ("mocap/143_33.bvh", "mocap/69_20.bvh")
FPS = 15.0  # the preset's scene.fps and tracker.samples.clip_fps
# The preset's tree filtering before the chain of likely samples (the filter's motion model, shares of its prior
# on the depth flips and on every sample, the posterior's mean).
FILTERED = (
    "tracker.chain.candidates=0",
    "tracker.filter.jump_share=0.05",
    "tracker.filter.flip_share=0.05",
    "tracker.filter.prune_fraction=0.01",
)
# Folder -> (what the row says, the overrides that take that part of the build away).
VARIANTS = {
    "full": ("the whole build", ()),
    "narrow_dictionary": (
        "samples from 2 short CMU clips (12 s) at 30 fps, turned every 30° and jittered, as before",
        (
            "tracker.samples.clips=[mocap/143_23.bvh,mocap/79_92.bvh]",
            "tracker.samples.clip_fps=30.0",
            "tracker.samples.clip_mirror=false",
            "tracker.samples.clip_turns_deg=[-150,-120,-90,-60,-30,0,30,60,90,120,150,180]",
            "tracker.samples.clip_copies=9",
            "tracker.samples.clip_jitter_deg=8.0",
            "tracker.thresholds=[0.038,0.033,0.026]",
        ),
    ),
    "filtered": ("the filter's motion model and shares of its prior instead of the chain of likely samples", FILTERED),
    "dm2": ("that filter with DM2's random walk instead of the learned transitions", (*FILTERED, "motion=dm2")),
    "no_placement": (
        "no root placement (the silhouette as it is)",
        ("tracker.align=none", "tracker.placed_on=reference"),
    ),
    "base_body": ("MakeHuman's base mesh instead of the nearest standard body", ("tracker.body=base",)),
}


def real_motion_step(reports: Path) -> Section:
    """Every held-out clip with every variant, one run after another (a paper-scale run takes much of the machine's
    memory); the table, Fig 5 per clip, and the whole-build runs joined to Fig 6(d)."""
    root = reports / "tbf_real"
    shutil.rmtree(root, ignore_errors=True)
    figures = []
    for path in HELD_OUT:
        clip = Path(path).stem
        frames = available_frames(read_clip(path), 0.0, FPS)
        for folder, (label, overrides) in VARIANTS.items():
            print(f"paper 2, real motion: {clip} ({frames} frames), {label} ...", flush=True)
            light = () if folder == "full" else LIGHT_RECORDING
            run_experiment(
                "tbf_paper_scale", root / clip / folder, f"scene.path={path}", f"frames={frames}", *overrides, *light
            )
        full = root / clip / "full"
        figures += [
            fig5_strip(full, reports / f"fig5_{clip}.png"),
            error_against_floor(full, reports / f"fig5_{clip}_error.png", clip),
        ]
    full_runs = [root / Path(clip).stem / "full" for clip in HELD_OUT]
    write_table_6d(collect([reports / EXPERIMENT, reports / CONTROL, *full_runs]), reports)
    table = real_motion_table(root, {folder: label for folder, (label, _) in VARIANTS.items()})
    write_text(reports / "tbf_real.csv", table.to_csv(index=False))
    text = markdown(table)
    write_text(reports / "tbf_real.md", text + "\n")
    console = "\nPaper 2 on real held-out motion:\n" + text + "\n" + "\n".join(f"  {f}" for f in figures)
    section = (
        "### Real motion the samples never held (experiment B at the paper's scale)\n\n"
        "`experiment=tbf_paper_scale`: the samples from 23 real CMU clips, mirrored and turned every 90°, tracking "
        "each held-out clip whole at 15 fps from one camera. The floor is the 3-D nearest sample per frame "
        "(root-aligned): no filter over these samples can do better. A frame is ambiguous when the silhouette cost "
        "itself prefers the estimate's sample to the floor's. Each row below the whole build takes one part of it "
        "away. The whole-build runs join Fig 6(d) (`table6d.md`).\n\n"
        + text
        + "\n\n"
        + "".join(f"![{figure.stem}]({figure.name})\n\n" for figure in figures)
    )
    return Section(console, section)


STEP = Step(
    "Paper 2 at its scale (SCALE=paper): experiment B on the held-out real clips, with an ablation row per part",
    ("tbf_paper_scale",),
    ("tbf_real.md", "fig5_<clip>.png", "table6d.md"),
    real_motion_step,
    scale="paper",
)
