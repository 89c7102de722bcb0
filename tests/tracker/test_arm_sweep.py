"""``scene=arm_sweep``: the upper arm sweeps round a still forearm and covers it in the front view; and AbIS
on it discards the forearm's front-view pairs by the model's prediction, not by losing them."""

import numpy as np
import pandas as pd
import pytest

from experiments.components import build, compose
from tests.conftest import run_cli
from tracker.models.dsq import PARAM_INDEX


@pytest.fixture(scope="module")
def sweep():
    return build(compose(["experiment=abis_occlusion"]))


def test_the_forearm_holds_still_while_the_elbow_flexes_and_the_upper_arm_swings(sweep):
    arm, scene = sweep.model, sweep.scene
    frames = range(0, int(scene.period_frames) + 1, 4)
    params = [scene.params(arm, frame) for frame in frames]
    for p in params:
        np.testing.assert_allclose(arm.connect(p), p, atol=1e-12)  # joints connected
    forearms = np.array([arm.world_transforms(p)[1] for p in params])
    np.testing.assert_allclose(forearms, np.broadcast_to(forearms[0], forearms.shape), atol=1e-9)
    flexion = np.array([p[1, PARAM_INDEX["r2"]] for p in params])
    np.testing.assert_allclose(flexion, [scene.flexion(frame) for frame in frames])
    assert flexion.max() == pytest.approx(scene.elbow_flexion) and flexion.min() == pytest.approx(scene.elbow_extension)
    shoulders = np.array([arm.world_transforms(p)[0][:3, 3] for p in params])
    assert np.ptp(shoulders, axis=0).max() > 0.3  # the root is what moves


def test_the_forearm_is_covered_in_the_front_view_while_the_others_see_it(sweep, renderer):
    arm, scene = sweep.model, sweep.scene
    pixels = {camera.name: [] for camera in sweep.cameras}
    for frame in range(0, int(sweep.scene.period_frames) + 1, 8):
        for name, view in renderer.render(sweep.cameras, arm.surface_meshes(scene.params(arm, frame))).items():
            pixels[name].append(np.count_nonzero(view.labels == 2))
    front = np.array(pixels["front"])
    assert front[0] > 1500 and front.min() <= 0.02 * front.max()
    assert min(pixels["top"]) >= 0.5 * max(pixels["top"]) > 0  # the top view sees it all along
    covered = front < 0.2 * front.max()
    assert np.all(np.array(pixels["left"])[covered] >= 0.5 * max(pixels["left"]))  # the left view while covered


def test_abis_discards_the_covered_forearms_pairs_for_occlusion(tmp_path):
    # Up to frame 40 of the sweep, by when the upper arm covers the forearm in the front view.
    result = run_cli(tmp_path / "out", "experiment=abis_occlusion", "frames=40", "record.images=false", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    table = pd.read_parquet(tmp_path / "out" / "frames.parquet")
    forearm = table[table["part"] == "forearm"].sort_values("frame")
    assert (forearm["tracked_front"] + forearm["new_front"]).max() >= 10
    assert forearm["visible_px_front"].iloc[-1] == 0  # covered by the end
    covering = forearm[forearm["frame"] >= forearm["frame"].iloc[int(forearm["visible_px_front"].argmax())]]
    left = covering[["discarded_occlusion_front", "discarded_error_front", "lost_front"]].sum()
    assert left["discarded_occlusion_front"] >= 0.5 * left.sum() > 0
