"""Off-screen renderer: per camera an RGB image, metric depth and a part-label image.

Outputs per view (arrays indexed ``[v, u]``, OpenCV pixel convention of `tracker.geometry.cameras`):
    rgb    ``(h, w, 3)`` uint8, lit and textured, background ``background_rgb``;
    depth  ``(h, w)`` float32, camera-frame z of the nearest surface in metres, ``inf`` where there is none;
    labels ``(h, w)`` uint8, 0 for background and each mesh's ``label`` where it is the nearest surface.
One GL context serves every frame and camera of a run; textures are uploaded once per mesh ``key``. pyrender's
cost is mostly per mesh drawn, so each pass draws as few as it can, the same triangles in the same order (the same
pixels as one mesh per part): the lit pass draws consecutive meshes that look alike (untextured, one colour: the
body's parts) as one mesh, and the label pass draws every mesh as one, unlit, each vertex coloured by its part's
label. The z-buffer pass that trackers call every frame (`SceneRenderer.render_depth_labels`) skips pyrender's
scene altogether on OSMesa: `_DirectLabels` draws its one mesh with pyrender's program, into buffers refilled in
place.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numba
import numpy as np

from tracker.geometry.cameras import Camera, opengl_camera
from tracker.render.gl import RenderBackendError, load_pyrender
from tracker.render.mesh import SurfaceMesh


@dataclass(frozen=True, eq=False)
class RenderedView:
    rgb: np.ndarray
    depth: np.ndarray
    labels: np.ndarray


@dataclass(frozen=True, eq=False)
class DepthLabels:
    """A z-buffer render: labels as in `RenderedView`, no colour, and the depth as the pass read it back (``raw``),
    made metric only where it is read (`depth_at`; `depth`: the whole image, as in `RenderedView`)."""

    labels: np.ndarray
    raw: np.ndarray  # (h, w), top row first
    to_metric: Callable[[np.ndarray], np.ndarray] = field(repr=False)  # raw depths -> metric (inf: none), any shape

    def depth_at(self, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """The metric depth at pixels ``(rows, columns)``: the same values as `depth` there."""
        return self.to_metric(self.raw[rows, columns])

    @functools.cached_property
    def depth(self) -> np.ndarray:
        return self.to_metric(self.raw)


DEFAULT_BACKGROUND = (40, 40, 48)  # RGB, 8-bit


@dataclass(frozen=True)
class Lighting:
    """Ambient level and directional lights ``(direction the light travels, intensity)``, fixed in the world."""

    ambient: float = 0.35
    lights: tuple[tuple[tuple[float, float, float], float], ...] = (((0.4, 0.6, -1.0), 2.5), ((-0.6, 0.3, -0.2), 1.5))


class SceneRenderer:
    """Renders `SurfaceMesh` lists from cameras of one image size. Close it (or use ``with``) to free the context."""

    def __init__(
        self,
        width: int,
        height: int,
        *,
        background_rgb: tuple[int, int, int] = DEFAULT_BACKGROUND,
        lighting: Lighting = Lighting(),
        znear: float = 0.05,
        zfar: float = 100.0,
    ) -> None:
        self._pyrender = load_pyrender()
        from OpenGL import GL  # only once pyrender has chosen the platform

        self._gl = GL
        self.width, self.height = int(width), int(height)
        self.znear, self.zfar = znear, zfar
        pr = self._pyrender
        background = [*(channel / 255.0 for channel in background_rgb), 1.0]
        self._scene = pr.Scene(bg_color=background, ambient_light=[lighting.ambient] * 3)
        for direction, intensity in lighting.lights:
            self._scene.add(pr.DirectionalLight(color=np.ones(3), intensity=intensity), pose=_light_pose(direction))
        self._camera_node = self._scene.add(pr.IntrinsicsCamera(fx=1, fy=1, cx=0, cy=0))
        self._materials: dict[str, object] = {}
        self._lit_nodes: list = []  # the lit pass's: one per run of alike meshes, or per mesh
        self._label_node = None  # the label pass's: every mesh as one, each vertex coloured by its label
        self._label_material = pr.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0])
        self._direct: _DirectLabels | None = None  # the z-buffer pass without pyrender's scene (made at first use)
        self.last_pass_ms: dict[str, float] = {}  # time spent in each pass, summed over the last call's cameras
        try:
            self._renderer = pr.OffscreenRenderer(self.width, self.height)
        except Exception as error:
            raise RenderBackendError(f"cannot open an off-screen OpenGL context: {error}") from error

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        renderer, self._renderer = getattr(self, "_renderer", None), None
        if renderer is not None:
            renderer.delete()

    def render(self, cameras: Sequence[Camera], meshes: Sequence[SurfaceMesh]) -> dict[str, RenderedView]:
        """Render ``meshes`` from every camera; returns views keyed by camera name."""
        if self._renderer is None:
            raise RuntimeError("the renderer is closed")
        self._set_meshes(meshes, lit=True)
        views = {}
        pass_ms = {"rgb_depth": 0.0, "labels": 0.0}
        for camera in cameras:
            self._set_camera(camera)
            start = time.perf_counter()
            rgb, raw, to_metric = self._lit_pass()
            depth = to_metric(raw)
            lit = time.perf_counter()
            labels, _, _ = self._label_pass()
            pass_ms["rgb_depth"] += 1e3 * (lit - start)
            pass_ms["labels"] += 1e3 * (time.perf_counter() - lit)
            views[camera.name] = RenderedView(rgb=rgb, depth=depth, labels=labels)
        self.last_pass_ms = pass_ms
        return views

    def render_depth_labels(self, cameras: Sequence[Camera], meshes: Sequence[SurfaceMesh]) -> dict[str, DepthLabels]:
        """Depth and labels only (one unlit pass per camera): the z-buffer an estimator uses for visibility. Each
        pass draws and reads back only the rectangle the meshes can cover in its camera (`drawn_box`), the rest
        background: the same arrays as the whole image drawn, with less to clear and read back."""
        if self._renderer is None:
            raise RuntimeError("the renderer is closed")
        vertices = np.concatenate([mesh.vertices for mesh in meshes]) if meshes else np.zeros((0, 3))
        direct = not self._renderer._platform.supports_framebuffers()
        if direct:
            with self._current():
                self._direct_labels().load(meshes)
        else:
            self._set_meshes(meshes, lit=False)
        views = {}
        for camera in cameras:
            self._set_camera(camera)
            box = drawn_box(camera, vertices, self.znear)
            views[camera.name] = DepthLabels(*(self._direct_label_pass(box) if direct else self._label_pass(box)))
        return views

    def _set_camera(self, camera: Camera) -> None:
        if (camera.width, camera.height) != (self.width, self.height):
            raise ValueError(
                f"camera {camera.name!r} is {camera.width}x{camera.height}, the renderer {self.width}x{self.height}"
            )
        gl = opengl_camera(camera)
        self._camera_node.camera = self._pyrender.IntrinsicsCamera(
            fx=gl.fx, fy=gl.fy, cx=gl.cx, cy=gl.cy, znear=self.znear, zfar=self.zfar
        )
        self._scene.set_pose(self._camera_node, gl.pose)

    def _lit_pass(self) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """RGB and depth (`_draw`), lit and textured: the lit nodes drawn, the label node hidden."""
        if self._label_node is not None:
            self._label_node.mesh.is_visible = False
        try:
            return self._draw(self._pyrender.RenderFlags.NONE, self._gl.GL_RGB)
        finally:
            if self._label_node is not None:
                self._label_node.mesh.is_visible = True

    def _label_pass(self, box: Box | None = None) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """Labels (0 on the background) and depth (`_draw`, within ``box``): the label node drawn unlit on black,
        the lit nodes hidden."""
        background, self._scene.bg_color = self._scene.bg_color, np.array([0.0, 0.0, 0.0, 1.0])
        for node in self._lit_nodes:
            node.mesh.is_visible = False
        try:
            return self._draw(self._pyrender.RenderFlags.FLAT, self._gl.GL_RED, box)
        finally:
            self._scene.bg_color = background
            for node in self._lit_nodes:
                node.mesh.is_visible = True

    def _direct_label_pass(self, box: Box | None) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """`_label_pass` of the meshes loaded into `_DirectLabels`, drawn by it (without framebuffers only)."""
        labels, scene, renderer = self._direct_labels(), self._scene, self._renderer._renderer
        return self._draw(
            self._pyrender.RenderFlags.FLAT,
            self._gl.GL_RED,
            box,
            draw=lambda: labels.draw(*renderer._get_camera_matrices(scene), self.width, self.height),
        )

    def _direct_labels(self) -> _DirectLabels:
        """The `_DirectLabels` of this context (made at first use, the context current)."""
        if self._direct is None:
            self._direct = _DirectLabels(self._pyrender, self._gl, self._renderer._renderer, self._label_material)
        return self._direct

    @contextlib.contextmanager
    def _current(self) -> Iterator[None]:
        """The renderer's context current within."""
        platform = self._renderer._platform
        platform.make_current()
        try:
            yield
        finally:
            platform.make_uncurrent()

    def _draw(
        self, flags, colour_format: int, box: Box | None = None, draw: Callable[[], None] | None = None
    ) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """The scene drawn from the camera: its colour buffer (``GL_RGB``: ``(h, w, 3)``, ``GL_RED``: ``(h, w)``,
        uint8) and its depth as read back, both top row first, with what makes that depth metric (any pixels of it:
        a pass whose depth is read at a few pixels converts those alone).

        Without framebuffers (OSMesa) pyrender draws to the window's buffer and reads back RGB and a depth it makes
        metric with boolean masks; this reads only the channels asked for, into arrays of its own, and makes the
        depth metric with pyrender's formula, element by element (the same values). There, with a ``box`` that
        holds everything the pass can draw (a label pass: colour 0 where nothing is drawn), only the box is cleared,
        drawn (a scissor) and read, the rest filled as the clear leaves it. With framebuffers pyrender's own
        (multisampled) path is kept. ``draw``: what draws instead of pyrender's render of the scene (there only)."""
        offscreen, gl = self._renderer, self._gl
        red = colour_format == gl.GL_RED
        if offscreen._platform.supports_framebuffers():
            colour, depth = offscreen.render(self._scene, flags=flags)
            return np.ascontiguousarray(colour[:, :, 0] if red else colour), depth, _metric_depth
        u0, v0, u1, v1 = (0, 0, self.width, self.height) if box is None else box
        whole = (u0, v0, u1, v1) == (0, 0, self.width, self.height)
        shape = (v1 - v0, u1 - u0) if red else (v1 - v0, u1 - u0, 3)
        colour, window_depth = np.empty(shape, np.uint8), np.empty(shape[:2], np.float32)  # the box's, read back
        if u1 > u0 and v1 > v0:
            with self._current():
                bottom = self.height - v1  # OpenGL's rows count from the bottom
                if not whole:
                    gl.glEnable(gl.GL_SCISSOR_TEST)
                    gl.glScissor(u0, bottom, u1 - u0, v1 - v0)
                renderer = offscreen._renderer
                renderer.viewport_width, renderer.viewport_height = self.width, self.height
                try:
                    renderer.render(self._scene, flags) if draw is None else draw()
                finally:
                    gl.glDisable(gl.GL_SCISSOR_TEST)
                gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, 0)
                gl.glReadBuffer(gl.GL_FRONT)
                gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
                gl.glReadPixels(u0, bottom, u1 - u0, v1 - v0, colour_format, gl.GL_UNSIGNED_BYTE, colour)
                gl.glReadPixels(u0, bottom, u1 - u0, v1 - v0, gl.GL_DEPTH_COMPONENT, gl.GL_FLOAT, window_depth)
        metric = functools.partial(_metric_window_depth, near=self.znear, far=self.zfar)
        if whole:
            return np.ascontiguousarray(colour[::-1]), window_depth[::-1], metric
        full_colour = np.zeros((self.height, self.width, *shape[2:]), np.uint8)  # as the clear leaves them
        full_depth = np.ones((self.height, self.width), np.float32)
        full_colour[v0:v1, u0:u1], full_depth[v0:v1, u0:u1] = colour[::-1], window_depth[::-1]
        return full_colour, full_depth, metric

    def _set_meshes(self, meshes: Sequence[SurfaceMesh], lit: bool) -> None:
        """Replace last frame's nodes (vertices change every frame; materials and textures are reused): the label
        node, and with ``lit`` the lit pass's nodes."""
        pr = self._pyrender
        for node in [*self._lit_nodes, self._label_node]:
            if node is not None:
                self._scene.remove_node(node)
        # A set's order follows its history of removals as well as the hashes: a fresh one, filled in order,
        # iterates in that order (pyrender draws its mesh nodes in it).
        self._scene._mesh_nodes = set()
        node_in_order = _node_in_order(pr.Node)
        runs = _alike_runs(meshes) if lit else []
        self._lit_nodes = [
            node_in_order(order, mesh=pr.Mesh([self._primitive(_merged(meshes[first:last]))]))
            for order, (first, last) in enumerate(runs)
        ]
        self._label_node = node_in_order(len(runs), mesh=pr.Mesh([self._label_primitive(meshes)])) if meshes else None
        for node in [*self._lit_nodes, self._label_node]:
            if node is not None:
                self._scene.add_node(node)

    def _primitive(self, mesh: SurfaceMesh):
        return self._pyrender.Primitive(
            positions=mesh.vertices.astype(np.float32),
            normals=None if mesh.normals is None else mesh.normals.astype(np.float32),
            texcoord_0=None if mesh.uv is None else mesh.uv.astype(np.float32),
            indices=mesh.faces.astype(np.uint32),
            material=self._material(mesh),
        )

    def _label_primitive(self, meshes: Sequence[SurfaceMesh]):
        """Every mesh as one primitive (`_label_arrays`)."""
        positions, colours, indices = _label_arrays(meshes)
        return self._pyrender.Primitive(
            positions=positions, indices=indices, color_0=colours, material=self._label_material
        )

    def _material(self, mesh: SurfaceMesh):
        material = self._materials.get(mesh.key)
        if material is None:
            pr = self._pyrender
            texture = None
            if mesh.texture is not None:
                texture = pr.Texture(source=mesh.texture, source_channels="RGB")
            color = [*(c / 255.0 for c in mesh.color), 1.0] if texture is None else [1.0, 1.0, 1.0, 1.0]
            material = pr.MetallicRoughnessMaterial(
                baseColorFactor=color, baseColorTexture=texture, metallicFactor=0.0, roughnessFactor=1.0
            )
            self._materials[mesh.key] = material
        return material


