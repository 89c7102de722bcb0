"""Part-label images of many posed meshes at once: one draw call per batch, for pose sample sets.

The meshes share one topology (faces, and a part label per face) and come already projected by the caller:
per vertex its pixel ``(u, v)`` in the OpenCV convention of `tracker.geometry.cameras` (centre of pixel
``[row j, column i]`` at ``(i, j)``), relative to the image's top-left corner, and its camera depth ``z`` (metres,
> 0). Each mesh is drawn into its own tile of one canvas (instanced: the instance is the mesh), with a depth test
and no lighting, multisampling or blending, so every pixel holds the label of the nearest face covering its
centre (0 where none): the same rule, and to rounding the same images, as the per-part label pass of
`tracker.render.offscreen`.

Perspective without a perspective camera: the caller's projection is exact, and the depth written is affine in
``1 / z`` (``1 - 2 z_near / z``), which is what a perspective z-buffer interpolates linearly across a triangle on
the screen; so the nearest surface wins at every pixel as it would under the camera.

The same image wherever a mesh's tile lies: pixel positions are rounded to `SUBPIXEL` of a pixel (finer than the
rasteriser's own grid) and the canvas' sides are powers of two, so that a vertex's place in the canvas and back
is exact in float32, and a mesh's image depends on the mesh alone, not on the batch it was drawn in.
"""

from __future__ import annotations

import numpy as np

from tracker.render.gl import RenderBackendError, load_pyrender

_VERTEX_SHADER = """#version 330 core
uniform samplerBuffer positions;  // (u, v, z) per vertex, mesh after mesh
uniform int vertices;             // per mesh
uniform ivec2 tile;               // pixels
uniform ivec2 canvas;             // pixels
uniform int columns;              // tiles per canvas row
uniform float near;               // smaller than every z drawn
void main() {
    vec3 p = texelFetch(positions, gl_InstanceID * vertices + gl_VertexID).xyz;
    vec2 corner = vec2(gl_InstanceID % columns, gl_InstanceID / columns) * vec2(tile);
    vec2 ndc = 2.0 * (corner + p.xy + 0.5) / vec2(canvas) - 1.0;  // rows grow with v: the canvas is read as stored
    gl_Position = vec4(ndc, 1.0 - 2.0 * near / p.z, 1.0);
}
"""
_FRAGMENT_SHADER = """#version 330 core
uniform usamplerBuffer face_labels;
out vec4 label;
void main() {
    label = vec4(float(texelFetch(face_labels, gl_PrimitiveID).r) / 255.0, 0.0, 0.0, 1.0);
}
"""


SUBPIXEL = 1.0 / 256


