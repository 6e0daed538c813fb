"""The names a sweep knows: factors with their units, designs (no heavy imports: `paintcell
--help` lists them)."""

from __future__ import annotations

#: name → (unit, meaning). The sweep sets these `Disturbances` fields per sample.
FACTORS: dict[str, tuple[str, str]] = {
    "part_offset_m": ("m", "part placement error on the skid: a translation of |x| in a seeded "
                           "random direction"),
    "part_rotation_rad": ("rad", "part placement error: a rotation of |x| about a seeded random "
                                 "axis through the part origin"),
    "tcp_offset_m": ("m", "TCP calibration error: the spray point |x| off in a seeded random "
                          "tool-frame direction"),
    "standoff_error_m": ("m", "actual − planned spray distance, signed (+: farther)"),
    "gain_scale": ("-", "servo gain factor (tuning error), > 0"),
    "trigger_delay_s": ("s", "paint trigger switching late (+) or early (−), signed"),
    "flow_scale": ("-", "actual ÷ nominal paint flow, > 0"),
    "flow_drift": ("-", "relative change of the flow over the program, signed, in (−1, 1)"),
}
#: factors that are lengths/angles in a random direction: the sweep uses |draw|.
MAGNITUDE_FACTORS = ("part_offset_m", "part_rotation_rad", "tcp_offset_m")
#: tolerances a paint shop asks about that this cell does not model (named in the error).
NOT_MODELLED = {"conveyor_speed_m_s": "the cell has no conveyor: the part stands still"}
METHODS = ("lhs", "mc")
#: the per-sample figures (validation metric keys) a sweep records and summarizes, with units.
SAMPLE_METRICS: dict[str, str] = {
    "executed_nsd_pct": "%",
    "executed_within_tolerance_pct": "%",
    "executed_min_um": "µm",
    "executed_mean_um": "µm",
    "loss_pp": "pp",
    "executed_cycle_time_s": "s",
    "tracking_error_max_mm": "mm",
}
