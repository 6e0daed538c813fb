"""Robot-aware speeds: feed the time law's joint-limit slowdowns back into the speed QP, for one
robot (`robot_aware_plan`) or the N robots of a cell (`robot_aware_parts`).

The planner (`paintcell.coverage.algorithm`) optimizes each pass's TCP speeds for the film,
knowing nothing of the robot. Along the IK path, joint velocity and acceleration limits can make
TOPP-RA slower than planned; the film then differs from the plan (the "time-law share" of the
loss). The loop the paper leaves open:

    plan → joint program → where the executed TCP speed falls short of the plan, cap the speed of
    those samples at what the robot reached (minus a margin, `paintcell.motion.speed_caps`) →
    re-plan the passes' speeds with the caps as per-sample upper bounds of eq. 2 → rebuild the
    joint program → repeat

The re-plan reproduces the same pass geometry (the planner is deterministic), so the caps of one
plan fit the next. Caps only shrink from one round to the next. A round whose program is longer
than the first by more than `MAX_CYCLE_GROWTH` ends the loop with the previous round's plan.

One robot also feeds back the bell's spin about its axis (`tool_axes`). In a cell of N robots
each capped part is planned again, the cell's `finish` makes the plans the robots run from them
and `rebuild` builds the same allocation's programs again. A part whose robots reach only a
fraction of its speeds, more than the brush table's lowest flow makes up for (an arm reaching
round a fascia's corner), is planned again at that pace (`part_pace`, `paced`): all its speeds
slower by one factor, the same passes and uniformity, and the cell's common film build turns
its flow down by the same factor; the caps then bind on a plan the arm can nearly follow,
instead of thickening the film where they bind. A round is kept while the cell's cycle stays
within its limit (the scenario's `max_cycle_time_s`) or grows by at most `MAX_CYCLE_GROWTH`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.core.tasks import map_tasks
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.motion.speed_caps import parts_caps, speed_caps, stored_caps, tool_axes
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface_data import Surface

#: The bell's x axis counts as followed when the program holds it within this of the plan [deg].
SPIN_TOL_DEG = 1.0
#: A re-planned round whose cycle grows by more than this fraction of the first is not taken.
MAX_CYCLE_GROWTH = 0.05
#: Re-plans at most of a cell of N robots.
CELL_ROUNDS = 2
#: A part's pace (`part_pace`): the share of its samples whose slowdown may stay deeper than
#: the brush table's lowest flow makes up for [-], the slowest pace [-] (the flow turned down
#: to half, a bell's range), and the pace above which the part keeps its planned speeds [-].
PACE_QUANTILE = 0.05
PACE_MIN = 0.5
PACE_KEEP = 0.9


@dataclass
class FeedbackResult:
    """Outcome of the robot-aware loop.

    plan / trajectory: the final plan and its joint program.
    rounds: per round, {"capped_samples", "max_deficit_pct", "cycle_s"} of the program that was
        measured (round 0 = the robot-free plan).
    caps_m_s: the final caps {pass side: (M,) [m/s]} in each pass's generation direction.
    """

    plan: CoveragePlan
    trajectory: Any
    rounds: list[dict[str, Any]] = field(default_factory=list)
    caps_m_s: dict[int, np.ndarray] = field(default_factory=dict)


def with_targets(plan: CoveragePlan, targets: CoveragePlan) -> CoveragePlan:
    """`plan` with the travel directions (TCP x axes, the robot's orientation targets) of
    `targets`, a plan of the same passes (same sides and sample counts; otherwise `plan` as it
    is): the program of a spin-fed re-plan is built from the targets the robot's spin came from,
    while the plan's own travel directions stay the film model's (`tool_x`)."""
    same = len(plan.passes) == len(targets.passes) and all(
        a.side == b.side and len(a.travel_dirs) == len(b.travel_dirs)
        for a, b in zip(plan.passes, targets.passes, strict=True))
    if not same:
        return plan
    passes = tuple(replace(a, travel_dirs=b.travel_dirs)
                   for a, b in zip(plan.passes, targets.passes, strict=True))
    return replace(plan, passes=passes)


def robot_aware_plan(surface: Surface, app: Applicator, settings: PlannerSettings,
                     plan: CoveragePlan, traj: Any, build: Any, rounds: int = 3,
                     T_world_part: np.ndarray | None = None) -> FeedbackResult:
    """Re-plan the speeds under the robot's reachable speeds until no new slowdown appears.

    surface, app, settings: what `plan` was planned with; traj: its joint program;
    build: callable plan → joint program (`paintcell.motion.trajectory.build_program` bound to
    the robot and
    placement); rounds: re-plans at most; T_world_part: the part placement — when given, the bell
    x axes the program holds are fed back too (`tool_axes`), so the plan's film model uses the
    orientation the robot really holds about the spray axis.
    Returns the final plan and program; a round whose program is slower than the first by more
    than `MAX_CYCLE_GROWTH` ends the loop with the previous round's plan.
    """
    res = FeedbackResult(plan, traj)
    cycle0 = float(traj.t_s[-1])
    caps: dict[int, np.ndarray] = {}
    tool_x: dict[int, np.ndarray] = {}
    for k in range(rounds):
        # the first caps trust the brush table's lowest flow (`paintcell.motion.flow`)
        caps, n_new, worst = speed_caps(res.plan, res.trajectory, caps, trust_floor=k == 0)
        turn = 0.0
        if T_world_part is not None:
            new_x = tool_axes(res.plan, res.trajectory, T_world_part)
            for i, p in enumerate(res.plan.passes):
                if p.side in new_x:
                    x_plan = p.travel_dirs[::-1] * -1 if i % 2 == 1 else p.travel_dirs
                    cosang = np.clip(np.einsum("ij,ij->i", x_plan, new_x[p.side]), -1, 1)
                    turn = max(turn, float(np.degrees(np.arccos(cosang)).max()))
            tool_x = new_x
        res.rounds.append({"capped_samples": float(n_new), "max_deficit_pct": worst,
                           "cycle_s": float(res.trajectory.t_s[-1]), "max_spin_deg": turn})
        if n_new == 0 and turn < SPIN_TOL_DEG:
            break
        finite = {k: np.where(np.isfinite(v), v, settings.v_max_m_s) for k, v in caps.items()}
        got = None
        # with the bell's spin fed back first; if that program fails or runs > 5 % longer (the
        # IK seeds follow the new target orientation to another branch), with the caps alone
        for use_spin in ([True, False] if tool_x else [False]):
            new_plan = plan_coverage(surface, app, settings, speed_caps_m_s=finite,
                                     tool_x=tool_x if use_spin else None)
            try:
                # the robot keeps the orientation targets of the first program (the free-spin
                # IK found the spin the film now assumes from them); targets equal to that spin
                # send the IK's seeds to other branches
                new_traj = build(with_targets(new_plan, plan) if use_spin else new_plan)
            except PaintcellError as e:      # the re-plan's program failed: try without spin
                res.rounds.append({"failed": str(e), "spin": use_spin})
                if use_spin:
                    tool_x, T_world_part = {}, None
                continue
            if float(new_traj.t_s[-1]) <= (1.0 + MAX_CYCLE_GROWTH) * cycle0:
                got = (new_plan, new_traj)
                break
            res.rounds.append({"rejected_cycle_s": float(new_traj.t_s[-1]), "spin": use_spin})
            if use_spin:
                tool_x = {}
                T_world_part = None              # the robot cannot hold the plan's spin: stop
        if got is None:
            break
        new_plan, new_traj = got
        res.plan, res.trajectory, res.caps_m_s = new_plan, new_traj, finite
    else:
        _, _, worst = speed_caps(res.plan, res.trajectory, caps)
        res.rounds.append({"capped_samples": 0.0, "max_deficit_pct": worst,
                           "cycle_s": float(res.trajectory.t_s[-1])})
    return res


@dataclass
class CellPrograms:
    """The programs of an allocation of a cell's passes to its robots: jobs per robot (each with
    `.part`, `.first`, `.end`: passes of that part's plan), each robot's own program (static),
    the staggered ones on the common clock, and the record of what was tried."""

    jobs: dict[int, tuple[Any, ...]]
    static: list[JointTrajectory]
    trajs: list[JointTrajectory]
    tried: list[dict[str, Any]]

    @property
    def cycle_s(self) -> float:
        """The cell's cycle [s]: the staggered programs' clock."""
        return (max(len(tr.t_s) for tr in self.trajs) - 1) * self.trajs[0].dt_s


def part_pace(plan: CoveragePlan, caps: dict[int, np.ndarray]) -> float:
    """The factor [-] on a part's planned speeds that lets its robots' slowdowns be made up by
    the brush table (`paintcell.motion.flow`). caps: the part's first caps {pass side: (M,)
    [m/s]} (`parts_caps` trusting the lowest flow: the speed the film sees, the TCP's over the
    flow), so r = cap ÷ asked < 1 only where the flow already sits at its floor and still falls
    short; a plan paced by k asks k × the speed there, and the flow makes up the rest while
    r ≥ k. k is the PACE_QUANTILE-th quantile of r over the part's samples (1 where uncapped), in
    [PACE_MIN, 1]; 1 when that is above PACE_KEEP (the caps alone cost less time than a slower
    part)."""
    r = [np.ones(len(p.speeds_m_s)) if c is None else
         np.minimum(1.0, c / np.asarray(p.speeds_m_s, float))
         for p, c in zip(plan.passes, stored_caps(plan, caps, False), strict=True)]
    k = float(np.quantile(np.concatenate(r), PACE_QUANTILE))
    return 1.0 if k > PACE_KEEP else max(PACE_MIN, k)


def paced(st: PlannerSettings, pace: float) -> PlannerSettings:
    """Planner settings whose pass speeds (nominal, lowest, highest) are `pace` × st's: the same
    passes at the same film uniformity, a film 1 / pace thicker at the same flow; planned with
    the bell's flow scaled by pace too (`Applicator.scaled`), the same film."""
    if pace == 1.0:
        return st
    return replace(st, v_nominal_m_s=pace * st.v_nominal_m_s, v_min_m_s=pace * st.v_min_m_s,
                   v_max_m_s=pace * st.v_max_m_s)


