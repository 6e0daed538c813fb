"""A paint line's takt arithmetic: what a body every `takt_s` seconds asks of the conveyor and of
each robot (`paintcell init BODY --line --takt T`, `paintcell.app.init_line`).

- Pitch: bodies ride the line one body length plus a gap apart, p = L + g [m]
  (`BODY_GAP_M`: skids leave about a metre between bodies).
- Conveyor speed: one pitch per takt, v = p / T [m/s]; a body passes every robot every T.
- A robot's program: its jobs' estimates as the booth's allocation makes them
  (`paintcell.booth.booth.estimate_s`: the paint time of each pass at its planned speed, TURN_S
  per turn-around, APPROACH_RETRACT_S per job), one after the other.
- Its return home: while it paints, the robot's carriage tracks the body, v · P metres for a
  program of P seconds (`paintcell.booth.conveyor`); before the next body it runs back that far
  at the rail's limits (a trapezoidal move at `RailSpec.v_max_m_s`, `a_max_m_s2`; a triangle
  when the run is too short to reach full speed). The program plus that return must fit T.
- The line's cycle: every carriage tracks the body until the last robot's program ends (the
  booth's cycle C: start delays + programs, on one clock), then all run back together, v · C
  metres each — the same distance at the same instant, so carriages of one rail line keep their
  order. The line meets its takt when C plus that return fits T (`max_cycle_s`).
- Robot count: a first estimate n₀ = ⌈Σ programs / (T · UTILISATION)⌉ (no line balances its
  robots perfectly; `UTILISATION` is the share of the takt a balanced robot is busy), then the
  smallest count from there whose every robot fits, up to the line's limit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from paintcell.booth.booth import estimate_s
from paintcell.core.errors import PaintcellError

__all__ = ["BODY_GAP_M", "UTILISATION", "LineTakt", "first_count", "return_home_s"]

#: Gap between two bodies on the line [m] (skid to skid, about a metre on car-body lines).
BODY_GAP_M = 1.0
#: Share of the takt a balanced robot is busy, for the first estimate of the robot count [-].
UTILISATION = 0.85


@dataclass(frozen=True)
class LineTakt:
    """A body every `takt_s` seconds [s]; bodies `body_length_m` long [m], `gap_m` apart [m]."""

    takt_s: float
    body_length_m: float
    gap_m: float = BODY_GAP_M

    def __post_init__(self) -> None:
        if not (math.isfinite(self.takt_s) and self.takt_s > 0):
            raise PaintcellError(f"takt {self.takt_s!r} s must be a number > 0")
        if not (math.isfinite(self.body_length_m) and self.body_length_m > 0
                and math.isfinite(self.gap_m) and self.gap_m >= 0):
            raise PaintcellError(f"body length {self.body_length_m!r} m and gap {self.gap_m!r} "
                                 "m must be > 0 and ≥ 0")

    @property
    def pitch_m(self) -> float:
        """Body-to-body distance on the line [m]: body length + gap."""
        return self.body_length_m + self.gap_m

    @property
    def conveyor_speed_m_s(self) -> float:
        """Line speed [m/s]: one pitch per takt."""
        return self.pitch_m / self.takt_s

    def program_s(self, jobs: Sequence[np.ndarray]) -> float:
        """Estimated program of a robot [s]: its jobs' `estimate_s` (each job: its passes'
        planned durations [s]) one after the other."""
        return float(sum(estimate_s(np.asarray(d, float)) for d in jobs))

    def robot_cycle_s(self, program_s: float, v_max_m_s: float = 1.5,
                      a_max_m_s2: float = 4.0) -> float:
        """A robot's time per body [s]: its program plus the carriage's return home over the
        distance the body carried it (module doc)."""
        return program_s + return_home_s(self.conveyor_speed_m_s * program_s, v_max_m_s,
                                         a_max_m_s2)

    def max_cycle_s(self, v_max_m_s: float = 1.5, a_max_m_s2: float = 4.0) -> float:
        """The longest booth cycle C [s] whose carriages' return home (v · C metres, module
        doc) still fits the takt: C + `return_home_s`(v · C) = T, in closed form (the
        trapezoidal move, else the triangular one)."""
        v, T = self.conveyor_speed_m_s, self.takt_s
        c = (T - v_max_m_s / a_max_m_s2) / (1.0 + v / v_max_m_s)
        if v * c * a_max_m_s2 >= v_max_m_s ** 2:
            return max(c, 0.0)
        r = math.sqrt(v / a_max_m_s2)                 # C + 2 r √C = T, a quadratic in √C
        return (math.sqrt(r * r + T) - r) ** 2


def return_home_s(distance_m: float, v_max_m_s: float = 1.5, a_max_m_s2: float = 4.0) -> float:
    """Time of a rest-to-rest move over `distance_m` [m] at speed and acceleration limits [s]:
    trapezoidal, or triangular when it cannot reach `v_max_m_s`."""
    d = abs(float(distance_m))
    if d * a_max_m_s2 >= v_max_m_s ** 2:
        return d / v_max_m_s + v_max_m_s / a_max_m_s2
    return 2.0 * math.sqrt(d / a_max_m_s2)


def first_count(total_program_s: float, takt_s: float, utilisation: float = UTILISATION) -> int:
    """First estimate of the robot count: ⌈total / (takt · utilisation)⌉, at least 1."""
    return max(1, math.ceil(total_program_s / (takt_s * utilisation) - 1e-9))
