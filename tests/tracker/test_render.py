import contextlib
import os
import subprocess
import sys

import numpy as np
import pytest

from tracker.geometry.cameras import look_at
from tracker.models.dsq import DSQShape, dsq_points, mesh_topology
from tracker.render.gl import PLATFORM_VARIABLE, RASTERISER_THREADS_VARIABLE, load_pyrender
from tracker.render.mesh import SurfaceMesh, vertex_normals
from tracker.render.offscreen import BOX_MARGIN_PX, DEFAULT_BACKGROUND, SceneRenderer, drawn_box


def rasterize(camera, vertices, faces):
    """Pixels whose centre lies inside a projected triangle (OpenGL's coverage rule), by barycentric tests."""
    uv, _ = camera.project(vertices)
    mask = np.zeros((camera.height, camera.width), bool)
    for tri in uv[faces]:
        lo = np.maximum(np.floor(tri.min(0)).astype(int), 0)
        hi = np.minimum(np.ceil(tri.max(0)).astype(int), [camera.width - 1, camera.height - 1])
        if (hi < lo).any():
            continue
        us, vs = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        (ax, ay), (bx, by), (cx, cy) = tri
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if abs(area) < 1e-12:
            continue
        w0 = ((bx - us) * (cy - vs) - (by - vs) * (cx - us)) / area
        w1 = ((cx - us) * (ay - vs) - (cy - vs) * (ax - us)) / area
        inside = (w0 >= 0) & (w1 >= 0) & (w0 + w1 <= 1)
        mask[vs[inside], us[inside]] = True
    return mask


def iou(a, b):
    return np.count_nonzero(a & b) / np.count_nonzero(a | b)


def sphere_mesh(center, radius, label=1, resolution=(40, 48)):
    topology = mesh_topology(*resolution)
    vertices = dsq_points(DSQShape(a=radius).to_params(), topology.eta, topology.omega) + center
    return SurfaceMesh(
        key=f"sphere{label}",
        label=label,
        vertices=vertices,
        faces=topology.faces,
        normals=vertex_normals(vertices, topology.faces, topology.weld),
        color=(200, 100, 50),
    )


def test_label_image_agrees_with_the_projected_mesh(arm, motion, rig, renderer):
    meshes = arm.surface_meshes(motion.params(arm, 10))
    for part_mesh in meshes:  # each part alone: its label region is exactly its projected silhouette
        views = renderer.render(rig, [part_mesh])
        for camera in rig:
            expected = rasterize(camera, part_mesh.vertices, part_mesh.faces)
            if expected.sum() < 50:
                continue  # seen end-on in the left view: too few pixels for a ratio to mean anything
            assert iou(views[camera.name].labels == part_mesh.label, expected) >= 0.98, (part_mesh.key, camera.name)
    views = renderer.render(rig, meshes)  # all parts: the union of their silhouettes, labels 1..3 only
    for camera in rig:
        expected = np.zeros((240, 320), bool)
        for mesh in meshes:
            expected |= rasterize(camera, mesh.vertices, mesh.faces)
        assert iou(views[camera.name].labels > 0, expected) >= 0.98
        assert set(np.unique(views[camera.name].labels)) <= {0, 1, 2, 3}


