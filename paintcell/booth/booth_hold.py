"""A booth robot's program held at its ends: delayed at home before its start (the stagger's
start delay) and held at rest after its end, so every robot's program runs on one booth clock
(`paintcell.booth.booth_programs`)."""

from __future__ import annotations

import numpy as np

from paintcell.motion.joint_trajectory import RETRACT, JointTrajectory


def held_to(traj: JointTrajectory, K: int) -> JointTrajectory:
    """`traj` held at its last sample (at rest, brush off) up to K samples."""
    n = K - len(traj.t_s)
    if n <= 0:
        return traj
    dt = traj.dt_s
    a = {name: getattr(traj, name) for name in JointTrajectory._ARRAYS}
    ext = {"t_s": traj.t_s[-1] + dt * np.arange(1, n + 1),
           "qd": np.zeros((n, a["qd"].shape[1])), "qdd": np.zeros((n, a["qdd"].shape[1])),
           "v_tcp_planned": np.zeros(n), "paint_on": np.zeros(n, bool),
           "pass_index": np.full(n, -1), "segment": np.full(n, RETRACT),
           "s_pass_m": np.full(n, np.nan), "flow": np.ones(n)}
    out = {k: np.concatenate([v, ext[k] if k in ext else np.repeat(v[-1:], n, axis=0)])
           for k, v in a.items()}
    return JointTrajectory(**out, robot_name=traj.robot_name, joint_names=traj.joint_names,
                           slowdowns=traj.slowdowns, pass_summary=traj.pass_summary,
                           meta=dict(traj.meta))


def delayed(traj: JointTrajectory, n: int) -> JointTrajectory:
    """`traj` preceded by n samples holding its first one (at rest at home, brush off)."""
    if n <= 0:
        return traj
    a = {name: getattr(traj, name) for name in JointTrajectory._ARRAYS}
    head = {"qd": np.zeros((n, a["qd"].shape[1])), "qdd": np.zeros((n, a["qdd"].shape[1])),
            "v_tcp_planned": np.zeros(n), "paint_on": np.zeros(n, bool),
            "pass_index": np.full(n, -1), "s_pass_m": np.full(n, np.nan), "flow": np.ones(n)}
    out = {k: np.concatenate([head[k] if k in head else np.repeat(v[:1], n, axis=0), v])
           for k, v in a.items() if k != "t_s"}
    out["t_s"] = traj.t_s[0] + traj.dt_s * np.arange(len(traj.t_s) + n)
    return JointTrajectory(**out, robot_name=traj.robot_name, joint_names=traj.joint_names,
                           slowdowns=traj.slowdowns, pass_summary=traj.pass_summary,
                           meta={**traj.meta, "start_delay_s": n * traj.dt_s})
