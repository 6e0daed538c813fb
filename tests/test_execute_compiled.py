"""paintcell.execution.execute_compiled: the compiled per-step loops give what the per-sample
Python computations gave, on the real two-pass program of tests/test_execute.py (3.7 s at 1 kHz).

- Inverse dynamics (the servo's feed-forward, and the kinematic replay's torque): equal bit for bit
  to a per-sample `mujoco.mj_inverse` loop written here.
- Kinematic replay: sensors (TCP pose, contacts) bit for bit equal to the Python loop.
- Servo: states, applied and demanded torques, torque utilization (max |τ_demand| / τ_max, what
  `validate` reports) and the contacts of a collision equal to the former `mujoco.rollout` path
  (`PAINTCELL_COMPILED_STEPS=0`) within 1e-9 rad / 1e-9 of τ_max: the compiled feedback sums
  Kp·q + Kd·q̇ in another order than that path's matrix product.
"""

from __future__ import annotations

import copy
import os
import sys

import mujoco
import numpy as np
import pytest

import paintcell.execution.execute as execute_module
from paintcell.execution import execute_compiled
from paintcell.execution.execute import (
    ServoSettings,
    controller_model,
    execute,
    inverse_dynamics,
    set_torque_actuators,
)
from paintcell.execution.trace import ExecutedTrace
from tests.test_execute import make_case, make_cell

# The Linux wheels of mujoco ship libmujoco.so next to the package: there the loops must be
# found (else every comparison below would compare the Python path with itself and pass).
pytestmark = pytest.mark.skipif(
    execute_compiled.mujoco_c() is None
    and (not sys.platform.startswith("linux")
         or os.environ.get("PAINTCELL_COMPILED_STEPS") == "0"),
    reason="libmujoco not found next to the mujoco package, or PAINTCELL_COMPILED_STEPS=0")


def test_the_compiled_loops_are_in_use() -> None:
    c = execute_compiled.mujoco_c()
    assert c is not None, ("libmujoco of the bindings' version not found next to the mujoco "
                           "package: the execution silently runs the Python loops")


def _python_inverse(model: mujoco.MjModel, cell: object, q: np.ndarray, qd: np.ndarray,
                    qdd: np.ndarray) -> np.ndarray:
    """The per-sample computation the compiled loop replaces (as `inverse_dynamics` set it up)."""
    m = copy.copy(model)
    m.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
                           | mujoco.mjtDisableBit.mjDSBL_CONTACT
                           | mujoco.mjtDisableBit.mjDSBL_SENSOR)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_INVDISCRETE
    d = mujoco.MjData(m)
    out = np.empty_like(q)
    for k in range(len(q)):
        d.qpos[cell.qpos_adr] = q[k]  # type: ignore[attr-defined]
        d.qvel[cell.dof_adr] = qd[k]  # type: ignore[attr-defined]
        d.qacc[cell.dof_adr] = qdd[k]  # type: ignore[attr-defined]
        mujoco.mj_inverse(m, d)
        out[k] = d.qfrc_inverse[cell.dof_adr]  # type: ignore[attr-defined]
    return out


def _without_compiled(monkeypatch: pytest.MonkeyPatch, fn: object) -> ExecutedTrace:
    monkeypatch.setenv("PAINTCELL_COMPILED_STEPS", "0")
    execute_compiled.mujoco_c.cache_clear()
    try:
        assert execute_compiled.mujoco_c() is None
        return fn()  # type: ignore[operator,no-any-return]
    finally:
        monkeypatch.delenv("PAINTCELL_COMPILED_STEPS")
        execute_compiled.mujoco_c.cache_clear()


def test_inverse_dynamics_equals_the_per_sample_mj_inverse_loop(
        monkeypatch: pytest.MonkeyPatch) -> None:
    case, cell = make_case(), make_cell()
    traj = case.traj
    model = copy.copy(cell.model)
    set_torque_actuators(model, cell)
    ctrl_model = controller_model(model, cell, ServoSettings())
    # long enough for the two-thread split (execute._inverse_compiled), which runs on
    # any machine with two cores
    assert len(traj.q) >= execute_module.SPLIT_MIN_SAMPLES
    monkeypatch.setattr(execute_module, "_cores", lambda: 2)
    got = inverse_dynamics(ctrl_model, cell, traj.q, traj.qd, traj.qdd)
    ref = _python_inverse(ctrl_model, cell, traj.q, traj.qd, traj.qdd)
    assert np.abs(ref).max() > 1.0  # real torques (gravity alone is tens of N·m)
    np.testing.assert_array_equal(got, ref)


def test_kinematic_replay_equals_the_python_loop(monkeypatch: pytest.MonkeyPatch) -> None:
    case, cell = make_case(), make_cell()
    new = execute(cell, case.traj, mode="kinematic")
    old = _without_compiled(monkeypatch, lambda: execute(cell, case.traj, mode="kinematic"))
    for f in ("q", "qd", "tau", "tau_demand", "tcp_pos_world", "tcp_rot_world"):
        np.testing.assert_array_equal(getattr(new, f), getattr(old, f), err_msg=f)


