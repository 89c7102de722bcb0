"""``make reproduce SCALE=paper``'s comparison of the plug-board's combinations (a model with another paper's tracker,
a tracker on more views), into ``reports/combinations/`` and ``reports/combinations.md`` / ``.csv``
(`eval.combinations`):

- the held-out real clips (`experiments.real_motion.HELD_OUT`, whole, at 15 fps) tracked by tree filtering on the
  paper-scale samples from 1, 2 and 3 cameras (``experiment=tbf_multi_view``, its ``rig=body_multi`` cut to its
  first views: front; front and side; front, side and the 45° view), and from one camera by the one-camera preset
  (``experiment=tbf_paper_scale``: its chain of likely samples; the multi-view settings' jumps let one ambiguous view
  jump to a wrong pose); and
  by paper 1's AbIS from 3 cameras at 640x480 (``experiment=abis_body``: features on a textured skin, the body's
  parts fitted top-down), at 15 fps and at 60 fps (the same clip, its limbs moving a quarter as far per frame);
- paper 1's arm in its elbow swing (``experiment=abis_fig8_fig9``, 3 orthogonal views) by AbIS and by tree
  filtering over a grid of its parameters (``tracker=tbf cost=nwxor motion=dm2``).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from omegaconf import OmegaConf

from eval.combinations import arm_table, body_table
from eval.runs import markdown
from experiments.cli_runs import LIGHT_RECORDING, run_experiment, write_text
from experiments.real_motion import FPS, HELD_OUT
from experiments.schemas import CONFIG_DIR
from experiments.steps import Section, Step
from tracker.motion.mocap import available_frames, read_clip

CAMERA_COUNTS = (1, 2, 3)  # the first views of rig=body_multi
ABIS_DENSE_FPS = 60.0
ARM_TRACKERS = {
    "AbIS (Levenberg-Marquardt), 3 views": (),
    "tree filtering (nwXOR, DM2), 3 views": ("tracker=tbf", "cost=nwxor", "motion=dm2"),
}


def first_views(count: int) -> str:
    """The override that cuts rig=body_multi to its first ``count`` cameras."""
    views = OmegaConf.load(CONFIG_DIR / "rig" / "body_multi.yaml")["views"][:count]
    return (
        "rig.views=[" + ",".join(f"{{name:{v.name},position:[{','.join(map(str, v.position))}]}}" for v in views) + "]"
    )


@dataclass(frozen=True)
class BodyRow:
    """A row of the held-out clips: what it says, the experiment, its overrides and the frame rate it tracks at."""

    label: str
    experiment: str
    overrides: tuple[str, ...] = ()
    fps: float = FPS


def body_runs() -> dict[str, BodyRow]:
    """Folder -> its row, for every row of the held-out clips."""
    rows = {"tbf_paper_1_view": BodyRow("tree filtering, 1 camera (experiment=tbf_paper_scale)", "tbf_paper_scale")}
    for count in CAMERA_COUNTS:
        rows[f"tbf_{count}_views"] = BodyRow(
            f"tree filtering, {count} camera{'s' * (count > 1)} (experiment=tbf_multi_view)",
            "tbf_multi_view",
            (first_views(count),),
        )
    rows["abis_3_views"] = BodyRow("AbIS, 3 cameras at 640x480 (experiment=abis_body)", "abis_body")
    # The same clip 4 times as densely sampled in time: how much of AbIS's error is the limbs' motion per frame.
    rows[f"abis_3_views_{ABIS_DENSE_FPS:.0f}fps"] = BodyRow(
        f"AbIS, 3 cameras, at {ABIS_DENSE_FPS:.0f} fps", "abis_body", (f"scene.fps={ABIS_DENSE_FPS}",), ABIS_DENSE_FPS
    )
    return rows


def combinations_step(reports: Path) -> Section:
    """Run every row, one after another (paper-scale runs from three views take much of the machine's memory)."""
    root = reports / "combinations"
    shutil.rmtree(root, ignore_errors=True)
    body_rows = body_runs()
    for path in HELD_OUT:
        clip = Path(path).stem
        for folder, row in body_rows.items():
            frames = available_frames(read_clip(path), 0.0, row.fps)
            print(f"combinations: {clip} ({frames} frames), {row.label} ...", flush=True)
            run_experiment(
                row.experiment,
                root / clip / folder,
                f"scene.path={path}",
                f"frames={frames}",
                *row.overrides,
                *LIGHT_RECORDING,
            )
    arm_runs = {}
    for label, overrides in ARM_TRACKERS.items():
        print(f"combinations: paper 1's arm by {label} ...", flush=True)
        folder = root / "arm" / ("tbf" if overrides else "abis")
        arm_runs[label] = run_experiment("abis_fig8_fig9", folder, *overrides, *LIGHT_RECORDING)
    body, arm = body_table(root, {folder: row.label for folder, row in body_rows.items()}), arm_table(arm_runs)
    write_text(reports / "combinations.csv", body.to_csv(index=False))
    text = markdown(body) + "\n\n" + markdown(arm)
    write_text(reports / "combinations.md", text + "\n")
    console = f"\nAny model with any tracker:\n{text}\n"
    section = (
        "### Any model with any tracker: several views for tree filtering, the body by AbIS, the arm by tree "
        "filtering\n\n"
        "The held-out real clips tracked by tree filtering on the paper-scale samples (`experiment=tbf_multi_view`) "
        "from the first 1, 2 and 3 cameras of `rig=body_multi` (front; side; 45° between), the likelihood the "
        "product of the views', and by paper 1's AbIS from the same three views at 640x480 (`experiment=abis_body`: "
        "KLT features on a textured skin, the parts' joints fitted top-down; it starts at the truth, as paper 1 "
        "does, and has no floor: it searches no dictionary), at 15 fps and at 60 fps; and paper 1's arm in its "
        "elbow swing by AbIS and by tree filtering over a grid of its parameters (the floor: the grid's sample "
        "nearest the truth).\n\n" + text + "\n\n"
    )
    return Section(console, section)


STEP = Step(
    "Any model with any tracker (SCALE=paper): the held-out clips by tree filtering from 1-3 cameras and by AbIS, "
    "the arm by both",
    ("tbf_paper_scale", "tbf_multi_view", "abis_body", "abis_fig8_fig9"),
    ("combinations.md",),
    combinations_step,
    scale="paper",
)
