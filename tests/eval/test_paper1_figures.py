import matplotlib.image
import numpy as np
import pandas as pd

from eval.arm_figures import _estimates, fig6_fig7_sheets, fig8_part2_b1_r2, fig9_part2_correspondences
from eval.figures import write_figures
from tracker.models.dsq import PARAM_NAMES


def test_fig8_and_fig9_are_written_from_an_abis_run(abis_run, tmp_path):
    fig8 = fig8_part2_b1_r2(abis_run, out=tmp_path / "fig8.png")
    fig9 = fig9_part2_correspondences(abis_run, out=tmp_path / "fig9.png")
    for figure in (fig8, fig9):
        image = matplotlib.image.imread(figure)
        assert image.shape[0] > 200 and image.shape[1] > 400 and image.std() > 0.05  # drawn, not blank
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig8.png", "fig9.png"]


def test_write_figures_knows_what_a_run_supports(abis_run, five_frame_run):
    assert [p.name for p in write_figures(abis_run)] == [
        "views.png",
        "fig6_input_views.png",
        "fig7_estimated_views.png",
        "fig8_part2_b1_r2.png",
        "fig9_part2_correspondences.png",
    ]
    assert [p.name for p in write_figures(five_frame_run)] == ["views.png"]  # render_only: no estimates


def test_fig7_renders_the_estimate_where_fig6_shows_the_input(abis_run, arm, rig, renderer):
    # The estimate of a short run sits on the truth: its render covers the same pixels as the input's.
    estimates = _estimates(abis_run, arm)
    table = pd.read_parquet(abis_run / "frames.parquet")
    frame = max(estimates)
    truth = np.stack(
        [
            table[(table["frame"] == frame) & (table["part"] == part)][
                [f"truth_{name}" for name in PARAM_NAMES]
            ].to_numpy()[0]
            for part in arm.part_names
        ]
    )
    estimated = renderer.render(rig, arm.surface_meshes(estimates[frame]))
    true = renderer.render(rig, arm.surface_meshes(truth))
    for camera in rig:
        a, b = estimated[camera.name].labels > 0, true[camera.name].labels > 0
        assert (a & b).sum() / (a | b).sum() > 0.85
    sheets = fig6_fig7_sheets(abis_run, frames=[0, frame])
    assert [p.name for p in sheets] == ["fig6_input_views.png", "fig7_estimated_views.png"]
    six, seven = (matplotlib.image.imread(p) for p in sheets)
    assert six.shape == seven.shape and seven.std() > 0.05
