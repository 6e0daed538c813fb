"""The range of every numeric scenario setting, checked when a scenario or booth is loaded.

The settings classes refuse values that make no sense (a negative spacing); these ranges also
refuse values that make sense on paper but multiply time or memory past any machine (a 10 µm
profile spacing, 10⁶ band curves, a 1000 km overspray, a one-hour jerk ramp), so such a typo
is answered at load in one line naming the file, the table, the key and the valid range, not
by an out-of-memory or a library's raw error minutes later. Each bound is one to two orders of
magnitude beyond what any shipped scenario, test or benchmark uses; the combined costs
(grids × footprints, widths tried) are budgeted in `paintcell.core.budget`.

`(table, key) → (low, high, what)`: inclusive bounds in the key's unit; +inf as high means
unbounded above (still finite unless `INF_ALLOWED` names the key).
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["INF_ALLOWED", "RANGES", "check_range"]

_INF = math.inf

RANGES: dict[tuple[str, str], tuple[float, float, str]] = {
    # PlannerSettings (`paintcell.coverage.coverage_settings`)
    ("planner", "u_max"): (1e-6, 0.999, "a fraction, 0.04 = 4 %"),
    ("planner", "overspray_m"): (0.0, 2.0, "m past the part's edge"),
    ("planner", "v_nominal_m_s"): (0.01, 5.0, "m/s"),
    ("planner", "v_min_m_s"): (0.01, 5.0, "m/s"),
    ("planner", "v_max_m_s"): (0.01, 5.0, "m/s"),
    ("planner", "a_max_m_s2"): (0.01, 200.0, "m/s²"),
    ("planner", "n_knots"): (2, 200, "speed knots per pass"),
    ("planner", "w_min_m"): (0.01, 3.0, "m (a pass per w: a 1 mm width is 1000 passes a metre)"),
    ("planner", "w_max_m"): (0.01, 3.0, "m"),
    ("planner", "w_res_m"): (0.0005, 1.0, "m"),
    ("planner", "width_tolerance_m"): (0.0, 1.0, "m"),
    ("planner", "n_future"): (1, 8, "future passes"),
    ("planner", "future_grid_n"): (1, 50, "widths per future pass"),
    ("planner", "width_change_weight"): (0.0, 1e3, "a weight"),
    ("planner", "sample_spacing_m"): (0.001, 0.5, "m"),
    ("planner", "band_curves"): (1, 51, "odd count of sub-offset curves"),
    ("planner", "band_half_width"): (1e-6, 10.0, "a fraction of the index width"),
    ("planner", "marker_turn_rad"): (1e-3, 2 * math.pi, "rad"),
    ("planner", "marker_spacing_m"): (0.005, 100.0, "m"),
    ("planner", "max_markers"): (1, 100, "markers per pass"),
    ("planner", "profile_spacing_m"): (0.0005, 0.2, "m"),
    ("planner", "film_guard_band_m"): (0.0, 2.0, "m"),
    ("planner", "max_passes"): (1, 5000, "passes"),
    ("planner", "max_opening_fraction"): (1e-6, 1.0, "a fraction"),
    ("planner", "max_axis_turn_rad_m"): (1e-3, _INF, "rad/m (inf: no bound)"),
    ("planner", "smoothing_m"): (0.0, 1.0, "m"),
    ("planner", "start_position"): (0.0, 1.0, "a fraction of the altitude"),
    # TrajectorySettings (`paintcell.motion.trajectory`)
    ("trajectory", "control_rate_hz"): (50.0, 10000.0, "Hz"),
    ("trajectory", "tcp_a_max_m_s2"): (0.01, 500.0, "m/s²"),
    ("trajectory", "velocity_margin"): (0.01, 1.0, "a fraction"),
    ("trajectory", "acceleration_margin"): (0.01, 1.0, "a fraction"),
    ("trajectory", "jerk_ramp_s"): (0.001, 2.0, "s"),
    ("trajectory", "approach_clearance_m"): (0.0, 2.0, "m"),
    ("trajectory", "retract_clearance_m"): (0.0, 2.0, "m"),
    ("trajectory", "turnaround_max_dip_m"): (0.0, _INF, "m (inf: always direct)"),
    ("trajectory", "turnaround_clearance_m"): (1e-4, 2.0, "m"),
    ("trajectory", "grid_spacing_m"): (0.0005, 0.5, "m"),
    ("trajectory", "path_tolerance_m"): (1e-6, 0.05, "m"),
    ("trajectory", "slowdown_threshold"): (1e-6, 0.999, "a fraction"),
    ("trajectory", "flow_min"): (0.05, 1.0, "a fraction of the part's flow (1: constant)"),
    ("trajectory", "q_home"): (-100.0, 100.0, "rad (a rail: m)"),
    # ServoSettings (`paintcell.execution.execute`)
    ("servo", "bandwidth_hz"): (0.01, 200.0, "Hz"),
    ("servo", "damping_ratio"): (0.0, 100.0, "-"),
    ("servo", "kp"): (0.0, 1e9, "N·m/rad"),
    ("servo", "kd"): (0.0, 1e8, "N·m·s/rad"),
    ("servo", "gain_scale"): (1e-3, 100.0, "a factor"),
    ("servo", "latency_steps"): (0, 100, "control periods"),
    ("servo", "seed"): (-2**63, 2**63 - 1, "an integer"),
    # Disturbances (`paintcell.execution.execute`)
    ("disturbances", "part_offset_m"): (0.0, 1.0, "m"),
    ("disturbances", "part_rotation_rad"): (0.0, math.pi, "rad"),
    ("disturbances", "tcp_offset_m"): (0.0, 0.5, "m"),
    ("disturbances", "gain_scale"): (1e-3, 100.0, "a factor"),
    ("disturbances", "standoff_error_m"): (-0.5, 0.5, "m"),
    ("disturbances", "trigger_delay_s"): (-10.0, 10.0, "s"),
    ("disturbances", "flow_scale"): (1e-3, 100.0, "a factor"),
    ("disturbances", "seed"): (-2**63, 2**63 - 1, "an integer"),
    # Conveyor (`paintcell.booth.conveyor`)
    ("conveyor", "speed_m_s"): (0.0, 2.0, "m/s"),
    ("conveyor", "mass_kg"): (0.0, 1e5, "kg"),
    ("conveyor", "force_max_n"): (0.0, 1e7, "N"),
    ("conveyor", "damping_n_s_m"): (0.0, 1e7, "N·s/m"),
}

#: Keys where +inf is a meaningful value (no bound).
INF_ALLOWED = frozenset({("planner", "max_axis_turn_rad_m"),
                         ("trajectory", "turnaround_max_dip_m")})


def _fmt(x: float) -> str:
    return "inf" if x == _INF else f"{x:g}"


def check_range(table: str, key: str, v: Any) -> str | None:
    """None when `v` (a number, or a list of numbers) is inside the range of `[table] key`
    (or the key has no range or `v` is no number); else the one-line reason with the valid
    range, e.g. "profile_spacing_m = 1e-06 is out of range; valid: [0.0005, 0.2] (m)"."""
    rng = RANGES.get(("planner" if table == "fast_planner" else table, key))
    if rng is None:
        return None
    lo, hi, what = rng
    values = v if isinstance(v, list | tuple) else [v]
    for x in values:
        if isinstance(x, bool) or not isinstance(x, int | float):
            continue   # a type error, reported by the type check
        inf_ok = ("planner" if table == "fast_planner" else table, key) in INF_ALLOWED
        if math.isnan(x) or (math.isinf(x) and not (inf_ok and x > 0)):
            return f"{key} = {v!r} is not a finite number; valid: [{_fmt(lo)}, {_fmt(hi)}] ({what})"
        if not lo <= x <= hi:
            return f"{key} = {v!r} is out of range; valid: [{_fmt(lo)}, {_fmt(hi)}] ({what})"
    return None
