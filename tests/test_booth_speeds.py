"""Robot-aware speeds in a cell of N robots (paintcell.motion.speed_feedback.robot_aware_parts,
measured by paintcell.motion.speed_caps.part_speeds for any number of robots): a robot's
slowdown, measured on its chained program, lands as caps on the very samples it ran slow — found
again by where they are in space — through a part run backwards and a robot with two jobs."""

from __future__ import annotations

import numpy as np

from paintcell.booth.booth import Job
from paintcell.booth.booth_build import reversed_plan
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.motion.speed_caps import (
    caps_from_speeds,
    part_speeds,
    planner_order,
    stored_caps,
)
from paintcell.paint.applicator import Applicator
from paintcell.surface import parts
from tests.helpers import stand_in_program

APP = Applicator.default()
ST = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=8, film_guard=False)


def _arc(p) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                           axis=1))])


def test_a_slowdown_in_a_reversed_part_is_capped_where_it_happened() -> None:
    plan0 = plan_coverage(parts.panel(0.04), APP, ST)       # the planner's own plan
    n = len(plan0.passes)
    assert n >= 4
    fin = reversed_plan(plan0)                               # the part runs backwards
    # robot 0 runs passes 0-1 of the finished plan; robot 1 chains two jobs: passes 2-2 and
    # 3..n, its second job slowed to 70 % over 0.3-0.5 m of its first pass (finished pass 3)
    jobs = {0: (Job(0, 0, 2),), 1: (Job(0, 2, 3), Job(0, 3, n))}
    prog0 = stand_in_program(fin.passes[0:2], {})
    prog1 = stand_in_program(fin.passes[2:n], {1: (0.3, 0.5, 0.7)})
    prog1.meta["job_first_pass_index"] = [0, 1]
    v_act = part_speeds([fin], jobs, [prog0, prog1])
    asked = [p.speeds_m_s for p in fin.passes]
    caps, n_new, worst = caps_from_speeds(plan0, planner_order(v_act[0], True),
                                          planner_order(asked, True))
    assert n_new > 0 and 25.0 <= worst <= 31.0
    # one pass capped: the planner's pass that finished pass 3 is (n - 1 - 3)
    p0 = plan0.passes[n - 4]
    assert set(caps) == {p0.side}
    gen = caps[p0.side]
    stored0 = gen[::-1] if (n - 4) % 2 == 1 else gen        # planner's execution order
    capped_xyz = p0.positions[np.isfinite(stored0)]
    # independent truth: where finished pass 3 ran slow, by position in space
    p3 = fin.passes[3]
    s3 = _arc(p3)
    nearest = np.argmin(np.linalg.norm(capped_xyz[:, None] - p3.positions[None], axis=2), axis=1)
    assert np.all((s3[nearest] > 0.3 - 0.05) & (s3[nearest] < 0.5 + 0.05))
    core = (s3 > 0.34) & (s3 < 0.46)
    back = stored_caps(plan0, caps, reverse=True)
    assert all(c is None for j, c in enumerate(back) if j != 3)
    assert np.all(np.isfinite(back[3][core]))
    assert np.all(back[3][core] < 0.75 * p3.speeds_m_s[core])
    assert np.all(np.isinf(back[3][(s3 < 0.2) | (s3 > 0.6)]))
    # nothing slowed: nothing capped
    free = [stand_in_program(fin.passes[0:2], {}), stand_in_program(fin.passes[2:n], {})]
    free[1].meta["job_first_pass_index"] = [0, 1]
    v_free = part_speeds([fin], jobs, free)
    caps, n_new, _ = caps_from_speeds(plan0, planner_order(v_free[0], True),
                                      planner_order(asked, True))
    assert caps == {} and n_new == 0
