"""What a validation returns: the thresholds, the checks of metrics against them, the report.

`Thresholds` holds the pass/fail limits (inf or None disables a check), `Check` one limit's
verdict, `ValidationReport` the metrics (report units in the key names: σ/μ in %, thickness in
µm, errors in mm / %, times in s), the checks and the per-vertex films [m], JSON-safe.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError, ScenarioDataError


class ValidationError(PaintcellError):
    """Plan, trajectory and trace cannot be compared (mismatched lengths, frames, parts)."""


@dataclass(frozen=True)
class Thresholds:
    """Pass/fail limits of a validation (inf or None disables a check).

    reachability_pct: minimum share of plan poses the robot reaches [%].
    max_collisions: maximum number of collision events: robot–part, robot–booth and robot–robot
        (self-collision, e.g. the wrist driven into the robot's base).
    max_executed_nsd_pct: maximum executed film σ/μ over the part [%]; it only tightens the
        paint spec's `max_nsd_pct` (`paintcell.validation.paint_spec`: the check holds the
        smaller of the two).
    max_loss_pp: maximum loss of uniformity, executed − planned σ/μ [percentage points].
    max_abs_loss_pp: maximum |executed − planned σ/μ| [percentage points]: a large negative loss
        (executed more uniform than planned) is a departure from the plan too. None: unchecked.
    max_cycle_time_s: maximum executed cycle time [s].
    max_tracking_error_mm: maximum TCP position error on paint segments [mm].
    max_speed_error_pct: maximum RMS TCP speed-following error on paint segments [%].
    max_torque_utilization: maximum |τ_demand|/τ_max of any joint, τ_demand the torque the
        controller demanded before the actuator clamp (> 1: the joint saturated) [-].
    max_joint_range_utilization: maximum |q − mid|/half-range of any joint (1 = at a limit) [-].
    tolerance: half-width of the window around the planned mean behind the
        `*_within_tolerance_pct` figures [fraction] (reported, not checked; the paint spec's
        window is `[spec] window_pct`).
    """

    reachability_pct: float | None = 100.0
    max_collisions: int | None = 0
    max_executed_nsd_pct: float | None = 20.0
    max_loss_pp: float | None = 1.0
    max_abs_loss_pp: float | None = None
    max_cycle_time_s: float | None = 120.0
    max_tracking_error_mm: float | None = None
    max_speed_error_pct: float | None = None
    max_torque_utilization: float | None = 1.0
    max_joint_range_utilization: float | None = 1.0
    tolerance: float = 0.10

    def __post_init__(self) -> None:
        if not (0 < self.tolerance < 1):
            raise ValidationError(f"tolerance = {self.tolerance} must be a fraction in (0, 1)")


#: Threshold ranges: (low, high, low inclusive, what it is). +inf disables a `max_*` check.
THRESHOLD_RANGES: dict[str, tuple[float, float, bool, str]] = {
    "reachability_pct": (0.0, 100.0, True, "a share of poses [%]"),
    "max_collisions": (0.0, math.inf, True, "a count of collision events"),
    "max_executed_nsd_pct": (0.0, math.inf, False, "σ/μ [%]"),
    "max_loss_pp": (0.0, math.inf, True, "percentage points"),
    "max_abs_loss_pp": (0.0, math.inf, True, "percentage points"),
    "max_cycle_time_s": (0.0, math.inf, False, "seconds"),
    "max_tracking_error_mm": (0.0, math.inf, True, "mm"),
    "max_speed_error_pct": (0.0, math.inf, True, "%"),
    "max_torque_utilization": (0.0, math.inf, False, "|τ|/τ_max"),
    "max_joint_range_utilization": (0.0, math.inf, False, "a fraction of the joint range"),
    "tolerance": (0.0, 1.0, False, "a fraction of the mean thickness"),
    # a booth's (paintcell.booth.booth.BoothThresholds)
    "max_robot_collisions": (0.0, math.inf, True, "a count of robot–robot collision events"),
    "max_body_nsd_pct": (0.0, math.inf, False, "σ/μ [%]"),
    "max_seam_nsd_ratio": (0.0, math.inf, False, "a ratio of σ/μ (seams ÷ interiors) [-]"),
    "min_bell_distance_m": (0.0, math.inf, True, "a distance [m]"),
}

def _fmt_range(lo: float, hi: float, lo_incl: bool = True) -> str:
    left = "[" if lo_incl else "("
    right = "]" if math.isfinite(hi) else ")"
    return f"{left}{lo:g}, {hi:g}{right}"


def check_thresholds(th: Any, where: str = "thresholds") -> None:
    """Refuse NaN, −inf, wrong types and out-of-range threshold values (ScenarioDataError).

    A NaN limit would silently remove its check (every comparison with NaN is False), so the gate
    could PASS without checking; `max_collisions = -1` could never pass. None or +inf disables a
    `max_*` check explicitly.
    """
    for f in fields(th):
        v = getattr(th, f.name)
        if v is None and f.name != "tolerance":
            continue
        lo, hi, lo_incl, what = THRESHOLD_RANGES.get(f.name, (-math.inf, math.inf, True, ""))
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} must be a number ({what})")
        if math.isnan(v) or v == -math.inf or (v == math.inf and not f.name.startswith("max_")):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} is not a finite number; valid: "
                                    f"{_fmt_range(lo, hi, lo_incl)} ({what})")
        if v < lo or (v == lo and not lo_incl) or (v > hi and math.isfinite(hi)) \
                or (f.name == "tolerance" and v >= hi):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} is out of range; valid: "
                                    f"{_fmt_range(lo, hi, lo_incl)} ({what})")
        if f.name in ("max_collisions", "max_robot_collisions") and math.isfinite(v) \
                and v != int(v):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} must be a whole number")


@dataclass(frozen=True)
class Check:
    """One threshold check: value vs limit; kind "max" (value ≤ limit) or "min" (value ≥ limit)."""

    name: str
    value: float
    limit: float
    unit: str
    passed: bool
    kind: str = "max"
    detail: str = ""


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Plan-vs-executed metrics (scalars in `metrics`, report units in the key names).

    metrics: JSON-safe scalars (σ/μ in %, thickness in µm, errors in mm / %, times in s).
    checks: one `Check` per enabled threshold; passed: all checks passed.
    reachability: summary dict from the robots' reachability report (or None).
    collisions: collision events (bodies, start/end time [s], max depth [m], samples).
    joint_range_utilization / torque_utilization: per joint, max fraction [-] (torque: demanded
        before the actuator clamp, so > 1 where the joint saturated).
    torque_saturation_pct: per joint, share of program steps whose demanded torque exceeded
        τ_max [%].
    planned_thickness_m / executed_thickness_m / trajectory_thickness_m: (N,) film per surface
        vertex [m] (plots only).
    """

    metrics: dict[str, Any]
    checks: tuple[Check, ...]
    reachability: dict[str, Any] | None
    collisions: tuple[dict[str, Any], ...]
    joint_range_utilization: tuple[float, ...]
    torque_utilization: tuple[float, ...]
    planned_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    executed_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    trajectory_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    torque_saturation_pct: tuple[float, ...] = ()

    @property
    def passed(self) -> bool:
        """True when every enabled check passed."""
        return all(c.passed for c in self.checks)

    @property
    def loss_pp(self) -> float:
        """Executed − planned σ/μ [percentage points]."""
        return float(self.metrics["loss_pp"])

    def __getattr__(self, name: str) -> Any:
        # Scalar metrics read as attributes too (report.executed_nsd_pct).
        metrics = self.__dict__.get("metrics", {})
        if name in metrics:
            return metrics[name]
        raise AttributeError(name)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serializable report (no thickness arrays; nan/inf → None)."""
        d: dict[str, Any] = {k: _json_num(v) for k, v in self.metrics.items()}
        d["passed"] = self.passed
        d["checks"] = [{k: _json_num(v) for k, v in asdict(c).items()} for c in self.checks]
        d["reachability"] = self.reachability
        d["collisions"] = list(self.collisions)
        d["joint_range_utilization"] = [_json_num(x) for x in self.joint_range_utilization]
        d["torque_utilization"] = [_json_num(x) for x in self.torque_utilization]
        d["torque_saturation_pct"] = [_json_num(x) for x in self.torque_saturation_pct]
        return d


def _json_num(v: Any) -> Any:
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    return v


def threshold_checks(m: dict[str, Any], th: Thresholds) -> list[Check]:
    """Each limit of `th` set (not None or inf) checked against the metrics `m`, in report
    order."""
    spec = [  # (name, metric key, limit, unit, kind)
        ("reachability", "reachability_pct", th.reachability_pct, "%", "min"),
        ("collisions", "n_collisions", th.max_collisions, "events", "max"),
        ("executed σ/μ", "executed_nsd_pct", th.max_executed_nsd_pct, "%", "max"),
        ("uniformity loss", "loss_pp", th.max_loss_pp, "pp", "max"),
        ("|uniformity loss|", "abs_loss_pp", th.max_abs_loss_pp, "pp", "max"),
        ("cycle time", "executed_cycle_time_s", th.max_cycle_time_s, "s", "max"),
        ("TCP tracking error", "tracking_error_max_mm", th.max_tracking_error_mm, "mm", "max"),
        ("speed-following error", "speed_error_rms_pct", th.max_speed_error_pct, "%", "max"),
        ("torque utilization", "max_torque_utilization", th.max_torque_utilization, "-", "max"),
        ("joint range utilization", "max_joint_range_utilization",
         th.max_joint_range_utilization, "-", "max"),
    ]
    out = []
    for name, key, limit, unit, kind in spec:
        if limit is None or not math.isfinite(float(limit)):
            continue
        value = float(m[key])
        if not math.isfinite(value):
            if key == "reachability_pct":  # no reachability report given: nothing to check
                continue
            passed = False
        else:
            passed = value <= limit if kind == "max" else value >= limit
        detail = ""
        if key == "reachability_pct" and not passed:
            detail = str(m.get("reachability_verdict", ""))
        out.append(Check(name=name, value=value, limit=float(limit), unit=unit,
                         passed=bool(passed), kind=kind, detail=detail))
    return out
