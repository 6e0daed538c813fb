"""Compiled per-step loops around MuJoCo's own C functions: the inverse-dynamics feed-forward,
the digital servo's stepping, and the kinematic replay, without a Python statement per 1 ms step.

Each loop is a `numba.njit` function that writes the step's inputs into the `MjData` arrays
(numpy views of MuJoCo's memory), calls the MuJoCo C function through `ctypes` (`mj_inverse`,
`mj_step`, `mj_fwdPosition` + `mj_sensorPos`, from the very `libmujoco` the `mujoco` bindings
loaded) and copies the outputs out. The physics is MuJoCo's, call for call what the Python loops
did; only the loop and the control law (a few multiply-adds per joint) are compiled. The
results equal those loops' (tests/test_execute_compiled.py: inverse dynamics and the kinematic
replay bit for bit, the servo's states to 1e-9 rad: its feedback product is summed in another
order than the former matrix product).

`mujoco_c()` is None when the shared library cannot be found next to the `mujoco` package or
numba is missing; the callers then run their Python loops (`PAINTCELL_COMPILED_STEPS=0` forces
that, for comparisons), and one warning line a process names why.

Joint positions [rad], velocities [rad/s], accelerations [rad/s²], torques [N·m].
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import logging
import os
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

# The film kernel's module first: it sets numba's CPU features before anything compiles, so
# every numba function of the process is compiled (and cached) for one target, whichever stage
# runs first (two targets would mean two compilations of these loops in a fresh checkout).
from paintcell.paint.deposition_jit import HAVE_NUMBA

if HAVE_NUMBA:
    from numba import njit

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MujocoC:
    """MuJoCo's C functions `f(const mjModel*, mjData*)` as ctypes objects numba can call."""

    inverse: Any
    step: Any
    fwd_position: Any
    sensor_pos: Any
    error_hook: Any = None  # ctypes c_void_p of libmujoco's `mju_user_error`, or None


def _library_path() -> str | None:
    """The libmujoco shared library the `mujoco` package ships (and its bindings loaded)."""
    here = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(here, pattern)))
        if found:
            return found[0]
    return None


@functools.lru_cache(maxsize=1)
def mujoco_c() -> MujocoC | None:
    """The C functions, or None (no library found, not the bindings' MuJoCo version, numba
    missing, or `PAINTCELL_COMPILED_STEPS=0`): callers fall back to their Python loops. The
    fallback says why, once a process (a `logging` warning of this module; at INFO level when
    `PAINTCELL_COMPILED_STEPS=0` asked for it)."""
    if os.environ.get("PAINTCELL_COMPILED_STEPS", "1") == "0":
        _say_fallback("PAINTCELL_COMPILED_STEPS=0 is set", logging.INFO)
        return None
    c, why = _load_mujoco_c()
    if c is None:
        _say_fallback(why, logging.WARNING)
    return c


#: reasons already told this process (`mujoco_c`'s cache is cleared by benchmarks and tests).
_told: set[str] = set()


def _say_fallback(why: str, level: int) -> None:
    if why in _told:
        return
    _told.add(why)
    _log.log(level, "paintcell: warning: the compiled MuJoCo step loops are not used (%s); "
             "execution runs them as Python loops: the same physics, ~1.3x slower, results "
             "equal to ~1e-15 rad", why)


def _load_mujoco_c() -> tuple[MujocoC | None, str]:
    """(the C functions, "") or (None, why they cannot be used)."""
    if not HAVE_NUMBA:
        return None, "numba is not installed"
    path = _library_path()
    if path is None:
        return None, (f"no libmujoco shared library next to the mujoco package in "
                      f"{os.path.dirname(mujoco.__file__)}")
    if not (hasattr(mujoco.MjModel, "_address") and hasattr(mujoco.MjData, "_address")):
        # bindings that no longer expose the struct addresses: the Python loops
        return None, (f"the mujoco {mujoco.__version__} bindings do not expose the MjModel/"
                      "MjData addresses")
    try:
        lib = ctypes.CDLL(path)
        # a library of another version than the bindings' would read their structs with another
        # layout: only the very build they loaded is used
        lib.mj_versionString.restype = ctypes.c_char_p
        lib.mj_versionString.argtypes = []
        found = lib.mj_versionString().decode()
        if found != mujoco.mj_versionString():
            return None, (f"{path} is MuJoCo {found}, the bindings are "
                          f"{mujoco.mj_versionString()}")
        fns = []
        for name in ("mj_inverse", "mj_step", "mj_fwdPosition", "mj_sensorPos"):
            f = getattr(lib, name)
            f.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
            f.restype = None
            fns.append(f)
        hook = ctypes.c_void_p.in_dll(lib, "mju_user_error")
    except (OSError, AttributeError, ValueError) as exc:  # another build: the Python loops
        return None, f"{path} cannot be used: {' '.join(str(exc).split())}"
    inverse, step, fwd_position, sensor_pos = fns
    return MujocoC(inverse, step, fwd_position, sensor_pos, error_hook=hook), ""


