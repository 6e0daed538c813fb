"""The offscreen OpenGL backend of the renders, and the errors of rendering.

`mujoco.Renderer` needs an offscreen OpenGL context. An explicit `MUJOCO_GL` is respected;
otherwise `egl` (a GPU, or Mesa's software EGL on a CPU machine) and then `osmesa` (Debian
`libosmesa6`) are each probed in a subprocess (a failed GL initialisation can poison the
process), and the first that renders is installed: `MUJOCO_GL`/`PYOPENGL_PLATFORM` are set for
child processes and, when `mujoco` was imported before the choice, its `GLContext` class is
swapped for the chosen one (the Renderer looks it up at construction). No backend →
`RenderBackendError` naming the package to install. Image sizes in pixels (width, height).
"""

from __future__ import annotations

import os
import subprocess
import sys

import mujoco

from paintcell.core.errors import PaintcellError

# Probe order when MUJOCO_GL is unset: EGL serves GPUs and Mesa's software rasterizer alike.
BACKENDS = ("egl", "osmesa")
_INSTALL_HINT = ("install libosmesa6 (apt-get install -y libosmesa6) or libegl1 "
                 "(apt-get install -y libegl1), or set MUJOCO_GL=egl|osmesa")

_backend: str | None = None


class RenderError(PaintcellError):
    """A render cannot be made (bad camera, bad sizes, bad thickness array, ...)."""


class RenderBackendError(RenderError):
    """No offscreen OpenGL backend works on this machine."""


_PROBE_CODE = (
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><light pos=\"0 0 2\"/>"
    "<geom size=\"0.1\"/></worldbody></mujoco>')\n"
    "r = mujoco.Renderer(m, 8, 8)\n"
    "d = mujoco.MjData(m)\n"
    "mujoco.mj_forward(m, d)\n"
    "r.update_scene(d)\n"
    "r.render()\n"
    "r.close()\n"
)


def probe_backend(name: str, timeout_s: float = 120.0) -> str | None:
    """Try to render an 8×8 frame with `MUJOCO_GL=name` in a subprocess.

    Returns None when it works, else the last line of the error (one line).
    """
    env = dict(os.environ, MUJOCO_GL=name, PYOPENGL_PLATFORM=name)
    try:
        res = subprocess.run([sys.executable, "-c", _PROBE_CODE], env=env, capture_output=True,
                             text=True, timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired:
        return f"probe timed out after {timeout_s:.0f} s"
    if res.returncode == 0:
        return None
    lines = [ln for ln in (res.stderr or res.stdout).strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else f"exit status {res.returncode}"


def _install_backend(name: str) -> None:
    """Make `name` the GL backend of this process (and of its children)."""
    os.environ["MUJOCO_GL"] = name
    if name in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", name)
    from mujoco.rendering.classic import gl_context as glc

    if getattr(glc, "_MUJOCO_GL", None) == name:
        return  # mujoco was imported with this backend already
    try:
        if name == "egl":
            from mujoco.egl import GLContext
        elif name == "osmesa":
            from mujoco.osmesa import GLContext
        elif name in ("glfw", "glx"):
            from mujoco.glfw import GLContext
        else:
            raise RenderBackendError(f"unknown MUJOCO_GL={name!r}: use egl or osmesa")
    except (ImportError, OSError, RuntimeError) as e:
        raise RenderBackendError(f"MUJOCO_GL={name} cannot be loaded ({one_line(e)}): "
                                 f"{_INSTALL_HINT}") from e
    glc.GLContext = GLContext  # type: ignore[attr-defined]


def backend_name() -> str:
    """Name of the offscreen GL backend in use ("egl", "osmesa", ...); chooses it on first call.

    Raises RenderBackendError (one line, naming the package to install) when none works.
    """
    global _backend
    if _backend is not None:
        return _backend
    explicit = os.environ.get("MUJOCO_GL", "").strip().lower()
    if explicit:
        _install_backend(explicit)
        _backend = explicit
        return explicit
    errors = []
    for name in BACKENDS:
        err = probe_backend(name)
        if err is None:
            _install_backend(name)
            _backend = name
            return name
        errors.append(f"{name}: {err}")
    raise RenderBackendError(f"no offscreen OpenGL backend ({'; '.join(errors)}): {_INSTALL_HINT}")


def one_line(e: BaseException) -> str:
    """The first line of an exception's message (at most 200 characters), for one-line
    errors."""
    text = str(e).strip().splitlines()
    return text[0][:200] if text else type(e).__name__


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A MuJoCo offscreen renderer of `width` × `height` pixels, or a RenderBackendError naming
    the GL backend and how to install one."""
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # any GL failure: the backend is unusable
        raise RenderBackendError(f"offscreen renderer with MUJOCO_GL={backend_name()} failed "
                                 f"({one_line(e)}): {_INSTALL_HINT}") from e
