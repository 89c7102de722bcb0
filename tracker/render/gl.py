"""The one place that chooses the OpenGL platform and imports pyrender.

PyOpenGL picks its platform when first imported, so ``PYOPENGL_PLATFORM`` must be set before any import of
``OpenGL`` or ``pyrender``. We default it to ``osmesa`` (software off-screen rendering: no display, no GPU); a
user who exports another value (e.g. ``egl`` on a GPU machine) keeps it.
"""

from __future__ import annotations

import logging
import os
import sys
from types import ModuleType

PLATFORM_VARIABLE = "PYOPENGL_PLATFORM"
DEFAULT_PLATFORM = "osmesa"
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
    logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)  # "no OpenGL_accelerate" is expected
    try:
        import pyrender
    except Exception as error:  # PyOpenGL raises assorted errors when the platform library is missing
        fix = OSMESA_FIX if platform == "osmesa" else f"check the OpenGL platform {platform!r}"
        raise RenderBackendError(f"cannot load pyrender with {PLATFORM_VARIABLE}={platform}: {error}; {fix}") from error
    if platform == "osmesa":
        _use_stable_osmesa_context_ids()
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