# Exit code of a MuJoCo fatal error inside a compiled loop: the CLI's code for an internal error
# (paintcell.cli.common.EXIT_USAGE; not imported: the app stage sits above this one).
FATAL_EXIT_CODE = 2


def _on_mujoco_error(msg: bytes) -> None:
    # MuJoCo's error handler must not return (the engine's state is undefined after it), and a
    # Python exception cannot unwind through the compiled loop: one paintcell line, then exit.
    # The results folder is safe: a run builds in a hidden temporary folder that the next writer
    # removes (paintcell.core.results_dir), and the lock is released with the process.
    text = " ".join(msg.decode(errors="replace").split()) if msg else "unknown error"
    sys.stderr.write(f"paintcell: internal error: MuJoCo stopped the simulation: {text} "
                     "(rerun with PAINTCELL_COMPILED_STEPS=0 --debug for a Python traceback)\n")
    sys.stderr.flush()
    os._exit(FATAL_EXIT_CODE)


_ERROR_CB = ctypes.CFUNCTYPE(None, ctypes.c_char_p)(_on_mujoco_error)
_hook_lock = threading.Lock()
_hook_users = 0


@contextlib.contextmanager
def _fatal_errors_exit(c: MujocoC) -> Iterator[None]:
    """While a compiled loop runs, MuJoCo's fatal errors (e.g. its arena full of contacts) end
    the process with one paintcell line and exit code 2, instead of MuJoCo's default handler's
    `ERROR:` on stdout, a MUJOCO_LOG.TXT in the working folder and exit code 1 (which the CLI
    documents as "a threshold was not met"). Outside the loops the bindings' own handling (a
    `mujoco.FatalError`) is left as it is."""
    global _hook_users
    if c.error_hook is None:
        yield
        return
    with _hook_lock:
        if _hook_users == 0:
            c.error_hook.value = ctypes.cast(_ERROR_CB, ctypes.c_void_p).value
        _hook_users += 1
    try:
        yield
    finally:
        with _hook_lock:
            _hook_users -= 1
            if _hook_users == 0:
                c.error_hook.value = None


if HAVE_NUMBA:
    @njit(cache=True, nogil=True)
    def _inverse_loop(inv: Any, mptr: int, dptr: int, qpos: np.ndarray, qvel: np.ndarray,
                      qacc: np.ndarray, qfrc: np.ndarray, qa: np.ndarray, da: np.ndarray,
                      q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, out: np.ndarray) -> None:
        n = qa.shape[0]
        for k in range(q.shape[0]):
            for j in range(n):
                qpos[qa[j]] = q[k, j]
                qvel[da[j]] = qd[k, j]
                qacc[da[j]] = qdd[k, j]
            inv(mptr, dptr)
            for j in range(n):
                out[k, j] = qfrc[da[j]]

    @njit(cache=True, nogil=True)
    def _kinematic_loop(fwd: Any, sens: Any, mptr: int, dptr: int, qpos: np.ndarray,
                        qvel: np.ndarray, sdata: np.ndarray, qa: np.ndarray, da: np.ndarray,
                        q: np.ndarray, qd: np.ndarray, k0: int, k1: int,
                        sens_out: np.ndarray) -> None:
        n = qa.shape[0]
        for k in range(k0, k1):
            for j in range(n):
                qpos[qa[j]] = q[k, j]
                qvel[da[j]] = qd[k, j]
            fwd(mptr, dptr)
            sens(mptr, dptr)
            sens_out[k, :] = sdata

    @njit(cache=True, nogil=True)
    def _servo_loop(step: Any, mptr: int, dptr: int, qpos: np.ndarray, qvel: np.ndarray,
                    ctrl: np.ndarray, sdata: np.ndarray, qa: np.ndarray, da: np.ndarray,
                    act: np.ndarray, base: np.ndarray, kpg: np.ndarray, kdg: np.ndarray,
                    lag: int, k0: int, k1: int, q_meas: np.ndarray, qd_meas: np.ndarray,
                    sens_out: np.ndarray, ctrl_out: np.ndarray) -> None:
        n = qa.shape[0]
        for k in range(k0, k1):
            j = k - lag
            if j < 0:
                j = 0  # before t0 the arm rests in its initial state
            for c in range(ctrl.shape[0]):
                ctrl_out[k, c] = base[k, c]
            for i in range(n):
                ctrl_out[k, act[i]] = base[k, act[i]] - (q_meas[j, i] * kpg[i]
                                                         + qd_meas[j, i] * kdg[i])
            ctrl[:] = ctrl_out[k]
            step(mptr, dptr)
            sens_out[k, :] = sdata  # sensors of the state at t_k (evaluated before integrating)
            for i in range(n):
                q_meas[k + 1, i] = qpos[qa[i]]
                qd_meas[k + 1, i] = qvel[da[i]]


