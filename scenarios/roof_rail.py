"""Roof painted by an IRB 5500-class arm on a floor rail — the booth answer to `roof.py`'s
upside-down hang.

Same roof, placement and plan as `roof.py` (5 passes along the car, 1.9 m long, stepping over
1.68 m). The IRB 4600-class arm cannot reach that from the floor (see roof.py); the 2.975 m
IRB 5500-class arm can, from the floor 1.5 m to the side of the roof's centre line... and a rail
along the car (±2 m, `robots.rail`) lets it hold the arm near its preferred posture pass by pass:
the rail position of each pass is the minimum of a smooth 1-D cost (the arm's main axes near
home) over the rail positions where the pass is feasible, and the carriage moves during the
turn-arounds. Rail frame (carriage top) at x = −0.3 m, 0.3 m above the floor (rail on its
sleepers), carriage along world y; the arm faces +x.
Home: tucked back, bell 0.8 m above the roof.
"""

from sim.scenario import Placement, Scenario, Thresholds

SCENARIO = Scenario(
    name="roof_rail",
    part="roof",
    part_placement=Placement(xyz_m=(1.2, 0.0, 1.0), rpy_rad=(0.0, 0.0, 1.5707963267948966)),
    robot="irb5500_rail",
    base=Placement(xyz_m=(-0.5, 0.0, 1.0)),
    planner={"first_side": "right"},
    trajectory={"q_home": (0.0, 0.0, -0.6, 0.3, 0.0, 0.9, 0.0),
                "approach_clearance_m": 0.15, "retract_clearance_m": 0.3},
    # A 10 Hz position loop: with the default 15 Hz and 2 ms latency, the J3 loop of this larger
    # arm rings in the fast turn-arounds (demanded torque 1.46x its limit; 0.43x without latency,
    # 0.44x at 10 Hz). Large arms run lower position-loop bandwidths than 2 m arms.
    servo={"bandwidth_hz": 10.0},
    # Achieved (fast / full): executed σ/μ 4.85 / 4.85 %, loss −0.01 / −0.01 pp (no free bell
    # spin needed, unlike roof.py's +0.22 pp), cycle 28.94 / 28.91 s (roof.py: 28.8 s).
    # Limits: σ/μ + ~2 points, |loss| 0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=7.0,
        max_loss_pp=0.5,
        max_abs_loss_pp=0.5,
        max_cycle_time_s=33.5,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
