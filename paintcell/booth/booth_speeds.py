"""Robot-aware speeds in a booth: the loop of `paintcell.motion.speed_feedback` with every
robot of the booth (`paintcell.booth.booth_programs` runs it on the chosen allocation when
`Booth.robot_aware_speeds` is set, the default).

Every robot's program is measured on the passes it runs and capped where it ran slow, as a
one-robot run's (`speed_feedback.part_speeds`, `caps_from_speeds`); each capped part is planned
again under its caps, the plans are finished as before (`booth_plans.finish_plans`: the
refinement keeps under the caps too) and the same allocation is built again. A round whose
programs fail or make the booth's cycle longer than `MAX_CYCLE_GROWTH` ends the loop with the
previous round's plans.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.booth.booth import Booth, Job
from paintcell.booth.booth_plans import FinishedPlans, PartPlans, finish_plans
from paintcell.core.errors import PaintcellError
from paintcell.coverage.coverage import plan_coverage
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion import speed_feedback as sf
from paintcell.motion.joint_trajectory import JointTrajectory

#: re-plans at most.
ROUNDS = 2
#: a round whose booth cycle grows by more than this fraction of the first is not taken.
MAX_CYCLE_GROWTH = 0.05


@dataclass
class Built:
    """An allocation as built (`booth_programs._choose`): jobs per robot, each robot's static
    program, the staggered ones, and the record of what was tried."""

    jobs: dict[int, tuple[Job, ...]]
    static: list[JointTrajectory]
    trajs: list[JointTrajectory]
    tried: list[dict[str, Any]]

    @property
    def cycle_s(self) -> float:
        """The booth's cycle [s]: the staggered programs' clock."""
        return (max(len(tr.t_s) for tr in self.trajs) - 1) * self.trajs[0].dt_s


def robot_aware_booth(booth: Booth, pp: PartPlans, fin: FinishedPlans, built: Built,
                      rebuild: Callable[[list[CoveragePlan]], Built], rounds: int = ROUNDS
                      ) -> tuple[FinishedPlans, Built, dict[str, Any]]:
    """The plans and programs after the robot-aware rounds (module doc) and a record
    {rule, rounds: [{capped_samples, max_deficit_pct, cycle_s, replanned}], cycle_s (the booth
    cycle of the programs returned [s]), capped_passes}."""
    plans0 = list(pp.plans)
    caps: list[dict[int, np.ndarray]] = [{} for _ in plans0]
    cycle0 = built.cycle_s
    rec: dict[str, Any] = {"rule": f"caps where a robot ran > 0.5 % slower than asked (at or "
                                   f"between samples), re-planned at most {rounds}×, kept if "
                                   f"the cycle grows ≤ "
                                   f"{MAX_CYCLE_GROWTH:.0%}", "rounds": []}
    for _ in range(rounds + 1):
        v_act = sf.part_speeds(fin.plans, built.jobs, built.static)
        lags = sf.part_speeds(fin.plans, built.jobs, built.static, lags=True)
        new_caps, counts, worst = [], [], 0.0
        for i, bp in enumerate(booth.parts):
            asked = [np.asarray(p.speeds_m_s, float) for p in fin.plans[i].passes]
            c, n, w = sf.caps_from_speeds(plans0[i], sf.planner_order(v_act[i], bp.reverse),
                                          sf.planner_order(asked, bp.reverse), caps[i],
                                          lags=sf.planner_order(lags[i], bp.reverse))
            new_caps.append(c)
            counts.append(n)
            worst = max(worst, w)
        rnd: dict[str, Any] = {"capped_samples": int(sum(counts)), "max_deficit_pct": worst,
                               "cycle_s": built.cycle_s}
        rec["rounds"].append(rnd)
        if not any(counts) or len(rec["rounds"]) > rounds:
            break
        trial = list(plans0)
        rnd["replanned"] = []
        for i, n in enumerate(counts):
            if not n:
                continue
            st = pp.settings[i]
            finite = {k: np.where(np.isfinite(v), v, st.v_max_m_s) for k, v in new_caps[i].items()}
            try:
                got = plan_coverage(pp.skins[i], pp.applicator, st, speed_caps_m_s=finite)
            except PaintcellError as exc:       # the caps do not fit this part's plan: keep it
                rnd.setdefault("failed", {})[booth.parts[i].part] = str(exc)
                continue
            if [len(p.positions) for p in got.passes] != \
                    [len(p.positions) for p in plans0[i].passes]:
                rnd.setdefault("failed", {})[booth.parts[i].part] = "other passes"
                continue
            trial[i] = got
            rnd["replanned"].append(booth.parts[i].part)
        if not rnd["replanned"]:
            break
        try:
            fin2 = finish_plans(booth, pp, trial,
                                [sf.stored_caps(trial[i], new_caps[i], bp.reverse)
                                 for i, bp in enumerate(booth.parts)])
            built2 = rebuild(fin2.plans)
        except PaintcellError as exc:           # the re-planned programs do not work: stop
            rnd["rejected"] = str(exc)
            break
        if built2.cycle_s > (1.0 + MAX_CYCLE_GROWTH) * cycle0:
            rnd["rejected"] = f"cycle {built2.cycle_s:.2f} s against {cycle0:.2f} s"
            break
        plans0, caps, fin, built = trial, new_caps, fin2, built2
    rec["cycle_s"] = built.cycle_s           # the programs run (the tried table: before it)
    rec["capped_passes"] = {booth.parts[i].part: sorted(int(k) for k in c)
                            for i, c in enumerate(caps) if c}
    return fin, built, rec