@pytest.mark.parametrize("size", [(320, 240), (81, 61)], ids=["320x240", "81x61"])
def test_depth_is_the_camera_z_of_the_nearest_surface(renderer, size):
    """Also at a width whose rows are no multiple of 4 bytes (read back unpadded), where the z-buffer render reads
    the same depth and labels as the lit and labelled one."""
    width, height = size
    camera = look_at(
        "c",
        np.array([0.2, -2.5, 0.3]),
        np.zeros(3),
        np.array([0, 0, 1.0]),
        width=width,
        height=height,
        focal_px=400.0 * width / 320,
    )
    center, radius = np.array([0.1, 0.2, -0.1]), 0.3
    mesh = sphere_mesh(center, radius, resolution=(160, 192))
    with contextlib.ExitStack() as stack:
        if size != (renderer.width, renderer.height):
            renderer = stack.enter_context(SceneRenderer(width, height))
        view = renderer.render([camera], [mesh])["c"]
        zbuffer = renderer.render_depth_labels([camera], [mesh])["c"]
    np.testing.assert_array_equal(zbuffer.depth, view.depth)
    np.testing.assert_array_equal(zbuffer.labels, view.labels)
    rows, columns = np.random.default_rng(0).integers(0, [height, width], (500, 2)).T  # on and off the sphere
    np.testing.assert_array_equal(zbuffer.depth_at(rows, columns), view.depth[rows, columns])  # read where needed
    assert iou(view.labels == 1, rasterize(camera, mesh.vertices, mesh.faces)) >= 0.95
    assert iou(view.labels == 1, np.any(view.rgb != DEFAULT_BACKGROUND, axis=2)) >= 0.95  # the same rows
    # Analytic depth: intersect each pixel's ray (through its centre) with the sphere.
    us, vs = np.meshgrid(np.arange(width), np.arange(height))
    rays = np.stack([(us - camera.cx) / camera.fx, (vs - camera.cy) / camera.fy, np.ones_like(us, float)], -1)
    c = camera.world_to_camera(center[None])[0]
    b = rays @ c
    rr = np.einsum("ijk,ijk->ij", rays, rays)
    disc = b**2 - rr * (c @ c - radius**2)
    hit = disc > 0
    depth = np.where(hit, (b - np.sqrt(np.where(hit, disc, 0))) / rr, np.inf)  # camera z, as the ray has z = 1
    interior = hit & (disc > 0.02 * disc.max())  # away from the rim, where facets and coverage differ
    error = view.depth[interior] - depth[interior]
    # Flat facets lie inside the sphere, so the rendered surface is a little deeper, never shallower; at this
    # mesh resolution by under 0.5 mm (the error falls 4x per doubling of resolution: sagitta, not a bias).
    assert error.min() > -5e-5 and error.max() < 5e-4
    assert np.isinf(view.depth[~hit & (view.labels == 0)]).all()
    assert view.depth.dtype == np.float32


def test_the_z_buffer_pass_draws_only_where_its_meshes_can_be_seen_and_equals_the_whole_image_drawn(renderer):
    """`render_depth_labels` draws and reads back only each camera's `drawn_box`: its labels and depth equal those of
    `render`, which draws the whole image, bit for bit: two spheres, one cut by the image's left edge; a sphere
    reaching behind the near plane (the whole image drawn); spheres in front, right of the image (nothing drawn)."""
    camera = look_at(
        "c", np.array([0.0, -2.0, 0.0]), np.zeros(3), np.array([0, 0, 1.0]), width=320, height=240, focal_px=400.0
    )
    edge = np.array([-0.8, 0.0, 0.1])  # its centre projects 160 px left of the centre: half of it off the image
    scenes = {
        "two spheres": [sphere_mesh(np.array([0.1, 0.0, -0.1]), 0.2, 1), sphere_mesh(edge, 0.1, 2)],
        "through the near plane": [sphere_mesh(np.array([0.0, -1.9, 0.0]), 0.2, 1)],
        "out of sight": [sphere_mesh(np.array([3.0, 1.0, z]), 0.1, label) for label, z in ((1, 0.0), (2, 1.0))],
    }
    boxes = {}
    for name, meshes in scenes.items():
        boxes[name] = drawn_box(camera, np.concatenate([m.vertices for m in meshes]), renderer.znear)
        whole = renderer.render([camera], meshes)["c"]
        zbuffer = renderer.render_depth_labels([camera], meshes)["c"]
        np.testing.assert_array_equal(zbuffer.labels, whole.labels, err_msg=name)
        np.testing.assert_array_equal(zbuffer.depth, whole.depth, err_msg=name)
    u0, v0, u1, v1 = boxes["two spheres"]
    assert u0 == 0 and (u1 - u0) * (v1 - v0) < 0.6 * 320 * 240  # cut at the edge, a part of the image
    assert boxes["through the near plane"] is None
    u0, v0, u1, v1 = boxes["out of sight"]
    assert (u1 - u0) * (v1 - v0) == 0 and not whole.labels.any()