def _idx(a: Any) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, np.int64).ravel())


def inverse_dynamics_steps(c: MujocoC, model: mujoco.MjModel, data: mujoco.MjData,
                           qpos_adr: Any, dof_adr: Any, q: np.ndarray, qd: np.ndarray,
                           qdd: np.ndarray) -> np.ndarray:
    """(K, n) `qfrc_inverse` [N·m] at the dofs `dof_adr` after `mj_inverse` of each sample
    (q, q̇, q̈) (K, n) written at `qpos_adr` / `dof_adr` of `data` (other entries as they are)."""
    out = np.empty((len(q), len(_idx(dof_adr))))
    with _fatal_errors_exit(c):
        _inverse_loop(c.inverse, model._address, data._address, data.qpos, data.qvel, data.qacc,
                      data.qfrc_inverse, _idx(qpos_adr), _idx(dof_adr),
                      np.ascontiguousarray(q, float), np.ascontiguousarray(qd, float),
                      np.ascontiguousarray(qdd, float), out)
    return out


def kinematic_steps(c: MujocoC, model: mujoco.MjModel, data: mujoco.MjData, qpos_adr: Any,
                    dof_adr: Any, q: np.ndarray, qd: np.ndarray, k0: int, k1: int,
                    sens_out: np.ndarray) -> None:
    """Samples k0 ≤ k < k1: set (q, q̇)[k], `mj_fwdPosition` + `mj_sensorPos`, sensordata into
    `sens_out[k]` ((K, nsensordata), written in place)."""
    with _fatal_errors_exit(c):
        _kinematic_loop(c.fwd_position, c.sensor_pos, model._address, data._address, data.qpos,
                        data.qvel, data.sensordata, _idx(qpos_adr), _idx(dof_adr), q, qd, int(k0),
                        int(k1), sens_out)


def servo_steps(c: MujocoC, model: mujoco.MjModel, data: mujoco.MjData, qpos_adr: Any,
                dof_adr: Any, actuator_ids: Any, base: np.ndarray, kp_g: np.ndarray,
                kd_g: np.ndarray, lag: int, k0: int, k1: int, q_meas: np.ndarray,
                qd_meas: np.ndarray, sens_out: np.ndarray, ctrl_out: np.ndarray) -> None:
    """Steps k0 ≤ k < k1 of the digital servo (`paintcell.execution.execute`):
    ctrl[k] = base[k] − (Kp/g · q + Kd/g · q̇) measured at t_{max(k − lag, 0)}, on the robot's
    actuators (base[k] alone on the others), then `mj_step`.

    base, ctrl_out: (N, nu) [actuator units]; kp_g, kd_g: (n,) gains ÷ gear; q_meas, qd_meas:
    (N + 1, n), row 0 the initial state, rows k + 1 written here (the state after step k);
    sens_out: (N, nsensordata), the sensors of the state at t_k. All written in place."""
    with _fatal_errors_exit(c):
        _servo_loop(c.step, model._address, data._address, data.qpos, data.qvel, data.ctrl,
                    data.sensordata, _idx(qpos_adr), _idx(dof_adr), _idx(actuator_ids), base,
                    np.ascontiguousarray(kp_g, float), np.ascontiguousarray(kd_g, float), int(lag),
                    int(k0), int(k1), q_meas, qd_meas, sens_out, ctrl_out)
