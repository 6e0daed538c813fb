"""Human names, units and precision for the metrics a paint engineer reads first.

metrics.json keeps the machine keys (`loss_pp 0.00170501`); the report shows
"Loss of uniformity plan → execution: 0.17 pp". Each entry: machine key, label, unit, decimals.
A key missing from a results folder's metrics (an older run, a disabled check) is left out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

#: a robot's motion: (metric key, label, unit, decimals), of each robot in its section, over the
#: robots in the key figures.
ROBOT_MOTION: tuple[tuple[str, str, str, int], ...] = (
    ("executed_paint_time_s", "Time with the bell painting", "s", 1),
    ("tracking_error_max_mm", "Largest TCP path error while painting", "mm", 2),
    ("speed_error_rms_pct", "RMS TCP speed error while painting", "%", 1),
    ("max_joint_range_utilization", "Closest approach to a joint limit (1 = at it)", "", 2),
    ("max_torque_utilization", "Highest joint torque / rated torque", "", 2),
)
#: (section, [(metric key, label, unit, decimals)]) in reading order.
HEADLINE: tuple[tuple[str, tuple[tuple[str, str, str, int], ...]], ...] = (
    ("Film", (
        ("executed_inside_spec_pct", "Area inside the spec window, executed", "%", 1),
        ("planned_inside_spec_pct", "Area inside the spec window, planned", "%", 1),
        ("spec_target_um", "Spec target film", "µm", 1),
        ("spec_low_um", "Spec window, thinnest", "µm", 1),
        ("spec_high_um", "Spec window, thickest", "µm", 1),
        ("executed_below_spec_pct", "Area below the spec window, executed", "%", 1),
        ("executed_above_spec_pct", "Area above the spec window, executed", "%", 1),
        ("executed_within_tolerance_pct", "Area within ±tolerance of the planned mean, executed",
         "%", 1),
        ("executed_mean_um", "Mean film, executed", "µm", 1),
        ("planned_mean_um", "Mean film, planned", "µm", 1),
        ("executed_min_um", "Thinnest film, executed", "µm", 1),
        ("executed_max_um", "Thickest film, executed", "µm", 1),
        ("max_thickness_diff_um", "Largest film difference executed − planned", "µm", 1),
        ("rms_thickness_diff_um", "RMS film difference executed − planned", "µm", 2),
        ("executed_transfer_efficiency_pct", "Transfer efficiency, executed", "%", 1),
        ("planned_transfer_efficiency_pct", "Transfer efficiency, planned", "%", 1),
        ("paint_used_l", "Paint sent (film volume), executed", "L", 4),
        ("planned_paint_used_l", "Paint sent (film volume), planned", "L", 4),
        ("film_on_body_l", "Film on the body, executed", "L", 4),
    )),
    ("Uniformity (σ/μ, the paper's measure)", (
        ("planned_nsd_pct", "Film uniformity σ/μ, planned", "%", 2),
        ("trajectory_nsd_pct", "Film uniformity σ/μ, time law (commanded program)", "%", 2),
        ("servo_nsd_pct", "Film uniformity σ/μ, servo (before conveyor tracking)", "%", 2),
        ("executed_nsd_pct", "Film uniformity σ/μ, executed", "%", 2),
        ("loss_pp", "Loss of uniformity plan → execution", "pp", 2),
        ("loss_time_law_pp", "  of which time law and IK", "pp", 2),
        ("loss_servo_pp", "  of which servo tracking and disturbances", "pp", 2),
        ("loss_conveyor_pp", "  of which conveyor tracking", "pp", 4),
        ("overlap_band_area_pct", "Overlap bands (two robots ≥ 10 % of the film each)", "%", 1),
        ("overlap_planned_nsd_pct", "Film uniformity σ/μ in overlap bands, planned", "%", 2),
        ("overlap_executed_nsd_pct", "Film uniformity σ/μ in overlap bands, executed", "%", 2),
    )),
    ("Motion", (
        ("executed_cycle_time_s", "Cycle time, executed", "s", 1),
        ("planned_cycle_time_s", "Cycle time, programmed", "s", 1),
        ("carrier_tracking_error_max_mm", "Largest conveyor carrier servo error", "mm", 3),
        *ROBOT_MOTION,
    )),
    ("Hems, flanges and turned edges (reported apart, not judged)", tuple(
        entry for region, name in (("hem", "Hem"), ("edge", "Turned edge"), ("inner", "Inner"))
        for entry in (
            (f"{region}_executed_mean_um", f"{name} mean film, executed", "µm", 1),
            (f"{region}_planned_mean_um", f"{name} mean film, planned", "µm", 1),
            (f"{region}_executed_vs_skin_pct", f"{name} film / skin film, executed", "%", 0),
            (f"{region}_executed_nsd_pct", f"{name} film uniformity σ/μ, executed", "%", 1)))),
    ("Reach and safety", (
        ("reachability_pct", "Plan poses reached", "%", 1),
        ("n_collisions", "Collision events", "", 0),
        ("n_robot_robot_collisions", "Robot–robot collision events", "", 0),
        ("min_bell_distance_m", "Closest two bells while both paint", "m", 2),
        ("max_contact_depth_mm", "Deepest contact", "mm", 1),
        ("part_placement_error_mm", "Part placement error (disturbance)", "mm", 1),
    )),
)

#: a robot's section (`paintcell.output.report_robots`): its share of a cell's work
#: (metrics.json `robots`) and its motion.
ROBOT_FIGURES = (
    ("Its share of the cell's work", (
        ("program_s", "Own program", "s", 2),
        ("start_delay_s", "Start delay (held at home)", "s", 2),
        ("busy_share_pct", "Busy (own program ÷ cell cycle)", "%", 2),
        ("paint_share_pct", "Brush on (÷ cell cycle)", "%", 2),
        ("paint_credit_pct", "Paint credit (its share of the film volume)", "%", 2),
        ("coverage_credit_pct", "Coverage credit (area where it lays most film)", "%", 2))),
    ("Motion", ROBOT_MOTION),
)

#: check units as stored in metrics.json → as printed.
_CHECK_UNITS = {"-": "", "events": "events", "pp": "pp", "%": "%", "s": "s", "mm": "mm"}
#: decimals by unit for checks and pass tables.
_DECIMALS = {"pp": 2, "%": 1, "s": 1, "mm": 2, "events": 0, "": 2, "µm": 1, "mm/s": 0}


def number(v: Any, decimals: int) -> str:
    """A value at fixed precision ("—" for None/nan; integers stay integers)."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(x):
        return "—"
    if decimals == 0:
        return f"{x:.0f}"
    if 0 < abs(x) < 0.5 * 10.0**-decimals:  # 0.0012 pp reads "0.001 pp", not "0.00 pp"
        return f"{x:.{-math.floor(math.log10(abs(x)))}f}"
    return f"{x:.{decimals}f}"