def test_the_drawn_box_bounds_the_projected_vertices_widened_by_its_margin():
    """`drawn_box` (one compiled pass) against the bounds of `Camera.project`'s pixels, widened by `BOX_MARGIN_PX`
    and cut at the image, for clouds in and across the image; None (the whole image) when a vertex is behind the
    near plane or not a number."""
    camera = look_at(
        "c", np.array([0.0, -2.0, 0.0]), np.zeros(3), np.array([0, 0, 1.0]), width=320, height=240, focal_px=400.0
    )
    rng = np.random.default_rng(11)
    for spread in (0.05, 0.3, 2.0):
        vertices = rng.normal([0.2, 0.0, -0.1], spread, size=(500, 3))
        vertices[:, 1] = np.maximum(vertices[:, 1], -1.5)  # in front of the camera (at y = -2)
        pixels, _ = camera.project(vertices)
        low = np.maximum(np.floor(pixels.min(axis=0)).astype(int) - BOX_MARGIN_PX, 0)
        high = np.minimum(np.ceil(pixels.max(axis=0)).astype(int) + 1 + BOX_MARGIN_PX, [320, 240])
        assert drawn_box(camera, vertices, 0.05) == (low[0], low[1], *np.maximum(high, low))
    behind, lost = vertices.copy(), vertices.copy()
    behind[7] = [0.0, -2.5, 0.0]
    lost[3, 2] = np.nan
    assert drawn_box(camera, behind, 0.05) is None and drawn_box(camera, lost, 0.05) is None
    assert drawn_box(camera, np.zeros((0, 3)), 0.05) == (0, 0, 0, 0)


def test_the_z_buffer_pass_is_drawn_without_pyrenders_scene_and_equals_its_label_pass_frame_after_frame(
    arm, motion, rig, renderer, monkeypatch
):
    """On OSMesa `render_depth_labels` draws its meshes itself (pyrender's renderer is not called), refilling its
    buffers every frame: the arm's z-buffer meshes over three frames and three cameras, then no mesh at all, give
    the labels and depth of pyrender's own label pass (`render`), bit for bit."""
    load_pyrender()
    import pyrender.renderer

    calls = []
    render = pyrender.renderer.Renderer.render

    def counted(*args, **kwargs):
        calls.append(1)
        return render(*args, **kwargs)

    frames = [arm.zbuffer_meshes(motion.params(arm, frame)) for frame in (0, 6, 12)] + [[]]
    for meshes in frames:
        whole = renderer.render(rig, meshes)
        with monkeypatch.context() as patch:
            patch.setattr(pyrender.renderer.Renderer, "render", counted)
            zbuffers = renderer.render_depth_labels(rig, meshes)
        for camera in rig:
            np.testing.assert_array_equal(zbuffers[camera.name].labels, whole[camera.name].labels)
            np.testing.assert_array_equal(zbuffers[camera.name].depth, whole[camera.name].depth)
        assert any(whole[camera.name].labels.any() for camera in rig) == bool(meshes)
    assert not calls


