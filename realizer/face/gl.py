"""Offscreen OpenGL 3.3 core contexts: OSMesa (CPU) or EGL (GPU), no window.

The realizer's renderer (:mod:`realizer.face.render`) draws into its own
framebuffer objects, so a context here only has to exist and be made
current; the window-system buffer it gets is a few pixels.

PyOpenGL chooses its back end from ``PYOPENGL_PLATFORM`` when OpenGL is first
imported (:func:`realizer.face.render.choose_platform` sets it). OSMesa is
Mesa's software rasteriser (llvmpipe, the Debian package libosmesa6): no
display and no GPU needed. EGL uses the GPU driver's headless path.

This module imports OpenGL only inside the functions that make a context.
"""

from __future__ import annotations

import ctypes
from abc import ABC, abstractmethod
from typing import Any

from realizer.errors import RealizerError

__all__ = ["GLContext", "GLContextError", "make_context"]


class GLContextError(RealizerError):
    """No OpenGL 3.3 core context can be made with this back end."""


class GLContext(ABC):
    """A current-able OpenGL context. :meth:`make_current` before any GL call."""

    @abstractmethod
    def make_current(self) -> None:
        """Make this context current on the calling thread."""

    @abstractmethod
    def release(self) -> None:
        """Free the context and its buffers."""


class _OSMesaContext(GLContext):
    #: The window-system buffer: never drawn into (we render to FBOs).
    SIZE = 4

    def __init__(self) -> None:
        from OpenGL import GL, osmesa

        attributes = [
            osmesa.OSMESA_FORMAT, osmesa.OSMESA_RGBA,
            osmesa.OSMESA_DEPTH_BITS, 0,
            osmesa.OSMESA_PROFILE, osmesa.OSMESA_CORE_PROFILE,
            osmesa.OSMESA_CONTEXT_MAJOR_VERSION, 3,
            osmesa.OSMESA_CONTEXT_MINOR_VERSION, 3,
            0,
        ]  # fmt: skip
        array = (ctypes.c_int * len(attributes))(*attributes)
        self._osmesa = osmesa
        self._gl = GL
        self._context: Any = osmesa.OSMesaCreateContextAttribs(array, None)
        if not self._context:
            raise GLContextError("OSMesaCreateContextAttribs failed (no OpenGL 3.3 core)")
        self._buffer = (GL.GLubyte * (4 * self.SIZE * self.SIZE))()

    def make_current(self) -> None:
        ok = self._osmesa.OSMesaMakeCurrent(
            self._context, self._buffer, self._gl.GL_UNSIGNED_BYTE, self.SIZE, self.SIZE
        )
        if not ok:
            raise GLContextError("OSMesaMakeCurrent failed")

    def release(self) -> None:
        if self._context is not None:
            self._osmesa.OSMesaDestroyContext(self._context)
            self._context = None


class _EGLContext(GLContext):
    def __init__(self) -> None:
        from OpenGL import EGL

        self._egl = EGL
        display = EGL.eglGetDisplay(EGL.EGL_DEFAULT_DISPLAY)
        major, minor = EGL.EGLint(), EGL.EGLint()
        if not display or not EGL.eglInitialize(
            display, ctypes.pointer(major), ctypes.pointer(minor)
        ):
            raise GLContextError("eglInitialize failed")
        config_attributes = [
            EGL.EGL_SURFACE_TYPE, EGL.EGL_PBUFFER_BIT,
            EGL.EGL_RENDERABLE_TYPE, EGL.EGL_OPENGL_BIT,
            EGL.EGL_RED_SIZE, 8, EGL.EGL_GREEN_SIZE, 8, EGL.EGL_BLUE_SIZE, 8,
            EGL.EGL_NONE,
        ]  # fmt: skip
        config = EGL.EGLConfig()
        count = EGL.EGLint()
        ok = EGL.eglChooseConfig(
            display,
            (EGL.EGLint * len(config_attributes))(*config_attributes),
            ctypes.pointer(config),
            1,
            ctypes.pointer(count),
        )
        if not ok or count.value < 1:
            raise GLContextError("eglChooseConfig found no pbuffer configuration")
        surface_attributes = [EGL.EGL_WIDTH, 4, EGL.EGL_HEIGHT, 4, EGL.EGL_NONE]
        surface = EGL.eglCreatePbufferSurface(
            display, config, (EGL.EGLint * len(surface_attributes))(*surface_attributes)
        )
        if not EGL.eglBindAPI(EGL.EGL_OPENGL_API):
            raise GLContextError("eglBindAPI(EGL_OPENGL_API) failed")
        context_attributes = [
            EGL.EGL_CONTEXT_MAJOR_VERSION, 3,
            EGL.EGL_CONTEXT_MINOR_VERSION, 3,
            EGL.EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL.EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
            EGL.EGL_NONE,
        ]  # fmt: skip
        context = EGL.eglCreateContext(
            display,
            config,
            EGL.EGL_NO_CONTEXT,
            (EGL.EGLint * len(context_attributes))(*context_attributes),
        )
        if not context:
            raise GLContextError("eglCreateContext failed (no OpenGL 3.3 core)")
        self._display, self._surface, self._context = display, surface, context

    def make_current(self) -> None:
        if not self._egl.eglMakeCurrent(self._display, self._surface, self._surface, self._context):
            raise GLContextError("eglMakeCurrent failed")

    def release(self) -> None:
        if self._context is not None:
            egl = self._egl
            egl.eglMakeCurrent(
                self._display, egl.EGL_NO_SURFACE, egl.EGL_NO_SURFACE, egl.EGL_NO_CONTEXT
            )
            egl.eglDestroyContext(self._display, self._context)
            if self._surface:
                egl.eglDestroySurface(self._display, self._surface)
            self._context = None


def make_context(platform: str) -> GLContext:
    """An OpenGL 3.3 core context for PyOpenGL's ``platform`` ("osmesa" or "egl").

    Raises :class:`GLContextError` (or the back end's own error, which the
    renderer wraps) when none can be made.
    """
    if platform == "osmesa":
        return _OSMesaContext()
    if platform == "egl":
        return _EGLContext()
    raise GLContextError(f"PYOPENGL_PLATFORM={platform!r}: use 'osmesa' or 'egl' offscreen")
