"""Headless MuJoCo rendering: choose an OpenGL backend before ``mujoco`` is imported.

MuJoCo picks its OpenGL backend once, when ``mujoco`` is first imported, from the
``MUJOCO_GL`` environment variable. :func:`configure_gl_backend` runs when
``lfd_envs.mujoco`` is imported (before this package imports ``mujoco``) and, when
``MUJOCO_GL`` is unset and there is no display, sets it to

1. ``egl`` if an EGL display can be initialised (Mesa or NVIDIA, no X server needed),
2. else ``osmesa`` if the OSMesa library is installed (software rendering),
3. else ``egl`` anyway, so that :func:`make_renderer` raises a clear ``RuntimeError``.

A user-set ``MUJOCO_GL`` is always respected. The backend is fixed when ``mujoco`` is imported
(switching afterwards fails inside MuJoCo's GL loader), so the fallback is decided by probing,
and :func:`make_renderer` turns a failure into a ``RuntimeError`` that says what to do.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from typing import Any

_HINT = ("install the EGL (e.g. libegl1) or OSMesa (e.g. libosmesa6) libraries, or set MUJOCO_GL "
         "to a working backend before importing lfd_envs")


def _egl_works() -> bool:
    """True if libEGL loads and its default display initialises (cheap; no PyOpenGL import)."""
    name = ctypes.util.find_library("EGL")
    if name is None:
        return False
    try:
        egl = ctypes.CDLL(name)
        egl.eglGetDisplay.restype = ctypes.c_void_p
        egl.eglGetDisplay.argtypes = [ctypes.c_void_p]
        egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        egl.eglTerminate.argtypes = [ctypes.c_void_p]
        display = egl.eglGetDisplay(None)
        if not display:
            return False
        ok = bool(egl.eglInitialize(display, None, None))
        if ok:
            egl.eglTerminate(display)
        return ok
    except (OSError, AttributeError):
        return False


def _osmesa_available() -> bool:
    return ctypes.util.find_library("OSMesa") is not None


def configure_gl_backend() -> str:
    """Set ``MUJOCO_GL`` for headless use if it is unset and there is no display.

    Returns the backend in effect (``""`` means MuJoCo's default, e.g. GLFW with a display).
    Has no effect on a ``mujoco`` module that is already imported.
    """
    current = os.environ.get("MUJOCO_GL")
    if current:
        return current
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return ""
    backend = "egl" if _egl_works() else ("osmesa" if _osmesa_available() else "egl")
    os.environ["MUJOCO_GL"] = backend
    return backend


def make_renderer(model: Any, height: int, width: int) -> Any:
    """A ``mujoco.Renderer`` of ``height`` × ``width`` pixels, or a clear ``RuntimeError``.

    The model's offscreen buffer is enlarged when needed.
    """
    import mujoco

    model.vis.global_.offheight = max(int(model.vis.global_.offheight), int(height))
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), int(width))
    try:
        return mujoco.Renderer(model, height=int(height), width=int(width))
    except Exception as err:  # the GL backends raise many different types
        backend = os.environ.get("MUJOCO_GL") or "<unset>"
        raise RuntimeError(
            f"MuJoCo headless rendering failed with MUJOCO_GL={backend} ({type(err).__name__}: {err}). "
            f"lfd_envs picks EGL, else OSMesa, when MUJOCO_GL is unset and there is no display, but only "
            f"if it is imported before mujoco (the backend is fixed when mujoco is imported): set "
            f"MUJOCO_GL=egl (or osmesa) in the environment or import lfd_envs first; {_HINT}. "
            "State observations (obs_mode='state') need no rendering."
        ) from err


__all__ = ["configure_gl_backend", "make_renderer"]