class _DirectLabels:
    """The label pass of `SceneRenderer.render_depth_labels` drawn straight through OpenGL: what pyrender does to
    draw the label node (`_label_primitive`), without walking its scene, and with buffers made once and refilled
    each frame instead of a new mesh uploaded. The same program (pyrender's flat shaders, from its cache, for the
    same vertex attributes and material), vertex layout (position and colour interleaved in float32, one identity
    instance matrix), uniforms (set through the program as pyrender sets them) and state, so the same pixels, to
    the bit. Every call needs the renderer's context current."""

    def __init__(self, pyrender, gl, renderer, material) -> None:
        self._gl, self._material = gl, material
        corner = pyrender.Primitive(  # a primitive like every label primitive, to pick the program by
            positions=np.zeros((3, 3), np.float32),
            indices=np.array([[0, 1, 2]], np.uint32),
            color_0=np.zeros((3, 4), np.uint8),
            material=material,
        )
        flags = pyrender.constants.ProgramFlags.USE_MATERIAL
        self._program = renderer._get_primitive_program(corner, pyrender.RenderFlags.FLAT, flags)
        self._elements = 0
        self._vertex_array = gl.glGenVertexArrays(1)
        gl.glBindVertexArray(self._vertex_array)
        self._vertex_buffer, instances, self._element_buffer = gl.glGenBuffers(3)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self._vertex_buffer)  # location 0: position, 1: colour (COLOR_0_LOC)
        for location, (size, offset) in enumerate(((3, 0), (4, 3))):
            gl.glVertexAttribPointer(location, size, gl.GL_FLOAT, gl.GL_FALSE, 7 * 4, ctypes.c_void_p(4 * offset))
            gl.glEnableVertexAttribArray(location)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, instances)  # locations 2-5 (INST_M_LOC): the instance's model matrix
        identity = np.eye(4, dtype=np.float32)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, identity.nbytes, identity, gl.GL_STATIC_DRAW)
        for column in range(4):
            gl.glEnableVertexAttribArray(2 + column)
            gl.glVertexAttribPointer(2 + column, 4, gl.GL_FLOAT, gl.GL_FALSE, 4 * 4 * 4, ctypes.c_void_p(16 * column))
            gl.glVertexAttribDivisor(2 + column, 1)
        gl.glBindBuffer(gl.GL_ELEMENT_ARRAY_BUFFER, self._element_buffer)
        gl.glBindVertexArray(0)

    def load(self, meshes: Sequence[SurfaceMesh]) -> None:
        """Every mesh as one (`_label_arrays`, as `_label_primitive` has them), uploaded as pyrender uploads a
        primitive: position and colour (in [0, 1], pyrender's ``format_color_array``) interleaved in float32."""
        gl = self._gl
        positions, colours, indices = _label_arrays(meshes)
        data = np.hstack([positions, (colours / 255.0).astype(np.float32)])
        gl.glBindVertexArray(self._vertex_array)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self._vertex_buffer)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, data.nbytes, data, gl.GL_DYNAMIC_DRAW)
        gl.glBufferData(gl.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, gl.GL_DYNAMIC_DRAW)
        gl.glBindVertexArray(0)
        self._elements = indices.size

    def draw(self, view: np.ndarray, projection: np.ndarray, width: int, height: int) -> None:
        """Clear to black and draw the loaded meshes with pyrender's camera matrices ``view`` and ``projection``
        (`Renderer._get_camera_matrices`), into the window's buffer of ``width`` x ``height``."""
        gl, program, material = self._gl, self._program, self._material
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, 0)  # pyrender's forward pass without an offscreen buffer
        gl.glViewport(0, 0, width, height)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthMask(gl.GL_TRUE)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glDepthRange(0.0, 1.0)
        gl.glClearColor(0.0, 0.0, 0.0, 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
        gl.glEnable(gl.GL_MULTISAMPLE)
        if self._elements:
            program._bind()
            program.set_uniform("V", view)
            program.set_uniform("P", projection)
            program.set_uniform("M", np.eye(4))  # the label node's pose
            program.set_uniform("material.emissive_factor", material.emissiveFactor)
            program.set_uniform("material.base_color_factor", material.baseColorFactor)
            program.set_uniform("material.metallic_factor", material.metallicFactor)
            program.set_uniform("material.roughness_factor", material.roughnessFactor)
            gl.glEnable(gl.GL_BLEND)  # an opaque material, one-sided
            gl.glBlendFunc(gl.GL_ONE, gl.GL_ZERO)
            gl.glPolygonMode(gl.GL_FRONT_AND_BACK, gl.GL_FILL)
            gl.glEnable(gl.GL_CULL_FACE)
            gl.glCullFace(gl.GL_BACK)
            gl.glDisable(gl.GL_PROGRAM_POINT_SIZE)
            gl.glBindVertexArray(self._vertex_array)
            gl.glDrawElementsInstanced(gl.GL_TRIANGLES, self._elements, gl.GL_UNSIGNED_INT, ctypes.c_void_p(0), 1)
            gl.glBindVertexArray(0)
            program._unbind()
        gl.glFlush()


def _label_arrays(meshes: Sequence[SurfaceMesh]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every mesh as one, in order: ``(n, 3)`` float32 positions, ``(n, 4)`` uint8 colours (each vertex its mesh's
    label as an 8-bit grey, opaque) and ``(m, 3)`` uint32 faces."""
    if not meshes:
        return np.zeros((0, 3), np.float32), np.zeros((0, 4), np.uint8), np.zeros((0, 3), np.uint32)
    offsets = np.cumsum([0] + [len(mesh.vertices) for mesh in meshes])[:-1]
    colours = np.concatenate(
        [np.full((len(mesh.vertices), 4), (mesh.label, mesh.label, mesh.label, 255), np.uint8) for mesh in meshes]
    )
    positions = np.concatenate([mesh.vertices for mesh in meshes]).astype(np.float32)
    faces = np.concatenate([mesh.faces + offset for mesh, offset in zip(meshes, offsets, strict=True)])
    return positions, colours, faces.astype(np.uint32)


@functools.cache
def _node_in_order(node_class: type) -> type:
    """pyrender's node class with a hash that is the node's place in the list of meshes drawn.

    pyrender keeps a scene's mesh nodes in a set and draws them in its order (sorted by their poses, here all the
    same); a node's default hash is its address, so that order, and with it which of two surfaces at the same
    depth is seen (where a hand touches the face, two parts' textures), changed from run to run. Hashes 0, 1, 2, ...
    inserted into a fresh set give the meshes' own order (at the same depth the one listed first is seen)."""

    class NodeInOrder(node_class):
        def __init__(self, order: int, **kwargs) -> None:
            super().__init__(**kwargs)
            self.order = order

        def __hash__(self) -> int:
            return self.order

    return NodeInOrder


Box = tuple[int, int, int, int]  # (u0, v0, u1, v1): half-open pixel bounds, top row first

BOX_MARGIN_PX = 2  # beyond the projected vertices' bounds: coverage is by pixel centres, OpenGL's transform float32


def drawn_box(camera: Camera, vertices: np.ndarray, near: float) -> Box | None:
    """The rectangle of ``camera``'s image that holds every pixel a pass can draw of meshes with these world
    ``vertices`` ``(n, 3)``: a triangle in front of the camera projects inside its vertices' projections, so their
    bounds widened by `BOX_MARGIN_PX`, cut at the image (empty when none can be seen). None (the whole image) when
    a vertex is not in front of the near plane: clipped there, a triangle's image is not bounded by its vertices'."""
    if not len(vertices):
        return (0, 0, 0, 0)
    in_front, u_min, v_min, u_max, v_max = _projected_bounds(
        np.ascontiguousarray(vertices, dtype=np.float64),
        np.asarray(camera.position, dtype=np.float64),
        np.asarray(camera.rotation, dtype=np.float64),
        (camera.fx, camera.fy, camera.cx, camera.cy),
        near,
    )
    if not in_front:
        return None
    low = np.maximum(np.floor([u_min, v_min]).astype(int) - BOX_MARGIN_PX, 0)
    high = np.minimum(np.ceil([u_max, v_max]).astype(int) + 1 + BOX_MARGIN_PX, [camera.width, camera.height])
    high = np.maximum(high, low)
    return int(low[0]), int(low[1]), int(high[0]), int(high[1])


@numba.njit(cache=True, nogil=True)
def _projected_bounds(
    points: np.ndarray, position: np.ndarray, rotation: np.ndarray, intrinsics: tuple, near: float
) -> tuple[bool, float, float, float, float]:
    """Whether every world point ``(n, 3)`` lies beyond ``near`` in the camera (and is finite), and the bounds of
    their pixels ``(u_min, v_min, u_max, v_max)`` (`Camera.project`'s, to rounding), in one pass."""
    fx, fy, cx, cy = intrinsics
    u_min = v_min = np.inf
    u_max = v_max = -np.inf
    for point in points:
        x, y, z = point[0] - position[0], point[1] - position[1], point[2] - position[2]
        depth = x * rotation[0, 2] + y * rotation[1, 2] + z * rotation[2, 2]
        if not depth > near:  # behind the near plane, or not a number
            return False, u_min, v_min, u_max, v_max
        u = fx * (x * rotation[0, 0] + y * rotation[1, 0] + z * rotation[2, 0]) / depth + cx
        v = fy * (x * rotation[0, 1] + y * rotation[1, 1] + z * rotation[2, 1]) / depth + cy
        if not (np.isfinite(u) and np.isfinite(v)):
            return False, u_min, v_min, u_max, v_max
        u_min, u_max = min(u_min, u), max(u_max, u)
        v_min, v_max = min(v_min, v), max(v_max, v)
    return True, u_min, v_min, u_max, v_max


def _metric_window_depth(window_depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """OpenGL's window depth (1 where nothing was drawn) as metric depth, ``inf`` where nothing was drawn:
    pyrender's read_depth_buf's formula (camera z, 0 where nothing was drawn), then `_metric_depth`."""
    depth = (2.0 * near * far) / (far + near - (2.0 * window_depth - 1.0) * (far - near))
    return _metric_depth(np.where(window_depth < 1.0, depth, 0.0))


def _metric_depth(depth: np.ndarray) -> np.ndarray:
    """pyrender's depth (camera z in metres, 0 where nothing was drawn) with ``inf`` where nothing was drawn."""
    return np.where(depth > 0, depth, np.inf).astype(np.float32)


def _look(mesh: SurfaceMesh) -> tuple | None:
    """What a mesh looks like in the lit pass, when two meshes alike in it can be drawn as one (None: its own)."""
    if mesh.texture is not None or mesh.uv is not None or mesh.normals is None:
        return None
    return tuple(mesh.color)


def _alike_runs(meshes: Sequence[SurfaceMesh]) -> list[tuple[int, int]]:
    """``[first, last)`` of each run of consecutive meshes alike in the lit pass (a mesh with a look of its own, a
    textured one, is a run of one)."""
    runs, first = [], 0
    for index in range(1, len(meshes) + 1):
        if index == len(meshes) or _look(meshes[index]) is None or _look(meshes[index]) != _look(meshes[first]):
            runs.append((first, index))
            first = index
    return runs


def _merged(meshes: Sequence[SurfaceMesh]) -> SurfaceMesh:
    """Alike meshes as one, their vertices and faces one after another, in order (one mesh: itself)."""
    if len(meshes) == 1:
        return meshes[0]
    offsets = np.cumsum([0] + [len(mesh.vertices) for mesh in meshes])[:-1]
    return SurfaceMesh(
        key=f"merged {meshes[0].color}",
        label=meshes[0].label,
        vertices=np.concatenate([mesh.vertices for mesh in meshes]),
        faces=np.concatenate([mesh.faces + offset for mesh, offset in zip(meshes, offsets, strict=True)]),
        normals=np.concatenate([mesh.normals for mesh in meshes]),
        color=meshes[0].color,
    )


def _light_pose(direction: Sequence[float]) -> np.ndarray:
    """A pose whose -z axis (pyrender's light direction) points along ``direction``."""
    z = -np.asarray(direction, dtype=np.float64)
    z /= np.linalg.norm(z)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return pose