def replan_capped(skin: Surface, app: Applicator, st: PlannerSettings,
                  caps_m_s: dict[int, np.ndarray]) -> CoveragePlan | PaintcellError:
    """A part's plan again with per-sample speed caps {pass side: (M,) [m/s]} (`plan_coverage`),
    or the error that refused it (returned: a task of `robot_aware_parts`'s pool)."""
    try:
        return plan_coverage(skin, app, st, speed_caps_m_s=caps_m_s)
    except PaintcellError as exc:
        return exc


def robot_aware_parts(names: Sequence[str], reverse: Sequence[bool], planned: Any,
                      finished: Any, built: CellPrograms,
                      finish: Callable[[list[CoveragePlan], list[Any]], Any],
                      rebuild: Callable[[list[CoveragePlan]], CellPrograms],
                      rounds: int = CELL_ROUNDS, pool: Any = None,
                      max_cycle_s: float | None = None
                      ) -> tuple[Any, CellPrograms, dict[str, Any]]:
    """The plans and programs of a cell of N robots after the robot-aware rounds (module doc) and
    a record {rule, rounds: [{capped_samples, max_deficit_pct, cycle_s, replanned}], cycle_s (the
    cell cycle of the programs returned [s]), capped_passes}.

    names, reverse: each part's name and whether its passes run backwards; planned: the parts as
    the planner planned them (`.plans`, `.skins`, `.settings`, `.applicator`); finished: the
    plans the robots run (`.plans`), made by finish(planner plans, each part's caps per pass of
    its finished plan); built: the programs of the chosen allocation, built again by
    rebuild(finished plans). pool: a `paintcell.booth.booth_tasks.TaskPool` that plans a round's
    capped parts side by side (None: one after the other here; the same plans). max_cycle_s:
    the cell's cycle limit [s]: a round is kept while the cycle stays within it or grows by at
    most MAX_CYCLE_GROWTH (None: the growth only).

    The first round also sets each part's pace (`part_pace`): a part whose robots reach only a
    fraction of its speeds, deeper than the brush table makes up for, is planned again at
    that pace (`paced`), its caps kept."""
    plans0 = list(planned.plans)
    caps: list[dict[int, np.ndarray]] = [{} for _ in plans0]
    pace = [1.0] * len(plans0)
    cycle0 = built.cycle_s
    limit = max((1.0 + MAX_CYCLE_GROWTH) * cycle0, max_cycle_s or 0.0)
    rec: dict[str, Any] = {"rule": f"caps where a robot ran > 0.5 % slower than asked (at or "
                                   f"between samples), re-planned at most {rounds}×, a part "
                                   f"whose robots reach only a fraction of its speeds planned "
                                   f"again at that pace, kept if the cycle stays within "
                                   f"{limit:.2f} s", "rounds": []}
    fresh = [True] * len(plans0)       # a part's first caps on its plan at its pace
    for k in range(rounds + 1):
        # a part's first caps trust the brush table's lowest flow (`paintcell.motion.flow`)
        new_caps, counts, worst = parts_caps(plans0, finished.plans, reverse, built.jobs,
                                             built.static, caps, trust_floor=fresh)
        rnd: dict[str, Any] = {"capped_samples": int(sum(counts)), "max_deficit_pct": worst,
                               "cycle_s": built.cycle_s}
        rec["rounds"].append(rnd)
        if not any(counts) or len(rec["rounds"]) > rounds:
            break
        fresh = [False] * len(plans0)
        if k == 0:
            pace = [part_pace(plans0[i], new_caps[i]) for i in range(len(plans0))]
            rnd["paced"] = {names[i]: round(x, 3) for i, x in enumerate(pace) if x < 1.0}
            # a paced part is planned again at its pace, under the caps, its flow turned down
            # by the pace (the same film); what its robots reach on that plan is measured
            # in the next round as on a first plan (trusting the lowest flow)
            for i, x in enumerate(pace):
                if x < 1.0:
                    counts[i], fresh[i] = max(counts[i], 1), True
        trial = list(plans0)
        rnd["replanned"] = []
        capped = [i for i, n in enumerate(counts) if n]
        args = []
        for i in capped:
            st = paced(planned.settings[i], pace[i])
            app = planned.applicator if pace[i] == 1.0 else planned.applicator.scaled(pace[i])
            args.append((planned.skins[i], app, st,
                         {k: np.where(np.isfinite(v), v, st.v_max_m_s)
                          for k, v in new_caps[i].items()}))
        for i, got in zip(capped, map_tasks(replan_capped, args, pool), strict=True):
            why = str(got) if isinstance(got, PaintcellError) else (
                "other passes" if [len(p.positions) for p in got.passes]
                != [len(p.positions) for p in plans0[i].passes] else None)
            if why is not None:        # the caps (or pace) do not fit this part's plan: keep it
                rnd.setdefault("failed", {})[names[i]] = why
                if k == 0 and pace[i] < 1.0:         # it keeps its planned speeds
                    pace[i], fresh[i] = 1.0, False
                    rnd["paced"].pop(names[i], None)
                continue
            assert not isinstance(got, PaintcellError)
            trial[i] = got
            rnd["replanned"].append(names[i])
        if not rnd["replanned"]:
            break
        try:
            fin2 = finish(trial, [stored_caps(trial[i], new_caps[i], rev)
                                  for i, rev in enumerate(reverse)])
            built2 = rebuild(fin2.plans)
        except PaintcellError as exc:           # the re-planned programs do not work: stop
            rnd["rejected"] = str(exc)
            break
        if built2.cycle_s > limit:
            rnd["rejected"] = (f"cycle {built2.cycle_s:.2f} s against {cycle0:.2f} s "
                               f"(limit {limit:.2f} s)")
            break
        plans0, caps, finished, built = trial, new_caps, fin2, built2
    rec["cycle_s"] = built.cycle_s           # the programs run (the tried table: before it)
    rec["capped_passes"] = {names[i]: sorted(int(k) for k in c) for i, c in enumerate(caps) if c}
    return finished, built, rec