def test_uniforms_are_set_only_when_they_change_and_the_images_are_pyrenders_own(arm, motion, rig, monkeypatch):
    """The textured arm's frames drawn with uniforms set only when their values change (`tracker.render.gl`) equal,
    bit for bit, those drawn with pyrender's own setter, which sets each one again for every part, with under half the
    uniform lookups; a renderer's programs, deleted when it closes, forget what they held."""
    load_pyrender()  # the platform chosen, and the setter in place, before pyrender's module is imported here
    import pyrender.shader_program as shader_program

    frames = [arm.surface_meshes(motion.params(arm, frame)) for frame in (0, 5, 10)]
    lookups = {"changed": 0, "every": 0}
    look_up = shader_program.glGetUniformLocation

    def drawn(setter):
        def counted(*args):
            lookups[setter] += 1
            return look_up(*args)

        with monkeypatch.context() as patch:
            patch.setattr(shader_program, "glGetUniformLocation", counted)
            if setter == "every":
                patch.setattr(shader_program.ShaderProgram, "set_uniform", changed.pyrender_set_uniform)
            with SceneRenderer(320, 240) as renderer:  # programs of its own
                views = [renderer.render(rig, meshes) for meshes in frames]
                programs = list(renderer._renderer._renderer._program_cache._program_cache.values())
        assert programs and not any("_held_uniforms" in vars(program) for program in programs)
        return views

    changed = shader_program.ShaderProgram.set_uniform
    for ours, theirs in zip(drawn("changed"), drawn("every"), strict=True):
        for camera in rig:
            for image in ("rgb", "depth", "labels"):
                np.testing.assert_array_equal(getattr(ours[camera.name], image), getattr(theirs[camera.name], image))
    assert lookups["changed"] < lookups["every"] / 2


def test_convention_pin_a_rendered_blob_sits_where_the_camera_projects_it(rig, renderer):
    camera = rig[0]
    for center in (np.array([0.3, 0.1, 0.05]), np.array([0.9, -0.2, -0.3])):
        view = renderer.render([camera], [sphere_mesh(center, 0.03)])[camera.name]
        vs, us = np.nonzero(view.labels == 1)
        expected, _ = camera.project(center[None])
        # A sphere projects to an ellipse whose centre is slightly off the centre's projection; 0.15 px covers it
        # and still rejects the half-pixel offset of the wrong pixel convention.
        np.testing.assert_allclose([us.mean(), vs.mean()], expected[0], atol=0.15)


def test_rendering_is_deterministic_and_reuses_the_context(arm, motion, rig, renderer):
    meshes = arm.surface_meshes(motion.params(arm, 3))
    first = renderer.render(rig, meshes)
    materials = len(renderer._materials)
    renderer.render(rig, arm.surface_meshes(motion.params(arm, 30)))
    again = renderer.render(rig, meshes)
    for name in first:
        np.testing.assert_array_equal(first[name].rgb, again[name].rgb)
        np.testing.assert_array_equal(first[name].labels, again[name].labels)
    assert len(renderer._materials) == materials  # one material (texture upload) per part, not one per frame


