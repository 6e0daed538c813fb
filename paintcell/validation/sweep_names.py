"""The names a sweep knows: factors with their units, designs (no heavy imports: `paintcell
--help` lists them)."""

from __future__ import annotations

from typing import Any

#: name → (unit, meaning). The sweep sets these `Disturbances` fields per sample.
FACTORS: dict[str, tuple[str, str]] = {
    "part_offset_m": ("m", "part placement error on the skid: a translation of |x| in a seeded "
                           "random direction (a booth: the whole body on its skid)"),
    "part_rotation_rad": ("rad", "part placement error: a rotation of |x| about a seeded random "
                                 "axis through the part origin"),
    "tcp_offset_m": ("m", "TCP calibration error: the spray point |x| off in a seeded random "
                          "tool-frame direction"),
    "standoff_error_m": ("m", "actual − planned spray distance, signed (+: farther)"),
    "gain_scale": ("-", "servo gain factor (tuning error), > 0"),
    "trigger_delay_s": ("s", "paint trigger switching late (+) or early (−), signed"),
    "flow_scale": ("-", "actual ÷ nominal paint flow, > 0"),
    "flow_drift": ("-", "relative change of the flow over the program, signed, in (−1, 1)"),
    "conveyor_speed_error_m_s": ("m/s", "booth only: actual − nominal line speed, signed; the "
                                        "robots still track the nominal speed"),
}
#: the factors the single-robot cell has no meaning for (it has no conveyor).
BOOTH_ONLY_FACTORS = ("conveyor_speed_error_m_s",)
#: factors that are lengths/angles in a random direction: the sweep uses |draw|.
MAGNITUDE_FACTORS = ("part_offset_m", "part_rotation_rad", "tcp_offset_m")
#: tolerances a paint shop asks about that this cell does not model (named in the error).
NOT_MODELLED = {"conveyor_speed_m_s": "the single-robot cell has no conveyor (the part stands "
                                      "still); a booth's line speed tolerance is "
                                      "conveyor_speed_error_m_s on a booth scenario"}
METHODS = ("lhs", "mc")
#: the per-sample figures (validation metric keys) a sweep records and summarizes, with units.
SAMPLE_METRICS: dict[str, str] = {
    "executed_nsd_pct": "%",
    "executed_within_tolerance_pct": "%",
    "executed_inside_spec_pct": "%",
    "executed_min_um": "µm",
    "executed_mean_um": "µm",
    "loss_pp": "pp",
    "executed_cycle_time_s": "s",
    "tracking_error_max_mm": "mm",
}
#: the figures a booth sample records beside those (`paintcell.sweeps.sweep_worker`): the
#: conveyor's share of the loss, the worst part's executed σ/μ and share of area in the paint
#: spec's window (the booth's spec checks), the carrier's measured speed.
BOOTH_METRICS: dict[str, str] = {
    "loss_conveyor_pp": "pp",
    "max_part_executed_nsd_pct": "%",
    "min_part_executed_inside_spec_pct": "%",
    "carrier_speed_m_s": "m/s",
}


def record_metrics(records: list[dict[str, Any]]) -> dict[str, str]:
    """figure → unit: `SAMPLE_METRICS`, and the `BOOTH_METRICS` some record holds a value of."""
    extra = {k: u for k, u in BOOTH_METRICS.items()
             if any((r.get("metrics") or {}).get(k) is not None for r in records)}
    return {**SAMPLE_METRICS, **extra}
