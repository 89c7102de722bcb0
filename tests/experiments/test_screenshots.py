"""The recording in Rerun's own viewer (headless, software Vulkan): every view drawn without complaint, the subject
whole inside the 3-D view at the first and the last frame, a picture saved as the docs' are, and each recording
opened after another shows its own layout."""

import io

import numpy as np
import pytest
from PIL import Image

from experiments.presentation import run_blueprint, views_of
from experiments.screenshots import headless_viewer, save_png, settled_picture, show
from tests.conftest import components_of

SATURATION, VALUE = 0.25, 0.3  # the models' colours and the estimate's yellow; the grid and background are grey


@pytest.fixture(scope="module")
def viewer():
    client = headless_viewer()
    yield client
    client.quit()


def subject_box(picture: bytes) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """The rows and columns of the picture's coloured pixels (min, max each), and its size (height, width)."""
    hsv = np.asarray(Image.open(io.BytesIO(picture)).convert("RGB").convert("HSV"), dtype=float) / 255
    coloured = (hsv[..., 1] > SATURATION) & (hsv[..., 2] > VALUE)
    rows, columns = np.nonzero(coloured)
    assert rows.size, "no coloured pixel in the 3-D view"
    return np.array([rows.min(), rows.max()]), np.array([columns.min(), columns.max()]), coloured.shape


def test_the_viewer_draws_the_subject_whole_in_the_3d_view(viewer, abis_run, tmp_path):
    last = 9  # abis_run has 10 frames
    for frame in (0, last):
        show(viewer, abis_run / "run.rrd", frame)  # raises if a view could not be drawn
        (view,) = [view for view in viewer.get_state().views if view.view_class == "3D"]
        rows, columns, (height, width) = subject_box(settled_picture(viewer, view.view_id))
        assert rows.min() > 2 and rows.max() < height - 3, f"frame {frame}: the subject touches the top or bottom"
        assert columns.min() > 2 and columns.max() < width - 3, f"frame {frame}: the subject touches a side"
        assert np.ptp(rows) > 0.1 * height, f"frame {frame}: the subject is a speck ({np.ptp(rows)} of {height} px)"
    saved = Image.open(save_png(settled_picture(viewer), tmp_path / "shot.png", width=640))
    viewer.close("all")
    assert saved.size[0] == 640 and saved.mode == "P"


def test_each_recording_opened_after_another_shows_its_own_layout(viewer, abis_run, body_swing_run):
    for run in (abis_run, body_swing_run, abis_run):
        show(viewer, run / "run.rrd", 0)
        components = components_of(run)
        layout = run_blueprint(components, components.settings.record)
        expected = [str(view.name) for view in views_of(layout.root_container)]
        shown = sorted(view.name for view in viewer.get_state().views)
        assert shown == sorted(expected), run
        viewer.close("all")
