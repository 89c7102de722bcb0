"""``python -m experiments.screenshots``: what a run's recording looks like, as pictures in ``docs/screenshots/``.

Each of `LAYOUTS` is a short real run through the command line (its recording in a temporary folder), sent to
Rerun's own viewer as a user sends one from a terminal (``rerun --port <port> run.rrd``), the viewer running
headless (``ViewerClient.spawn(headless=True)``: no window; Mesa's software Vulkan, lavapipe, draws it), the time
cursor paused at the run's last frame, and the whole window saved once two pictures in a row agree (the viewer has
drawn everything it loaded). A view the viewer could not draw is reported by name, and fails the script. One viewer
shows every layout in turn, as a user's does: each recording must bring its own.
"""

from __future__ import annotations

import argparse
import io
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from PIL import Image
from rerun.experimental import ViewerClient

from experiments.cli_runs import run_experiment
from tracker.atomic import atomic_path

OUT = Path("docs/screenshots")
WIDTH_PX = 1440  # the saved picture's width (the headless window is 1920 x 1080); 256 colours keep it small
SETTLE_S = 1.0  # between two pictures of the viewer that must agree
SETTLE_TRIES = 60
TIMELINE = "frame"


@dataclass(frozen=True)
class Layout:
    """A run whose default layout is pictured: ``experiment=<experiment>`` with ``overrides`` for ``frames``."""

    name: str
    experiment: str
    frames: int
    overrides: tuple[str, ...] = ()
    says: str = ""


# One small dictionary (one clip, no turns or mirror) keeps the dictionary trackers' pictures minutes away, not hours.
ONE_CLIP_DICTIONARY = (
    "tracker.samples.clips=[mocap_daz/martial_04.bvh]",
    "tracker.samples.clip_mirror=false",
    "tracker.samples.clip_turns_deg=[0.0]",
)
LAYOUTS = (
    Layout("abis_arm", "abis_fig8_fig9", 60, (), "Paper 1: the arm by AbIS from 3 orthogonal cameras"),
    Layout("abis_body", "abis_body", 12, (), "AbIS on the body, 3 cameras at 640x480"),
    Layout("tbf_experiment_a", "tbf_table4c", 60, (), "Paper 2, experiment A: tree filtering from 1 camera"),
    Layout(
        "hybrid_3_cameras",
        "hybrid_multi_view",
        12,
        ("scene.path=mocap/69_20.bvh", *ONE_CLIP_DICTIONARY),
        "The hybrid on a real clip from 3 cameras (a dictionary of one clip)",
    ),
)


class ViewerTrouble(RuntimeError):
    """The viewer could not draw a view of a recording, or never settled."""


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


RERUN = Path(sys.executable).with_name("rerun")  # the viewer of this environment


def headless_viewer() -> ViewerClient:
    """Rerun's viewer, without a window, on a free port."""
    return ViewerClient.spawn(headless=True, port=free_port(), hide_welcome_screen=True, executable_path=str(RERUN))


def settled_picture(viewer: ViewerClient, view_id: str | None = None) -> bytes:
    """A PNG of the viewer (or one view of it) once two pictures `SETTLE_S` apart agree."""
    previous = None
    for _ in range(SETTLE_TRIES):
        time.sleep(SETTLE_S)
        picture = viewer.take_screenshot(view_id)
        if picture == previous:
            return picture
        previous = picture
    raise ViewerTrouble(f"the viewer kept changing for {SETTLE_TRIES * SETTLE_S:.0f} s")


def show(viewer: ViewerClient, recording: Path, frame: int) -> bytes:
    """``recording`` loaded in ``viewer`` and paused at ``frame``: the viewer's settled picture (`settled_picture`),
    once it has drawn every view of the recording's layout without complaint."""
    port = viewer.url.rsplit(":", 1)[1].split("/", 1)[0]
    subprocess.run([str(RERUN), "--port", port, str(recording)], check=True, capture_output=True, timeout=60)
    for _ in range(SETTLE_TRIES):
        if not viewer.get_state().loading:
            break
        time.sleep(SETTLE_S)
    viewer.set_time(TIMELINE, sequence=frame, play_state="paused")
    picture = settled_picture(viewer)
    troubles = [f"{view.name}: {view.reports}" for view in viewer.get_state().views if view.reports]
    if troubles:
        raise ViewerTrouble(f"{recording}: views the viewer could not draw: {'; '.join(troubles)}")
    return picture


def save_png(picture: bytes, path: Path, width: int = WIDTH_PX) -> Path:
    """``picture`` scaled to ``width`` and reduced to 256 colours, into ``path`` atomically."""
    image = Image.open(io.BytesIO(picture)).convert("RGB")
    image = image.resize((width, round(image.height * width / image.width)), Image.Resampling.LANCZOS)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temporary:
        image.quantize(256, method=Image.Quantize.MEDIANCUT).save(temporary, format="PNG", optimize=True)
    return path


def picture_layout(viewer: ViewerClient, layout: Layout, runs: Path, out: Path, width: int) -> Path:
    run_dir = run_experiment(layout.experiment, runs / layout.name, f"frames={layout.frames}", *layout.overrides)
    picture = show(viewer, run_dir / "run.rrd", layout.frames - 1)
    viewer.close("all")
    return save_png(picture, out / f"{layout.name}.png", width)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help="the folder of the pictures")
    parser.add_argument("--width", type=int, default=WIDTH_PX, help="the pictures' width in pixels")
    parser.add_argument("layouts", nargs="*", help=f"some of {', '.join(layout.name for layout in LAYOUTS)} (all)")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.layouts) - {layout.name for layout in LAYOUTS})
    if unknown:
        parser.error(f"layouts: {', '.join(unknown)} not among {', '.join(layout.name for layout in LAYOUTS)}")
    chosen = [layout for layout in LAYOUTS if not args.layouts or layout.name in args.layouts]
    viewer = headless_viewer()
    try:
        with tempfile.TemporaryDirectory(prefix="screenshots_") as runs:
            for layout in chosen:
                print(f"{layout.name}: {layout.says}", flush=True)
                print(f"  wrote {picture_layout(viewer, layout, Path(runs), args.out, args.width)}", flush=True)
    finally:
        viewer.quit()


if __name__ == "__main__":
    main()