class LabelRenderer:
    """Draws batches of up to ``capacity`` meshes of one topology into ``height`` x ``width`` label tiles (a larger
    canvas draws no faster: measured). ``closed``: the meshes are closed, their faces counter-clockwise seen from
    outside, so their back faces are never seen and are skipped. Close it (or use ``with``) to free its context."""

    def __init__(
        self,
        faces: np.ndarray,
        face_labels: np.ndarray,
        vertices: int,
        width: int,
        height: int,
        capacity: int = 32,
        closed: bool = False,
    ) -> None:
        if face_labels.max(initial=0) > 255:
            raise ValueError("labels must fit a byte (1..255)")
        self.vertices, self.width, self.height = int(vertices), int(width), int(height)
        self._gl = _load_gl()
        limit = 4096  # canvas side, well inside every implementation's renderbuffer limit
        self.columns = max(1, min(capacity, limit // self.width))
        self.capacity = min(capacity, self.columns * max(1, limit // self.height))
        rows = -(-self.capacity // self.columns)
        self.used = (self.columns * self.width, rows * self.height)  # the part of the canvas drawn and read
        self.canvas = tuple(1 << (side - 1).bit_length() for side in self.used)  # powers of two
        self._platform = _context(*self.canvas)
        self._faces = int(faces.size)
        self._setup(np.ascontiguousarray(faces, np.uint32), np.ascontiguousarray(face_labels, np.uint8), closed)

    def __enter__(self) -> LabelRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        platform, self._platform = getattr(self, "_platform", None), None
        if platform is not None:
            platform.make_current()
            platform.delete_context()

    def render(self, pixels: np.ndarray, depth: np.ndarray, near: float) -> np.ndarray:
        """``(n, height, width)`` uint8 label images of ``n`` meshes: ``pixels`` ``(n, vertices, 2)`` their
        vertices' ``(u, v)`` in the tile, ``depth`` ``(n, vertices)`` their camera z, every one above ``near``
        (metres; the same ``near`` gives the same images whatever else is in the batch)."""
        if not 0 < near < float(np.min(depth, initial=np.inf)):
            raise ValueError(f"near={near}: every depth must lie beyond it, and it beyond 0")
        gl = self._gl
        images = []
        self._platform.make_current()
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self._framebuffer)
        gl.glViewport(0, 0, *self.canvas)
        gl.glUseProgram(self._program)
        for first in range(0, len(pixels), self.capacity):
            count = min(self.capacity, len(pixels) - first)
            grid = np.round(pixels[first : first + count] / SUBPIXEL) * SUBPIXEL
            batch = np.ascontiguousarray(
                np.concatenate([grid, depth[first : first + count, :, None]], axis=2), np.float32
            )
            gl.glBindBuffer(gl.GL_TEXTURE_BUFFER, self._positions)
            gl.glBufferSubData(gl.GL_TEXTURE_BUFFER, 0, batch.nbytes, batch)
            gl.glUniform1f(self._near, near)
            gl.glClearColor(0.0, 0.0, 0.0, 0.0)
            gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
            gl.glDrawElementsInstanced(gl.GL_TRIANGLES, self._faces, gl.GL_UNSIGNED_INT, None, count)
            canvas = np.frombuffer(gl.glReadPixels(0, 0, *self.used, gl.GL_RED, gl.GL_UNSIGNED_BYTE), np.uint8)
            tiles = canvas.reshape(-1, self.height, self.columns, self.width).transpose(0, 2, 1, 3)
            images.append(tiles.reshape(-1, self.height, self.width)[:count])
        return np.concatenate(images) if images else np.zeros((0, self.height, self.width), np.uint8)

    def _setup(self, faces: np.ndarray, face_labels: np.ndarray, closed: bool) -> None:
        gl = self._gl
        self._platform.make_current()
        self._program = _program(gl)
        gl.glUseProgram(self._program)
        self._vertex_array = gl.glGenVertexArrays(1)
        gl.glBindVertexArray(self._vertex_array)
        elements = gl.glGenBuffers(1)
        gl.glBindBuffer(gl.GL_ELEMENT_ARRAY_BUFFER, elements)
        gl.glBufferData(gl.GL_ELEMENT_ARRAY_BUFFER, faces.nbytes, faces, gl.GL_STATIC_DRAW)
        self._positions = _texture_buffer(gl, gl.GL_RGB32F, 0, self.capacity * self.vertices * 12, None)
        _texture_buffer(gl, gl.GL_R8UI, 1, face_labels.nbytes, face_labels)
        for name, value in (
            ("positions", 0),
            ("face_labels", 1),
            ("vertices", self.vertices),
            ("columns", self.columns),
        ):
            gl.glUniform1i(gl.glGetUniformLocation(self._program, name), value)
        gl.glUniform2i(gl.glGetUniformLocation(self._program, "tile"), self.width, self.height)
        gl.glUniform2i(gl.glGetUniformLocation(self._program, "canvas"), *self.canvas)
        self._near = gl.glGetUniformLocation(self._program, "near")
        self._framebuffer = _framebuffer(gl, *self.canvas)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glDisable(gl.GL_MULTISAMPLE)
        gl.glDisable(gl.GL_BLEND)
        if closed:  # back faces hidden behind front ones: skipped (half the faces, a third of the time)
            gl.glEnable(gl.GL_CULL_FACE)
            gl.glFrontFace(gl.GL_CW)  # the canvas' rows grow with v (down the image): windings are mirrored
            gl.glCullFace(gl.GL_BACK)
        else:
            gl.glDisable(gl.GL_CULL_FACE)
        gl.glEnable(gl.GL_SCISSOR_TEST)  # clear only the part of the canvas in use
        gl.glScissor(0, 0, *self.used)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)


def _load_gl():
    load_pyrender()  # sets the OpenGL platform before OpenGL is imported
    from OpenGL import GL

    return GL


def _context(width: int, height: int):
    """A current off-screen OpenGL context of the configured platform (`tracker.render.gl`)."""
    import os

    from pyrender.platforms import osmesa

    if os.environ.get("PYOPENGL_PLATFORM") == "egl":
        from pyrender.platforms import egl

        platform = egl.EGLPlatform(width, height)
    else:
        platform = osmesa.OSMesaPlatform(1, 1)  # renders into its own framebuffer object
    try:
        platform.init_context()
        platform.make_current()
    except Exception as error:
        raise RenderBackendError(f"cannot open an off-screen OpenGL context: {error}") from error
    return platform


def _program(gl) -> int:
    program = gl.glCreateProgram()
    for kind, source in ((gl.GL_VERTEX_SHADER, _VERTEX_SHADER), (gl.GL_FRAGMENT_SHADER, _FRAGMENT_SHADER)):
        shader = gl.glCreateShader(kind)
        gl.glShaderSource(shader, source)
        gl.glCompileShader(shader)
        if not gl.glGetShaderiv(shader, gl.GL_COMPILE_STATUS):
            raise RenderBackendError(f"label shader: {gl.glGetShaderInfoLog(shader).decode()}")
        gl.glAttachShader(program, shader)
    gl.glLinkProgram(program)
    if not gl.glGetProgramiv(program, gl.GL_LINK_STATUS):
        raise RenderBackendError(f"label shaders: {gl.glGetProgramInfoLog(program).decode()}")
    return program


def _texture_buffer(gl, internal_format: int, unit: int, size: int, data) -> int:
    """A buffer of ``size`` bytes seen by the shaders as a texture buffer on texture ``unit``."""
    buffer = gl.glGenBuffers(1)
    gl.glBindBuffer(gl.GL_TEXTURE_BUFFER, buffer)
    gl.glBufferData(gl.GL_TEXTURE_BUFFER, size, data, gl.GL_DYNAMIC_DRAW if data is None else gl.GL_STATIC_DRAW)
    texture = gl.glGenTextures(1)
    gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
    gl.glBindTexture(gl.GL_TEXTURE_BUFFER, texture)
    gl.glTexBuffer(gl.GL_TEXTURE_BUFFER, internal_format, buffer)
    return buffer


def _framebuffer(gl, width: int, height: int) -> int:
    """A single-sampled framebuffer: one byte of colour per pixel, 24-bit depth."""
    color, depth = gl.glGenRenderbuffers(2)
    gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, color)
    gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_R8, width, height)
    gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, depth)
    gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_DEPTH_COMPONENT24, width, height)
    framebuffer = gl.glGenFramebuffers(1)
    gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, framebuffer)
    gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_RENDERBUFFER, color)
    gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_RENDERBUFFER, depth)
    if gl.glCheckFramebufferStatus(gl.GL_FRAMEBUFFER) != gl.GL_FRAMEBUFFER_COMPLETE:
        raise RenderBackendError("cannot make the label framebuffer")
    return framebuffer
