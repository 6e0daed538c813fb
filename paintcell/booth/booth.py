"""A paint booth: several robots, a car body of several library parts, a conveyor.

`Booth` declares the job like `paintcell.app.scenario.Scenario` does for one robot: the body's
parts and
where they sit in the body frame, the body's placement at conveyor position 0, the robots (model,
base — a rail robot's base is its rail frame —, home), the conveyor and the thresholds.
`paintcell.booth.booth_run.run_booth` runs it end to end; `paintcell check` runs a booth script
like any scenario script (`SCENARIO = Booth(...)`).

Allocation (`allocate`): the jobs are whole parts or two pieces of a part (its passes split at
a pass boundary); a part planned in patches may also be cut once inside each patch and at its
seams, so that one robot takes a wing of every patch (`job_options`). Every assignment of one
job per robot — each part whole or split, one robot per job — is enumerated (≤ a few hundred
for four robots) and the one chosen:
1. every job is reachable by its robot (closed-form IK feasibility of every pass: inside the
   limits, off the wrist singularity; a rail robot at its best rail position per pass);
2. the booth cycle — the longest robot's estimated program: paint time of its passes plus
   TURN_S per turn-around and APPROACH_RETRACT_S — is the smallest; ties go to the smallest
   second-longest program, and so on (lexicographic min-max: the work is spread evenly)
   (`rank_allocations`); the estimate knows nothing of start delays, so the best ranked
   (`booth_programs.MAX_ALLOCATIONS_TRIED`) are all built and staggered (step 3) and the one
   with the shortest REAL cycle — max over the robots of start delay + own program — is taken
   (ties: the better ranked);
3. no two bells in the same zone: the two pieces of a split part are painted in the same pass
   order and direction at the same time, so the two bells stay a piece's width apart; robots on
   neighbouring parts can still meet at the seam, so the programs are then staggered
   (`paintcell.booth.booth_stagger.stagger_starts`): start delays (a hold at home, in steps
   of STAGGER_STEP_S) that keep every robot's bell, wrist, elbow, shoulder and base
   `min_bell_distance_m` from every other robot's at every instant (checked every 20 ms), those
   of the shortest cycle (any robot may wait, not only the later ones). (Neighbouring parts whose
   passes run in step, `BodyPart.reverse`, need no delay.) The smallest bell-to-bell distance
   of the executed programs is checked against the same limit, and MuJoCo counts robot–robot
   contacts;
4. every program keeps `Booth.body_clearance_m` from the whole body, every part of it, not
   only its own (`paintcell.booth.booth_clearance`); a program that cannot is rejected with
   its allocation.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from paintcell.booth.booth_chain import job_record
from paintcell.booth.conveyor import Conveyor
from paintcell.core.errors import PaintcellError
from paintcell.core.placement import Placement
from paintcell.motion.moves import APPROACH_RETRACT_S, TURN_S
from paintcell.surface.part_spec import MeshPart
from paintcell.validation.paint_spec import PaintSpec

#: largest step between the carriage positions `pass_feasible` tries on a rail [m].
RAIL_STEP_M = 0.12
#: `Booth.seam_shares` values: one seam share for the whole body, or one per seam.
SEAM_SHARE_MODES = ("one", "per seam")


class BoothError(PaintcellError):
    """A booth is mis-specified or cannot be allocated."""


@dataclass(frozen=True)
class BoothRobot:
    """One robot of the booth.

    name: short label (reports, RAPID task names). model: `paintcell.robots.load_robot` name (a rail
    robot:
    "<arm>_rail"). base: base placement in the world (a rail robot: its rail frame; the carriage
    slides along the frame's +y). home: joint values [rad] (rail: [m] first) where its program
    starts and ends (None: the model's home). rail_m: (lower, upper) carriage travel of a rail
    robot [m] (None: `paintcell.robots.rail.RailSpec`'s ±2 m). carriage_m: (lower, upper) the
    stretch of its rail [m] the carriage keeps to while the body stands at its nominal place
    (the program as planned; None: the whole rail less the conveyor's travel). The conveyor
    tracking then moves every carriage by the same distance at each instant, so robots on one
    rail line whose stretches are disjoint keep their order and their distance.
    """

    name: str
    model: str = "irb5500"
    base: Placement = Placement()
    home: tuple[float, ...] | None = None
    rail_m: tuple[float, float] | None = None
    carriage_m: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not self.name or not all(c.isalnum() or c in "_-" for c in self.name):
            raise BoothError(f"robot name {self.name!r} must be letters, digits, '_' or '-'")
        from paintcell.robots.catalog import ROBOT_NAMES

        if self.model not in ROBOT_NAMES:
            raise BoothError(f"robot {self.name!r}: model {self.model!r} is not a known robot; "
                             f"valid: {', '.join(ROBOT_NAMES)}")
        r = self.rail_m
        if r is not None and not (isinstance(r, tuple | list) and len(r) == 2
                                  and all(isinstance(x, int | float) and not isinstance(x, bool)
                                          and np.isfinite(x) for x in r) and r[0] < r[1]):
            raise BoothError(f"robot {self.name!r}: rail_m = {r!r} must be (lower, upper) "
                             "carriage travel [m] with lower < upper")
        c = self.carriage_m
        if c is not None:
            travel = r if r is not None else (-2.0, 2.0)
            if not (len(c) == 2 and all(np.isfinite(x) for x in c)
                    and travel[0] <= c[0] < c[1] <= travel[1]):
                raise BoothError(f"robot {self.name!r}: carriage_m = {c!r} must be (lower, upper) "
                                 f"[m] with lower < upper inside its rail {tuple(travel)!r}")
            if self.home is not None and not c[0] <= self.home[0] <= c[1]:
                raise BoothError(f"robot {self.name!r}: home[0] = {self.home[0]:g} m lies off "
                                 f"its carriage stretch {tuple(c)!r} m; move it into the stretch")


@dataclass(frozen=True)
class BodyPart:
    """A part of the body and its placement in the body frame (x along the car).
    part: a library part name, or the label of a mesh/CAD part (its `MeshPart.stem`).
    reverse: run the part's passes in the reverse order and direction (the same film), e.g. so
    two robots on neighbouring parts sweep in step instead of meeting at the seam.
    robots: names of the robots that may paint it (None: any that reaches it).
    mesh: a mesh/CAD file part (the `[part]` table of a scenario,
    `paintcell.surface.part_spec.MeshPart`, its file resolved), or None for a library
    part."""

    part: str
    placement: Placement
    planner: dict[str, Any] = field(default_factory=dict)
    reverse: bool = False
    robots: tuple[str, ...] | None = None
    mesh: MeshPart | None = None


@dataclass(frozen=True)
class BoothThresholds:
    """Pass/fail limits of a booth run (None disables a check).

    max_collisions: robot–part, robot–booth and robot–robot (and self) collision events.
    max_robot_collisions: robot–robot collision events alone.
    max_executed_nsd_pct: executed film σ/μ of the worst part [%] (the whole body's is reported;
        it also measures how far the parts' planned film builds differ); it only tightens the
        paint spec's `max_nsd_pct` (`Booth.spec`).
    max_body_nsd_pct: executed film σ/μ over the whole body [%] (with a common film build,
        `Booth.common_film_build`, it measures the parts' edges and the robots' seams).
    max_seam_nsd_ratio: the executed film's σ/μ over the body's seams (its vertices near another
        part, `paintcell.booth.booth_seams.seam_band`) ÷ its σ/μ over the parts' interiors [-]:
        how much more uneven the paint is where two parts meet. A body with no seam (or no
        interior) fails it (the ratio is NaN): leave it unset there.
    max_abs_loss_pp: |executed − planned σ/μ| [pp]. max_cycle_time_s: booth cycle [s].
    min_bell_distance_m: smallest distance between two bells while both paint [m].
    max_torque_utilization: largest demanded/limit torque of any joint [-].
    max_joint_range_utilization: the largest |q − mid| / half-range of any robot's joint, its rail
        included (1 = on the MJCF limit, a hard stop) [-].
    reachability_pct: the least robot's honest reachability [%]
        (`paintcell.validation.honest_reach`: poses lost to IK, joint jumps, configuration flips,
        contacts and time-law slowdowns > 10 % count against it).
    """

    max_collisions: int | None = 0
    max_robot_collisions: int | None = 0
    max_executed_nsd_pct: float | None = 20.0
    max_body_nsd_pct: float | None = None
    max_seam_nsd_ratio: float | None = None
    max_abs_loss_pp: float | None = 1.0
    max_cycle_time_s: float | None = 120.0
    min_bell_distance_m: float | None = 0.8
    max_torque_utilization: float | None = 1.0
    max_joint_range_utilization: float | None = 1.0
    reachability_pct: float | None = 100.0


@dataclass(frozen=True)
class Booth:
    """A booth job (module doc). `robots` and `parts` are tuples; `trajectory` and `servo` hold
    `TrajectorySettings` / `ServoSettings` fields shared by all robots. `allocation` fixes the
    jobs instead of the automatic choice: {robot name: [part index, first pass, end pass]} (several
    jobs: a list of them).
    """

    name: str
    parts: tuple[BodyPart, ...]
    robots: tuple[BoothRobot, ...]
    body_placement: Placement = Placement()
    conveyor: Conveyor = Conveyor()
    resolution_m: float = 0.01
    fast_resolution_m: float = 0.025
    planner: dict[str, Any] = field(default_factory=dict)
    trajectory: dict[str, Any] = field(default_factory=dict)
    servo: dict[str, Any] = field(default_factory=dict)
    disturbances: dict[str, Any] = field(default_factory=dict)
    """`paintcell.execution.execute.Disturbances` fields the run executes under, as a
    one-robot scenario's `[disturbances]`: every robot's TCP and trigger, the body's placement
    on the skid, the paint flow and the servo gains (empty: the nominal cell)."""
    thresholds: BoothThresholds = BoothThresholds()
    allocation: dict[str, Any] | None = None
    max_jobs_per_robot: int = 1
    """Jobs one robot may run one after the other (`paintcell.booth.booth_chain`): > 1 lets
    a booth have more jobs than robots (e.g. a roof robot paints its piece of the roof, then
    of the hood)."""
    common_film_build: bool = True
    """Scale each part's bell flow so every part's planned mean film is one target
    (`paintcell.booth.booth_build`); False: each part at the default flow, its own film
    build."""
    film_target_um: float | None = None
    """The common film build [µm] (None: the body's area-weighted planned mean)."""
    spec: PaintSpec = PaintSpec()
    """The paint spec every part's executed film is held to (`[spec]`,
    `paintcell.validation.paint_spec`; its target by default `film_target_um`, else the body's
    planned mean film over the judged area);
    `thresholds.max_executed_nsd_pct` can only tighten its σ/μ."""
    body_clearance_m: float | None = 0.01
    """Every robot's program keeps this far [m] from the whole body, every part of it
    (`paintcell.booth.booth_clearance`: rail positions chosen clear of the body, backed-off
    moves, else the allocation is rejected); None: not checked before execution."""
    film_refine_pace: bool = False
    """Plan the parts without the planner's film refinement and refine each afterwards with
    every pass's duration held, so robots sweeping in step keep their pace
    (`paintcell.coverage.film_refine.refine_parts`), then every part together against the
    body's film after the seam step, the durations free (`paintcell.booth.booth_plans.
    refine_body`: the changes left are small, under a second a pass); a part
    whose planner sets `film_refine = false` (the booth's `[planner]` or its own) is not
    refined at all, nor then the body."""
    robot_aware_speeds: bool = True
    """Measure each robot's program on its passes and re-plan the parts' speeds under what the
    robots reached where they ran slower than planned
    (`paintcell.motion.speed_feedback.robot_aware_parts`, as a one-robot run does); False: the
    plans as the planner made them."""
    blend_seams: bool = True
    """Switch off the samples that paint other parts more than their own
    (`paintcell.booth.booth_seams`)."""
    seam_shares: str = "one"
    """How the seams are blended (`blend_seams`): "one" share for the whole body, the one of
    `paintcell.coverage.patches.SEAM_SHARES` with the smallest whole-body planned σ/μ; "per
    seam": each seam between two parts its own share, by coordinate descent from that one
    (`paintcell.booth.booth_seams.per_seam_shares`; only paint switches, the motion is the
    same)."""
    source: str | None = None
    applicator: str | None = None
    """Path to the bell's applicator TOML shared by all robots (None: the default bell)."""
    sweep: dict[str, Any] = field(default_factory=dict)
    """The `paintcell sweep` table (`paintcell.validation.sweep_spec.SCENARIO_KEYS`); a booth sweep
    varies a one-robot cell's factors on every robot and the line speed
    (`paintcell.sweeps.sweep_worker`)."""

    def __post_init__(self) -> None:
        if not self.parts or not self.robots:
            raise BoothError("a booth needs at least one part and one robot")
        names = [r.name for r in self.robots]
        if len(set(names)) != len(names):
            raise BoothError(f"robot names must be unique, got {names}")
        for p in self.parts:
            if p.robots is not None and (bad := sorted(set(p.robots) - set(names))):
                raise BoothError(f"part {p.part!r} names robot(s) {bad}; robots are {names}")
        if self.seam_shares not in SEAM_SHARE_MODES:
            raise BoothError(f"seam_shares = {self.seam_shares!r} must be one of "
                             f"{', '.join(repr(m) for m in SEAM_SHARE_MODES)}")
        if not isinstance(self.conveyor, Conveyor):
            raise BoothError("Booth.conveyor must be a paintcell.booth.conveyor.Conveyor")

    @property
    def part(self) -> str:
        """Label of the body (the `check` table's part column)."""
        return "+".join(p.part for p in self.parts)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description."""
        return asdict(self)


@dataclass(frozen=True)
class Job:
    """Passes [first, end) of part `part` (index into `Booth.parts`)."""

    part: int
    first: int
    end: int


def job_options(n_passes: list[int], patches: list[list[int] | None] | None = None
                ) -> list[list[list[Job]]]:
    """Per part, its ways of being cut into jobs: whole, or two pieces at any pass boundary.

    patches: per part, the pass counts of its patches in execution order (`patch_pass_counts`;
    None: one pass family). A part of several patches may also be cut once inside each patch
    and at any of the seams between patches (a robot can then take one wing of every patch). The
    options are closed under dropping a cut, so two adjacent pieces on one robot are always
    dominated by their union (`booth_chain.assign_job_lists` skips them)."""
    out = []
    for p, n in enumerate(n_passes):
        opts = [[Job(p, 0, n)]] + [[Job(p, 0, k), Job(p, k, n)] for k in range(1, n)]
        counts = None if patches is None else patches[p]
        if counts is not None and len(counts) > 1:
            ends = np.cumsum(counts)
            starts = ends - np.asarray(counts)
            inside = [[()] + [(int(k),) for k in range(a + 1, b)]
                      for a, b in zip(starts, ends, strict=True)]
            seams = [((), (int(k),)) for k in ends[:-1]]
            seen = {tuple((j.first, j.end) for j in o) for o in opts}
            for pick in itertools.product(*inside, *seams):     # tens to hundreds
                cuts = [0, *sorted(k for c in pick for k in c), n]
                key = tuple(zip(cuts[:-1], cuts[1:], strict=True))
                if key not in seen:
                    seen.add(key)
                    opts.append([Job(p, a, b) for a, b in key])
        out.append(opts)
    return out


def patch_pass_counts(plan: Any) -> list[int] | None:
    """The pass counts of a patch plan's patches in execution order
    (`paintcell.coverage.patches`' report), or None for one pass family."""
    rep = (plan.settings or {}).get("report", {}) if isinstance(plan.settings, dict) else {}
    if "patches" not in rep or "order" not in rep:
        return None
    counts = [int(rep["patches"][k]["passes"]) for k in rep["order"]]
    return counts if len(counts) > 1 and sum(counts) == len(plan.passes) else None


def rank_allocations(n_robots: int, n_passes: list[int], durations: list[np.ndarray],
                     reachable: Any, max_jobs_per_robot: int = 1,
                     patches: list[list[int] | None] | None = None
                     ) -> tuple[list[dict[int, tuple[Job, ...]]], dict[str, Any]]:
    """Every feasible allocation of the module doc, best first.

    n_passes: per part, its number of passes; patches: per part, its patches' pass counts
    (`job_options`; None: whole or two pieces only); durations: per part, (P,) planned pass
    times [s];
    reachable(robot, job) -> bool; max_jobs_per_robot: jobs one robot may run one after the
    other (its program: `paintcell.booth.booth_chain.chain_programs`). Returns the
    allocations ({robot index: its jobs in part order}), best first by lexicographic min-max of
    the estimated program times (a robot's: the sum of its jobs' `estimate_s`), and a record of
    the search. With more than one job per robot every robot gets a job and only the best
    `booth_chain.KEEP_RANKED` are kept (`booth_chain.assign_job_lists`)."""
    if max_jobs_per_robot < 1:
        raise BoothError(f"max_jobs_per_robot must be >= 1, got {max_jobs_per_robot}")
    ranked: list[tuple[tuple[float, ...], int, dict[int, tuple[Job, ...]]]] = []
    n_considered = 0
    est_of: dict[Job, float] = {}
    serial = itertools.count()
    heap: list[Any] = []                      # the multi-job search's best kept
    for cut in itertools.product(*job_options(n_passes, patches)):
        jobs = [j for part_jobs in cut for j in part_jobs]
        for j in jobs:
            if j not in est_of:
                est_of[j] = estimate_s(durations[j.part][j.first:j.end])
        if max_jobs_per_robot == 1:
            if len(jobs) > n_robots:
                continue
            for robots in itertools.permutations(range(n_robots), len(jobs)):
                n_considered += 1
                if not all(reachable(r, j) for r, j in zip(robots, jobs, strict=True)):
                    continue
                est = [est_of[j] for j in jobs]
                # Lexicographic min-max: the longest program first, then the next longest, ...
                ranked.append((tuple(sorted(est, reverse=True)), next(serial),
                               {r: (j,) for r, j in zip(robots, jobs, strict=True)}))
        elif n_robots <= len(jobs) <= n_robots * max_jobs_per_robot:
            from paintcell.booth.booth_chain import assign_job_lists
            n_considered += assign_job_lists(n_robots, jobs, est_of, reachable,
                                             max_jobs_per_robot, heap, serial)
    ranked += [item[2] for item in heap]
    if not ranked:
        raise BoothError(f"no allocation puts every part within reach ({n_considered} "
                         "candidates); move the robots or add one")
    ranked.sort(key=lambda c: (c[0], c[1]))

    record = {"rule": "every job reachable, split parts swept in step; ranked by "
                      "lexicographic min-max of the estimated program times; of the best "
                      "ranked, the one whose programs, staggered to keep the arms apart, give "
                      "the shortest real cycle is taken",
              "max_jobs_per_robot": max_jobs_per_robot,
              "candidates": n_considered, "feasible": len(ranked),
              "estimated_cycle_s": ranked[0][0][0], "estimated_programs_s": list(ranked[0][0]),
              "best_ranked": [{"estimated_programs_s": list(c[0]),
                               "jobs": {r: job_record(js) for r, js in c[2].items()},
                               "estimated_s": {r: sum(est_of[j] for j in js)
                                               for r, js in c[2].items()}}
                              for c in ranked[:8]]}
    return [c[2] for c in ranked], record


def allocate(n_robots: int, n_passes: list[int], durations: list[np.ndarray],
             reachable: Any) -> tuple[dict[int, tuple[Job, ...]], dict[str, Any]]:
    """The best allocation of `rank_allocations` and its record."""
    ranked, record = rank_allocations(n_robots, n_passes, durations, reachable)
    return ranked[0], record


def estimate_s(pass_durations: np.ndarray) -> float:
    """Estimated program time of a job [s]: paint + turn-arounds + approach and retract."""
    return float(np.sum(pass_durations) + TURN_S * max(len(pass_durations) - 1, 0)
                 + APPROACH_RETRACT_S)


def pass_feasible(robot: Any, T_world_tcp: np.ndarray) -> bool:
    """Whether one pass is feasible for the robot in closed form on every pose: some branch
    inside the limits, off the wrist singularity, without a joint jump (a rail robot: at some
    carriage position at most RAIL_STEP_M from the next tried), as planned or with the bell
    half-turned about its axis (`paintcell.robots.paths`: the same film). A subsample of the
    pass screens (`paintcell.robots.rail.search_poses`); what it passes is confirmed on the
    whole pass."""
    from paintcell.core.transforms import half_turned

    return _held(robot, T_world_tcp) or _held(robot, half_turned(T_world_tcp))


def _held(robot: Any, T_world_tcp: np.ndarray) -> bool:
    """`pass_feasible` for the pass's frames as given."""
    from paintcell.robots.ik import IKSettings, branch_feasibility, opw_branches
    from paintcell.robots.rail import feasible_positions, search_poses, travel_m

    settings = IKSettings()
    if getattr(robot, "rail", None) is not None:
        lo, hi = travel_m(robot)
        # carriage positions at most RAIL_STEP_M apart (21 on a rail up to 2.4 m long)
        n = max(21, int(np.ceil((hi - lo) / RAIL_STEP_M - 1e-9)) + 1)
        return bool(feasible_positions(robot, T_world_tcp, np.linspace(lo, hi, n),
                                       robot.rail.arm.q_home, settings, need="any").any())
    if robot.opw is None:
        raise BoothError(f"{robot.name}: booth allocation needs closed-form IK (abb_paint, "
                         "irb5500 or their _rail variants)")
    sub, js = search_poses(T_world_tcp)
    for T, scale in ((sub, js), (T_world_tcp, 1.0)):
        Q, _, within = opw_branches(robot, T, robot.q_home)
        if not branch_feasibility(robot, Q, within, settings, scale).feasible.any():
            return False
    return True


def arm_points(robot: Any, q: np.ndarray) -> np.ndarray:
    """(K, 5, 3) world positions [m] of the bell (TCP), the wrist centre (joint5), the elbow
    (joint3), the shoulder (joint2) and the base (joint1: a raised robot's foot, which the arms
    below it can reach) of `robot` at joint values q (K, n)."""
    import pinocchio as pin

    m, d = robot.pin_model, robot.pin_model.createData()
    ids = [m.getJointId(f"joint{j}") for j in (5, 3, 2, 1)]
    out = np.empty((len(q), 1 + len(ids), 3))
    for k, qk in enumerate(q):
        pin.forwardKinematics(m, d, qk)
        out[k, 0] = pin.updateFramePlacement(m, d, robot.tcp_frame_id).translation
        for j, jid in enumerate(ids):
            out[k, 1 + j] = d.oMi[jid].translation
    return out
