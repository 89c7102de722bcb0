import numpy as np

from eval.plotting import views_sheet
from eval.recordings import read_rgb_frames


def test_recorded_images_round_trip_through_the_recording(five_frame_run, arm, motion, rig, renderer):
    images = read_rgb_frames(five_frame_run / "run.rrd", "left")
    assert sorted(images) == [0, 1, 2, 3, 4]
    rendered = renderer.render(rig, arm.surface_meshes(motion.params(arm, 3)))["left"].rgb
    assert images[3].shape == rendered.shape == (240, 320, 3)
    assert np.abs(images[3].astype(int) - rendered).mean() < 2.0  # AV1 video, YUV 4:2:0 (about 1.3 measured)


def test_views_sheet_shows_every_view_of_the_chosen_frames(five_frame_run, tmp_path):
    import matplotlib.image

    out = views_sheet(five_frame_run, frames=[0, 4], out=tmp_path / "sheet.png")
    sheet = matplotlib.image.imread(out)
    assert sheet.shape[1] > sheet.shape[0]  # 3 views across, 2 frames down
    assert [p.name for p in tmp_path.iterdir()] == ["sheet.png"]
