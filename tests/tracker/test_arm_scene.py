import numpy as np

from tracker.models.dsq import PARAM_INDEX
from tracker.sequence import simulate


def test_simulate_yields_each_frame_rendered_from_every_view_with_timings(arm, motion, rig, renderer):
    frames = list(simulate(arm, motion, rig, renderer, 3))
    assert [f.frame for f in frames] == [0, 1, 2]
    for frame in frames:
        assert set(frame.views) == {"front", "left", "top"} and set(frame.timings_ms) == {"pose", "render"}
        np.testing.assert_allclose(frame.truth, motion.params(arm, frame.frame))


def test_truth_motion_bends_and_rotates_the_forearm(arm, motion):
    params = np.stack([motion.params(arm, frame) for frame in range(64)])
    b1, r2 = params[:, 1, PARAM_INDEX["b1"]], params[:, 1, PARAM_INDEX["r2"]]
    assert b1.max() - b1.min() > 0.07 and np.ptp(np.degrees(r2)) > 60
    np.testing.assert_allclose(params[:, 0, PARAM_INDEX["a"]], 0.26)  # shapes other than b1 are constant
    # The shoulder stays put.
    shoulders = [arm.world_transforms(p)[0] @ np.append(-np.array([0, 0, 0.26]), 1) for p in params]
    np.testing.assert_allclose(np.array(shoulders)[:, :3], 0.0, atol=1e-12)


def test_forearm_is_seriously_occluded_in_the_left_view_only(arm, motion, rig, renderer):
    pixels = {view: [] for view in ("front", "left", "top")}
    for frame in range(0, 48, 4):  # one elbow period
        views = renderer.render(rig, arm.surface_meshes(motion.params(arm, frame)))
        for view, rendered in views.items():
            pixels[view].append(np.count_nonzero(rendered.labels == 2))
    left = np.array(pixels["left"])
    assert left.min() <= 0.05 * left.max()  # hidden behind the upper arm ...
    assert np.mean(left < 0.2 * left.max()) >= 0.25  # ... for a good part of the swing
    for view in ("front", "top"):
        assert min(pixels[view]) >= 0.3 * max(pixels[view]) > 0
