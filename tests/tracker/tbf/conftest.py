import numpy as np
import pytest


@pytest.fixture(scope="module")
def body_silhouettes(body):
    """Silhouettes of the body at 80x60 in 12 poses of the arm swing (side-on)."""
    from tracker.geometry.rigs import mono
    from tracker.motion.body_swing import BodySwing
    from tracker.render.offscreen import SceneRenderer

    camera = mono(position=(4.0, 0.0, 0.9), target=(0.0, 0.0, 0.9), focal_px=120.0, width=80, height=60)
    swing = BodySwing()
    with SceneRenderer(80, 60) as renderer:
        return np.array(
            [
                renderer.render_depth_labels(camera, body.surface_meshes(swing.params(body, 3 * k)))["main"].labels > 0
                for k in range(12)
            ]
        )
