"""The one place that chooses the OpenGL platform and imports pyrender.

PyOpenGL picks its platform when first imported, so ``PYOPENGL_PLATFORM`` must be set before any import of
``OpenGL`` or ``pyrender``. We default it to ``osmesa`` (software off-screen rendering: no display, no GPU); a
user who exports another value (e.g. ``egl`` on a GPU machine) keeps it.

On OSMesa we also default ``LP_NUM_THREADS`` to 0 (Mesa reads it once, when it makes its first context): llvmpipe
then rasterises in the thread that draws, not on threads of its own (one per core). Our draws are small
(a few meshes at 320x240 or 640x480) and come one at a time between the tracker's own work: handing each to
rasterising threads and waiting for them costs more than they share (a tracker's z-buffer pass takes longer with
them, the lit pass no less), and those threads take turns on the cores with the tracker's own worker.
The pixels are the same: each tile is rasterised the same way by whichever thread. A user's own value is kept.
"""

from __future__ import annotations

import logging
import os
import sys
from types import ModuleType

import numpy as np

PLATFORM_VARIABLE = "PYOPENGL_PLATFORM"
DEFAULT_PLATFORM = "osmesa"
RASTERISER_THREADS_VARIABLE = "LP_NUM_THREADS"  # llvmpipe's rasterising threads beside the drawing one
OSMESA_FIX = "install Debian's libosmesa6 (`sudo apt-get install libosmesa6`, or run `make setup`)"


class RenderBackendError(RuntimeError):
    """Off-screen OpenGL could not be started."""


def load_pyrender() -> ModuleType:
    """Import pyrender on the configured platform, or raise `RenderBackendError` saying how to fix it."""
    if PLATFORM_VARIABLE not in os.environ and "OpenGL" in sys.modules:
        raise RenderBackendError(
            f"OpenGL was imported before {PLATFORM_VARIABLE} was set, so it chose another platform; "
            "load tracker.render before anything that imports OpenGL, or export PYOPENGL_PLATFORM=osmesa"
        )
    platform = os.environ.setdefault(PLATFORM_VARIABLE, DEFAULT_PLATFORM)
    if platform == "osmesa":
        os.environ.setdefault(RASTERISER_THREADS_VARIABLE, "0")  # before Mesa's first context reads it
    logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)  # "no OpenGL_accelerate" is expected
    try:
        import pyrender
    except Exception as error:  # PyOpenGL raises assorted errors when the platform library is missing
        fix = OSMESA_FIX if platform == "osmesa" else f"check the OpenGL platform {platform!r}"
        raise RenderBackendError(f"cannot load pyrender with {PLATFORM_VARIABLE}={platform}: {error}; {fix}") from error
    if platform == "osmesa":
        _use_stable_osmesa_context_ids()
    _set_only_changed_uniforms()
    return pyrender


def _use_stable_osmesa_context_ids() -> None:
    """Make PyOpenGL identify the current OSMesa context by its address.

    PyOpenGL's OSMesa platform returns the current context as a new ctypes pointer object on every call, and such
    objects hash by identity. pyrender keys its shader-program cache on that value (as does PyOpenGL's per-context
    storage), so every render pass missed the cache, compiled fresh programs and never freed them: about 10 MB and
    several milliseconds per pass. An integer address is the same key for the same context every time.
    """
    import ctypes

    import OpenGL.platform as gl_platform

    if getattr(gl_platform.GetCurrentContext, "stable_ids", False):
        return
    current_context = gl_platform.PLATFORM.GetCurrentContext

    def current_context_address() -> int | None:
        pointer = current_context()
        return ctypes.cast(pointer, ctypes.c_void_p).value if pointer else None

    current_context_address.stable_ids = True
    gl_platform.GetCurrentContext = current_context_address


_UNIFORM_SETTER_INSTALLED = False


def _set_only_changed_uniforms() -> None:
    """Make pyrender set a shader program's uniform only when its value changes.

    pyrender sets every uniform of every mesh node it draws, by name (a location lookup each time): the same camera,
    lights and material factors again for each of a textured body's 15 parts, about 20 uniforms a part. A program
    keeps its uniforms' values (OpenGL program state), so setting the value it holds changes nothing: the same
    images, to the bit, in less time. The values are remembered per program object and dropped when pyrender
    deletes its program, so a program made anew is set in full; pyrender's own setter stays reachable as
    ``ShaderProgram.set_uniform.pyrender_set_uniform``.
    """
    from pyrender.shader_program import ShaderProgram

    global _UNIFORM_SETTER_INSTALLED
    if _UNIFORM_SETTER_INSTALLED:  # once per process: a test may put pyrender's own setter back
        return
    _UNIFORM_SETTER_INSTALLED = True
    set_uniform, remove_from_context = ShaderProgram.set_uniform, ShaderProgram._remove_from_context

    def set_changed_uniform(program: ShaderProgram, name: str, value, unsigned: bool = False) -> None:
        held = program.__dict__.setdefault("_held_uniforms", {})
        key = None  # a value of another kind (a list, which its owner may change in place): set every time
        if isinstance(value, (np.ndarray, np.generic, bool, int, float)):  # by its bytes: -0.0 is not 0.0
            array = np.asarray(value)
            key = (type(value), array.dtype.str, array.shape, array.tobytes(), unsigned)
        if key is None or held.get(name) != key:
            set_uniform(program, name, value, unsigned)
            held[name] = key

    def remove_and_forget(program: ShaderProgram) -> None:
        program.__dict__.pop("_held_uniforms", None)
        remove_from_context(program)

    set_changed_uniform.pyrender_set_uniform = set_uniform
    ShaderProgram.set_uniform = set_changed_uniform
    ShaderProgram._remove_from_context = remove_and_forget
