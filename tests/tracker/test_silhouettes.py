import numpy as np
import pytest

from tests.conftest import MOCAP_DIR
from tracker.geometry.rigs import mono
from tracker.motion.body_swing import BodySwing
from tracker.motion.mocap import MocapScene
from tracker.observe.silhouettes import BackgroundModel, SilhouetteCapture, iou
from tracker.render.nuisance import SensorNuisance
from tracker.sequence import background_frames, simulate

BLUE = (40, 70, 190)


def test_extracted_silhouettes_match_the_render_mask_under_noise_and_changing_light(body):
    from tracker.render.offscreen import SceneRenderer

    camera = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=480.0, width=320, height=240)
    nuisance, rng = SensorNuisance(noise_std=2.0, gain_amplitude=0.04, gain_period_frames=8), np.random.default_rng(0)
    scores = []
    with SceneRenderer(320, 240, background_rgb=BLUE) as renderer:
        capture = SilhouetteCapture.learn(background_frames(camera, renderer, 20, nuisance, rng))
        for scene in (BodySwing(period_frames=8), MocapScene(str(MOCAP_DIR / "79_92.bvh"), fps=4)):
            for frame in simulate(body, scene, camera, renderer, 8, nuisance, rng):  # light at every gain level
                captured = capture.step({"main": frame.views["main"].rgb}, {"main": frame.views["main"].labels > 0})
                scores.append(captured.iou["main"])
    assert min(scores) >= 0.97, scores


def test_a_change_of_light_alone_is_not_foreground_but_a_darker_object_of_the_same_hue_is():
    rng = np.random.default_rng(1)
    backdrop = np.broadcast_to(np.array(BLUE, np.uint8), (30, 40, 3))
    nuisance = SensorNuisance(noise_std=2.0, gain_amplitude=0.0)
    model = BackgroundModel.learn(np.stack([nuisance.apply(backdrop, k, rng) for k in range(10)]))
    brighter = SensorNuisance(noise_std=2.0, gain_amplitude=0.06, gain_period_frames=4).apply(backdrop, 1, rng)
    assert not model.silhouette(brighter).any()  # normalised colour unchanged, raw change 12 levels < 60
    image = nuisance.apply(backdrop, 0, rng)
    image[10:20, 10:20] = (np.array(BLUE) * 0.4).astype(np.uint8)  # same hue, 60 % darker: only the raw test sees it
    silhouette = model.silhouette(image)
    assert silhouette[10:20, 10:20].all() and silhouette.sum() == 100


def test_iou():
    a, b = np.zeros((4, 4), bool), np.zeros((4, 4), bool)
    a[:2], b[1:3] = True, True
    assert iou(a, b) == pytest.approx(4 / 12) and iou(a, a) == 1.0 and iou(~a & a, ~a & a) == 1.0