def with_unit(v: Any, unit: str, decimals: int | None = None) -> str:
    """"0.17 pp", "12.3 µm", "3 events", "0.85"."""
    d = _DECIMALS.get(unit, 2) if decimals is None else decimals
    text = number(v, d)
    return f"{text} {unit}" if unit and text != "—" else text


def headline_rows(metrics: dict[str, Any], sections: Sequence[Any] = HEADLINE
                  ) -> list[tuple[str, list[tuple[str, str, str]]]]:
    """[(section, [(label, value with unit, machine key)])] for the keys `metrics` has, of
    `sections` (`HEADLINE` or `ROBOT_FIGURES`)."""
    out = []
    for section, entries in sections:
        rows = [(label.strip(), with_unit(metrics[key], unit, dec), key)
                for key, label, unit, dec in entries if key in metrics]
        if rows:
            out.append((section, rows))
    return out


def check_reason(check: dict[str, Any]) -> str:
    """One sentence for a failed check: "Loss of uniformity 1.53 pp is above the limit 1.00 pp".
    """
    unit = _CHECK_UNITS.get(str(check.get("unit") or ""), str(check.get("unit") or ""))
    name = str(check.get("name", "check"))
    name = name[:1].upper() + name[1:]
    value, limit = check.get("value"), check.get("limit")
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        text = f"{name} could not be measured (limit {with_unit(limit, unit)})"
    elif check.get("kind") == "min":
        text = f"{name} {with_unit(value, unit)} is below the minimum {with_unit(limit, unit)}"
    else:
        text = f"{name} {with_unit(value, unit)} is above the limit {with_unit(limit, unit)}"
    detail = str(check.get("detail") or "")
    return f"{text} ({detail})" if detail else text


def check_cells(check: dict[str, Any]) -> tuple[str, str, str]:
    """(name, value with unit, limit with ≤/≥) of one check at sensible precision."""
    unit = _CHECK_UNITS.get(str(check.get("unit") or ""), str(check.get("unit") or ""))
    op = "≥" if check.get("kind") == "min" else "≤"
    return (str(check.get("name", "")), with_unit(check.get("value"), unit),
            f"{op} {with_unit(check.get('limit'), unit)}")