def test_where_two_surfaces_lie_at_the_same_depth_the_first_mesh_listed_is_seen(renderer):
    """Two coplanar squares, red and blue: the overlap shows the one listed first, in colour and label, whatever
    the nodes' addresses and whatever was rendered before (pyrender draws mesh nodes in a set's order; it used to
    follow the addresses, so a hand on the face showed one part's texture or the other's from run to run)."""
    camera = look_at(
        "c", np.array([0.0, -2.0, 0.0]), np.zeros(3), np.array([0, 0, 1.0]), width=320, height=240, focal_px=400.0
    )
    quad = np.array([[-0.3, 0.0, -0.3], [0.3, 0.0, -0.3], [0.3, 0.0, 0.3], [-0.3, 0.0, 0.3]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from the camera (-y)
    red, blue = (
        SurfaceMesh(key=name, label=label, vertices=quad + shift, faces=faces, normals=None, color=color)
        for name, label, shift, color in (("red", 1, (-0.1, 0, 0), (255, 0, 0)), ("blue", 2, (0.1, 0, 0), (0, 0, 255)))
    )
    centre = (120, 160)  # the camera looks at the overlap's middle
    for _ in range(3):  # nodes made anew each time, at other addresses
        for meshes, seen in (([red, blue], 1), ([blue, red], 2)):
            view = renderer.render([camera], meshes)["c"]
            assert view.labels[centre] == seen
            assert (view.rgb[centre][0] > view.rgb[centre][2]) == (seen == 1)


def test_repeated_renders_reuse_compiled_shaders(arm, motion, rig, renderer):
    # Regression: under OSMesa every pass used to miss pyrender's shader cache and compile (and leak) new programs.
    renderer.render(rig, arm.surface_meshes(motion.params(arm, 0)))
    programs = renderer._renderer._renderer._program_cache._program_cache  # pyrender internals, on purpose
    compiled = len(programs)
    for frame in range(1, 4):
        renderer.render(rig, arm.surface_meshes(motion.params(arm, frame)))
    assert len(programs) == compiled


def test_rgb_has_texture_where_the_part_is(arm, motion, rig, renderer):
    view = renderer.render(rig, arm.surface_meshes(motion.params(arm, 0)))["front"]
    part = view.labels == 1
    assert view.rgb[part].std() > 20  # blocks of different brightness
    np.testing.assert_array_equal(view.rgb[~(view.labels > 0)][0], [40, 40, 48])  # plain background


def test_camera_size_must_match_the_renderer(renderer):
    small = look_at("s", np.array([0, -2.0, 0]), np.zeros(3), np.array([0, 0, 1.0]), width=64, height=48, focal_px=50)
    with pytest.raises(ValueError, match="64x48"):
        renderer.render([small], [])


def _run_python(code, **exported):
    """``code`` in a fresh Python, with this one's environment but for what `load_pyrender` sets, and ``exported``."""
    env = {k: v for k, v in os.environ.items() if k not in (PLATFORM_VARIABLE, RASTERISER_THREADS_VARIABLE)}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env | exported)


@pytest.mark.parametrize(("exported", "rasterising_threads"), [({}, 0), ({"LP_NUM_THREADS": "2"}, 2)])
def test_llvmpipe_rasterises_in_the_drawing_thread_unless_the_user_says_otherwise(exported, rasterising_threads):
    result = _run_python(
        "import os\n"
        "from tracker.render.offscreen import SceneRenderer\n"
        "with SceneRenderer(32, 24) as renderer:\n"
        "    tasks = [open(f'/proc/self/task/{t}/comm').read() for t in os.listdir('/proc/self/task')]\n"
        "print(sum(name.startswith('llvmpipe') for name in tasks))",
        **exported,
    )
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) == rasterising_threads


def test_missing_pyrender_or_osmesa_names_the_fix():
    result = _run_python(
        "import sys; sys.modules['pyrender'] = None\n"
        "from tracker.render.offscreen import SceneRenderer\n"
        "SceneRenderer(32, 32)"
    )
    assert result.returncode != 0
    assert "RenderBackendError" in result.stderr and "libosmesa6" in result.stderr


def test_opengl_imported_before_the_platform_is_set_is_reported():
    result = _run_python("import OpenGL\nfrom tracker.render.gl import load_pyrender\nload_pyrender()")
    assert result.returncode != 0 and "PYOPENGL_PLATFORM" in result.stderr


def test_importing_the_core_needs_no_opengl():
    result = _run_python(
        "import sys, tracker.render.offscreen, tracker.sequence, tracker.models.dsq_arm\n"
        "assert 'OpenGL' not in sys.modules and 'pyrender' not in sys.modules\n"
        "assert not any(m.split('.')[0] in ('hydra', 'omegaconf', 'rerun') for m in sys.modules)"
    )
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize(
    ("edge_u", "whole"),
    [(None, True), (0.0, False), (-200.0, False)],  # in the middle; cut by the left border; out of the image
)
def test_a_view_holds_the_whole_object_only_when_no_part_of_it_touches_the_border(rig, renderer, edge_u, whole):
    from tracker.geometry.cameras import wholly_in_view

    camera, depth, radius = rig[0], 2.0, 0.1
    x = 0.0 if edge_u is None else (edge_u - camera.cx) * depth / camera.fx  # the sphere's centre projects to u
    center = camera.position + camera.rotation @ np.array([x, 0.0, depth])
    labels = renderer.render([camera], [sphere_mesh(center, radius)])[camera.name].labels
    uv, _ = camera.project(center[None])
    assert (edge_u is None) == (abs(uv[0, 0] - camera.cx) < 1)  # where it was put, by the projection alone
    assert wholly_in_view(labels) == whole