@pytest.mark.parametrize("part_shift_m", [0.0, 0.3])
def test_servo_equals_the_rollout_path(monkeypatch: pytest.MonkeyPatch,
                                       part_shift_m: float) -> None:
    """Nominal program, and the part pushed 0.3 m into the bell's path (a collision that pushes
    the arm back: contacts feed the dynamics)."""
    case, cell = make_case(part_shift_m), make_cell(part_shift_m)
    new = execute(cell, case.traj)
    old = _without_compiled(monkeypatch, lambda: execute(cell, case.traj))
    tau_max = cell.tau_max
    assert new.tau_demand is not None and old.tau_demand is not None
    assert np.abs(new.q - old.q).max() <= 1e-9
    assert np.abs(new.qd - old.qd).max() <= 1e-7
    assert np.all(np.abs(new.tau_demand - old.tau_demand) <= 1e-9 * tau_max)
    assert np.all(np.abs(new.tau - old.tau) <= 1e-9 * tau_max)
    assert np.abs(new.tcp_pos_world - old.tcp_pos_world).max() <= 1e-9
    use_new = np.max(np.abs(new.tau_demand) / tau_max)
    use_old = np.max(np.abs(old.tau_demand) / tau_max)
    assert use_new == pytest.approx(use_old, abs=1e-9)
    assert use_new > 0.01
    assert new.meta["settle_time_s"] == old.meta["settle_time_s"]
    assert new.meta["mujoco_warnings"] == old.meta["mujoco_warnings"]
    assert [(c.body1, c.body2, round(c.time_s, 6)) for c in new.contacts] == \
        [(c.body1, c.body2, round(c.time_s, 6)) for c in old.contacts]
    assert (len(new.contacts) > 0) == (part_shift_m > 0)
    for a, b in zip(new.contacts, old.contacts, strict=True):
        assert a.depth_m == pytest.approx(b.depth_m, abs=1e-9)


_OVERFLOW = r'''
import sys
import mujoco
import numpy as np
from paintcell.execution.execute_compiled import inverse_dynamics_steps, mujoco_c

spheres = "".join(f'<geom type="sphere" size="0.05" pos="{0.01 * i} 0 0"/>' for i in range(40))
boxes = spheres.replace('type="sphere" size="0.05"', 'type="box" size="0.05 0.05 0.05"')
xml = ('<mujoco><size memory="60K"/><worldbody>' + boxes + '<body><joint type="slide"/>'
       + spheres + '</body></worldbody></mujoco>')
m = mujoco.MjModel.from_xml_string(xml)
d = mujoco.MjData(m)
q = np.zeros((3, 1))
inverse_dynamics_steps(mujoco_c(), m, d, [0], [0], q, q, q)
print("returned")
'''


def test_a_mujoco_fatal_error_in_a_compiled_loop_is_one_paintcell_line_and_exit_2(
        tmp_path: os.PathLike) -> None:
    """40 overlapping sphere/box pairs need more than the 60 KB arena: MuJoCo's narrow phase hits
    its fatal 'stack overflow' inside the compiled loop. Without the hook MuJoCo's default handler
    prints ERROR on stdout, writes MUJOCO_LOG.TXT into the working folder and exits 1 — the CLI's
    code for "a threshold was not met"."""
    import subprocess

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.getcwd(), *sys.path]))
    r = subprocess.run([sys.executable, "-c", _OVERFLOW], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == execute_compiled.FATAL_EXIT_CODE == 2, (r.returncode, r.stderr)
    assert "returned" not in r.stdout and "ERROR" not in r.stdout
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "paintcell: internal error: MuJoCo stopped the simulation: mj_stackAlloc"), r.stderr
    assert "increase <size memory" in lines[0]  # MuJoCo's own fix for the user stays in the line
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()  # type: ignore[operator]


def test_the_fallback_to_the_python_loops_says_why_once(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture,
        tmp_path: os.PathLike) -> None:
    """A libmujoco that cannot be loaded (here a file that is no shared library), or none found:
    the Python loops run and one warning names why, once a process; a forced fallback
    (PAINTCELL_COMPILED_STEPS=0) is not a warning."""
    import logging

    fake = os.path.join(tmp_path, "libmujoco.so.9")
    with open(fake, "w") as f:
        f.write("not a library")
    monkeypatch.setattr(execute_compiled, "_told", set())
    caplog.set_level(logging.INFO, logger=execute_compiled.__name__)

    def warnings() -> list[str]:
        return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]

    try:
        monkeypatch.setattr(execute_compiled, "_library_path", lambda: fake)
        for _ in range(3):
            execute_compiled.mujoco_c.cache_clear()
            assert execute_compiled.mujoco_c() is None
        assert len(warnings()) == 1
        assert warnings()[0].startswith("paintcell: warning: the compiled MuJoCo step loops are "
                                        f"not used ({fake} cannot be used: ")
        monkeypatch.setattr(execute_compiled, "_library_path", lambda: None)
        execute_compiled.mujoco_c.cache_clear()
        assert execute_compiled.mujoco_c() is None
        assert len(warnings()) == 2 and "no libmujoco shared library next to the mujoco " \
            "package in " + os.path.dirname(mujoco.__file__) in warnings()[1]
        monkeypatch.setenv("PAINTCELL_COMPILED_STEPS", "0")
        execute_compiled.mujoco_c.cache_clear()
        assert execute_compiled.mujoco_c() is None
        assert len(warnings()) == 2
        assert "PAINTCELL_COMPILED_STEPS=0" in caplog.records[-1].getMessage()
    finally:
        monkeypatch.undo()
        execute_compiled.mujoco_c.cache_clear()
    assert execute_compiled.mujoco_c() is not None  # the real library again
