"""`paintcell init`'s cell of several robots, for a part that no one robot reaches: the part laid
crown up, N rail robots along its long axis (N = 2, then more up to `MAX_ROBOTS`), the booth's
automatic allocation splitting the passes (`paintcell.booth.booth.rank_allocations`), and the
booth's own checks before anything is written (`paintcell.booth.booth_programs.booth_programs`:
every program built, swept through the part's collision model, the robots staggered apart).

- The part lies crown up: its painted side up (world +z), the direction along which its skin's
  normals turn least (an arch's straight axis: the planner's zero-curvature passes run along it)
  along world x, the rails. A rotation within `SNAP_DEG` of the file's own axes keeps the file's
  axes (scans and CAD are drawn square to the part). Its lowest point `PART_LOW_Z_M` above the
  floor.
- The robots: `ARM` (the longest-reaching arm paintcell ships with the closed-form IK the
  booth's allocation needs) on rails parallel to x, half of them on each side (+y first),
  facing the part, each side's rails sharing the part's length. Rail frames are tried on a grid
  of gaps beside the part (`RAIL_GAPS_M`) and drops below its top (`RAIL_DROPS_M`), in that
  order; a frame is a candidate when every pass is reached by some robot (closed-form
  feasibility, `pass_feasible`), an allocation exists, and at home (carriage at both ends and
  the middle of its travel) every arm keeps `HOME_CLEARANCE_M` from the part (the booth's
  `BodyProbe`, MuJoCo's distance between the execution's collision geoms) and its bell, wrist,
  elbow, shoulder and base keep the booth's bell distance from every other robot's.
- The plan: the planner tables of `PLANNER_TRIES` in turn, the first whose longest pass over the
  part is at most `LONG_PASS_FACTOR` × the part's length along the rails (passes that run round
  the part leave a rail robot's reach) and whose film, planned as `run` plans it (film refined),
  is within the spec init writes (σ/μ), for 2 robots, then more; when no such table makes a cell
  with any count, those over it in turn, the most even first. Candidates are then checked, at
  most `LAYOUTS_VERIFIED` per plan, with each `TRAJECTORY_TRIES` table, by the booth's own
  program build (IK, moves, body clearance, staggering); the first that builds with no pose after
  a joint jump (the IK report's threshold; a frame built with one does not count toward
  `LAYOUTS_VERIFIED`, and its other trajectory tables are not tried: the poses are the frame's)
  is the cell, else the first that builds. The check runs on the plan without the film
  refinement and the robot-aware speeds that `run` adds (both re-time the same passes; the
  refinement's least squares over the whole part is most of a cowling's plan time).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from paintcell.app.init_toml import SPEC
from paintcell.core.errors import PaintcellError

__all__ = ["MAX_ROBOTS", "MultiCell", "choose_layout", "crown_up", "layout_problem", "rail_angle",
           "rail_robots"]

#: Most robots `init` lays out around one part.
MAX_ROBOTS = 4
#: The arm on every rail: 2.975 m reach and closed-form IK (the booth's allocation needs it).
ARM = "irb5500"
#: Gap between the part's side and a rail frame, horizontally [m], tried in this order.
RAIL_GAPS_M = (1.3, 1.0, 1.6)
#: Drop of a rail frame below the part's top [m], tried in this order (for each gap).
RAIL_DROPS_M = (0.45, 0.8, 0.1)
#: Carriage travel either side of a rail's middle [m]: with more the carriage jumps end to end
#: between a wing's passes and the forearm sweeps through the wing (crs_cowling_3_holes).
RAIL_HALF_TRAVEL_M = 0.6
#: Home of every rail robot: carriage at 0, then joints 1–6 [rad] (the arm folded back, the
#: bell high over its base).
HOME = (0.0, 0.0, -0.6, 0.3, 0.0, 0.9, 0.0)
#: Lowest point of the part above the floor [m].
PART_LOW_Z_M = 1.0
#: A rotation within this of the file's own axes keeps them [deg].
SNAP_DEG = 15.0
#: At home every arm keeps at least this from the part [m].
HOME_CLEARANCE_M = 0.1
#: A plan whose longest pass over the part exceeds this × the part's length along the rails is
#: not tried.
LONG_PASS_FACTOR = 2.0
#: How the notes on the planner tables begin (the cell's why keeps them, not the layouts').
_TABLE_NOTES = ("planner table", "the planner table")
#: Candidate layouts whose programs are built, per plan.
LAYOUTS_VERIFIED = 2
#: Planner tables tried in turn (passes along the rails; slower than the defaults because the
#: arms' J2/J3 accelerations limit the time law on an arch's wings). The first carries passes
#: 0.5 m past the part's ends (a tongue beyond a notch gets its film) and starts them mid-part
#: (a nearly developable arch's curvature divider wanders with scan noise); the second plans in
#: patches, straight passes per patch, for a part whose one-family passes run round it; the
#: third lays the passes along the rails themselves (`RAIL_AXIS`: the angle of the part's
#: straight axis about its mean normal), for a part whose zero-curvature direction is not its
#: straight axis (a bumper fascia: flat across its front, wrapping 120–160° at its corners, its
#: zero-curvature passes run round the wrap, 1.6 m, over a 0.45 m straight axis).
RAIL_AXIS = "along the rails"
PLANNER_TRIES: tuple[dict[str, Any], ...] = (
    {"orientation": "zero-curvature", "v_nominal_m_s": 0.4, "overspray_m": 0.5,
     "start_position": 0.5},
    {"orientation": "zero-curvature", "patches": True, "v_nominal_m_s": 0.3,
     "v_max_m_s": 0.45},
    {"orientation": RAIL_AXIS, "v_nominal_m_s": 0.3, "v_max_m_s": 0.45})
#: `[trajectory]` tables tried in turn: a 0.3 m retract, then 0.15 m (backed off 0.3 m from a
#: pass on a wing's lower edge, the via pose can leave the joint limits); then both with the
#: bell's roll following the travel (`keep_roll = false`: another arm pose on every other
#: pass, which two arms close over a small part may need to keep apart and off the part).
TRAJECTORY_TRIES: tuple[dict[str, Any], ...] = (
    {"approach_clearance_m": 0.15, "retract_clearance_m": 0.3},
    {"approach_clearance_m": 0.15, "retract_clearance_m": 0.15},
    {"approach_clearance_m": 0.15, "retract_clearance_m": 0.3, "keep_roll": False},
    {"approach_clearance_m": 0.15, "retract_clearance_m": 0.15, "keep_roll": False})
#: `[servo]` of the cell: gains from each joint's effective inertia (the IRB 5500's J3 loop
#: rings with the diagonal inertia in fast turn-arounds).
SERVO: dict[str, Any] = {"gain_inertia": "effective"}


@dataclass
class MultiCell:
    """The chosen cell: booth (`paintcell.booth.booth.Booth`, as `init` writes it, the part's
    file as given), planner and trajectory tables, gap and drop of the rails [m], the plan's pass
    count and whether it is a patch plan, why each choice was made (one line each: count,
    model, bases, plan, moves), and the poses of its programs after a joint jump."""

    booth: Any
    planner: dict[str, Any]
    trajectory: dict[str, Any]
    gap_m: float
    drop_m: float
    n_passes: int
    patches: bool
    why: dict[str, str] = field(default_factory=dict)
    jumps: int = 0
    planned_nsd_pct: float = float("nan")


def crown_up(surf: Any) -> tuple[np.ndarray, str]:
    """(R (3, 3) world-from-part rotation, why) laying the part crown up (module doc)."""
    skin = surf.region_surface(("skin",))
    v, f = skin.vertices, skin.faces
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])   # 2 × area · normal
    up = np.asarray(surf.regions.painted_direction, float)
    up = up / np.linalg.norm(up)
    P = np.eye(3) - np.outer(up, up)
    n = cross @ P                                   # normals' part across `up`
    M = P @ ((n / np.maximum(np.linalg.norm(cross, axis=1), 1e-30)[:, None]).T @ n) @ P
    w, vec = np.linalg.eigh(M + 1e6 * np.outer(up, up))   # `up` itself ranks last
    axis = vec[:, 0] * np.sign(vec[np.argmax(np.abs(vec[:, 0])), 0])   # its largest part > 0
    R = np.stack([axis, np.cross(up, axis), up])          # rows: world x, y, z in part axes
    best, best_deg = R, 180.0
    for cand in _axis_rotations():
        deg = np.degrees(np.arccos(np.clip((np.trace(cand.T @ R) - 1) / 2, -1, 1)))
        if deg < best_deg:
            best, best_deg = cand, deg
    if best_deg <= SNAP_DEG:
        return best, (f"painted side up, the skin's straight direction along the rails; "
                      f"{best_deg:.0f}° from the file's own axes, which are kept")
    return R, "painted side up, the skin's straight direction along the rails (world x)"


def rail_angle(surf: Any, R: np.ndarray) -> float:
    """The planner's orientation [rad] (`paintcell.coverage.start_curve`: the pass direction's
    angle about the skin's mean normal, from the part x axis projected) of passes along world
    x, the rails, for the part laid by `R` (3, 3) world-from-part; rounded to 1e-4 rad."""
    from paintcell.coverage.start_curve import average_normal, tangent_basis

    e1, e2 = tangent_basis(average_normal(surf.region_surface(("skin",))))
    a = float(np.arctan2(R[0] @ e2, R[0] @ e1)) % np.pi
    return round(a, 4) % round(np.pi, 4)


def _axis_rotations() -> list[np.ndarray]:
    """The 24 proper rotations that permute and flip the coordinate axes."""
    import itertools

    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            R[range(3), perm] = signs
            if np.linalg.det(R) > 0:
                out.append(R)
    return out


def rail_robots(n: int, lo: np.ndarray, hi: np.ndarray, gap_m: float, drop_m: float,
                model: str = ARM) -> list[Any]:
    """n `BoothRobot`s on rails along world x around the part's box [lo, hi] (world, m): the
    first ceil(n/2) on the +y side, the rest on −y, each side's rails centred on equal shares of
    the part's length, `gap_m` beside its box and `drop_m` below its top, the arm facing it."""
    from paintcell.booth.booth import BoothRobot
    from paintcell.core.placement import Placement

    out = []
    for side, count, y, yaw in ((+1, (n + 1) // 2, hi[1] + gap_m, -np.pi / 2),
                                (-1, n // 2, lo[1] - gap_m, np.pi / 2)):
        share = (hi[0] - lo[0]) / max(count, 1)
        for k in range(count):
            x = lo[0] + (k + 0.5) * share
            half = RAIL_HALF_TRAVEL_M if count == 1 else min(RAIL_HALF_TRAVEL_M, share / 2)
            name = ("left" if side > 0 else "right") + (f"_{k + 1}" if count > 1 else "")
            out.append(BoothRobot(name, f"{model}_rail",
                                  Placement((round(float(x), 4), round(float(y), 4),
                                             round(float(hi[2] - drop_m), 4)),
                                            (0.0, 0.0, float(yaw))),
                                  HOME, (-half, half)))
    return out


def choose_layout(name: str, mesh: Any, surf: Any, counts: tuple[int, ...], model: str = ARM,
                  say: Callable[[str], None] = print) -> MultiCell:
    """The first cell of `counts` robots (module doc) for the part `mesh` (its `MeshPart`, file
    resolved) imported as `surf` (part frame, fast resolution). Raises PaintcellError (one line:
    what each count met, and what to change) when none works up to the last count."""
    from scipy.spatial.transform import Rotation

    from paintcell.booth.booth import BodyPart, Booth
    from paintcell.booth.conveyor import Conveyor
    from paintcell.core.placement import Placement, triple

    R, why_pose = crown_up(surf)
    world = surf.vertices @ R.T
    lo0, hi0 = world.min(0), world.max(0)
    t = np.array([-(lo0[0] + hi0[0]) / 2, -(lo0[1] + hi0[1]) / 2, PART_LOW_Z_M - lo0[2]])
    lo, hi = lo0 + t, hi0 + t
    pl = Placement(triple(t, 4), triple(Rotation.from_matrix(R).as_euler("xyz")))
    length = float(hi[0] - lo[0])
    plans: dict[int, Any] = {}        # planner try → its part plans (or why it was skipped)
    nsd: dict[int, float] = {}        # planner try → σ/μ [%] of its film-refined plan's film
    uneven: set[int] = set()          # tables whose film is over the spec: tried last
    tried: dict[int, list[str]] = {n: [] for n in counts}
    for last_resort in (False, True):  # every count with the even tables, then with the uneven
        if last_resort and not uneven:
            break
        for n in counts:
            tried_n = tried[n]
            jumpy: MultiCell | None = None
            tables = sorted(uneven, key=lambda j: nsd[j]) if last_resort \
                else range(len(PLANNER_TRIES))
            for k in tables:
                planner = dict(PLANNER_TRIES[k])
                if planner["orientation"] == RAIL_AXIS:
                    planner["orientation"] = rail_angle(surf, R)
                part = BodyPart(mesh.stem, pl, {**planner, "film_refine": False}, mesh=mesh)
                booth = Booth(name=name, parts=(part,), robots=tuple(
                    rail_robots(n, lo, hi, 1.3, 0.45, model)), conveyor=Conveyor(
                        0.0, (1.0, 0.0, 0.0)), servo=dict(SERVO), robot_aware_speeds=False)
                if k not in plans:
                    say(f"init: planning the part with planner table {k + 1}: " + ", ".join(
                        f"{key} = {v}" for key, v in planner.items()))
                    got = _table_plans(booth, replace(part, planner=planner), k, length)
                    if isinstance(got, str):
                        plans[k] = got
                    else:
                        plans[k], nsd[k] = got
                        say(f"init: planner table {k + 1} lays {nsd[k]:.1f} % σ/μ on the skin "
                            "(fast plan, film refined)")
                if isinstance(plans[k], str):
                    tried_n.append(plans[k])
                    continue
                if not last_resort and nsd[k] > SPEC.max_nsd_pct:
                    tried_n.append(f"planner table {k + 1} lays a film of {nsd[k]:.1f} % σ/μ "
                                   f"(planned, refined), over the spec's {SPEC.max_nsd_pct:g} %")
                    uneven.add(k)
                    continue
                cell = _try_layouts(booth, plans[k], n, lo, hi, model, tried_n, say)
                if cell is not None:
                    cell.planner = dict(planner)
                    cell.why["pose"] = why_pose
                    cell.why["plan"] = "; ".join(t for t in tried_n if t.startswith(_TABLE_NOTES))
                    if last_resort:
                        cell.why["plan"] += (f"; no table within the spec makes a cell: table "
                                             f"{k + 1} kept, the most even of those that do")
                    cell.planned_nsd_pct = nsd[k]
                    if cell.jumps == 0:
                        return cell
                    jumpy = jumpy or cell
            if jumpy is not None:   # every cell built has a joint jump: the first of them
                return jumpy
    failed = [f"{n} robots: {'; '.join(t)}" for n, t in tried.items()]
    more = (f", or try `--robots N` with more robots (at most {MAX_ROBOTS})"
            if counts[-1] < MAX_ROBOTS else "")
    raise PaintcellError(
        f"no layout of {counts[0]} to {counts[-1]} {model} robots on rails paints {mesh.file}: "
        f"{' | '.join(failed)}; paint it in pieces (`--pieces`), or write the cell by hand (a "
        f"[[robots]] booth, as scenarios/crs_cowling_3_holes.toml){more}")


def _table_plans(booth: Any, refined_part: Any, k: int, length: float
                 ) -> tuple[Any, float] | str:
    """Planner table k's part plans (the booth's one part, film refinement off) and the σ/μ
    [%] over the skin of its film planned as `run` plans it (`refined_part`: film refinement
    on; it re-times the passes the geometry cache keeps), or why the table is no candidate."""
    from paintcell.app.init_verify import planned_nsd_pct
    from paintcell.booth.booth_plans import plan_part, plan_parts

    try:
        pp = plan_parts(booth, fast=True)
    except PaintcellError as exc:
        return f"the planner table {k + 1} fails ({str(exc).split(';')[0]})"
    longest = max(_pass_length(pp.plans[0], i) for i in range(len(pp.plans[0].passes)))
    if longest > LONG_PASS_FACTOR * length:
        return (f"planner table {k + 1}'s longest pass over the part is {longest:.1f} m, over "
                f"{LONG_PASS_FACTOR:.0f}× the part's {length:.2f} m along the rails")
    try:
        # the part's surface as read for the plan above (not read again)
        surf, _, _, run_plan = plan_part(replace(booth, parts=(refined_part,)), 0,
                                         booth.fast_resolution_m, pp.applicator, pp.surfaces[0])
    except PaintcellError as exc:
        return (f"the planner table {k + 1} fails with the film refinement "
                f"({str(exc).split(';')[0]})")
    return pp, planned_nsd_pct(run_plan, surf)


def _pass_length(plan: Any, i: int) -> float:
    """Length [m] of pass i's TCP path over the part (steps between two on-part samples): its
    run past the part's ends, the table's overspray, is no run round the part."""
    p = np.asarray(plan.passes[i].positions)
    on = np.asarray(plan.passes[i].on_part, bool)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    return float(step[on[1:] & on[:-1]].sum())


def _try_layouts(booth: Any, pp: Any, n: int, lo: np.ndarray, hi: np.ndarray, model: str,
                 tried: list[str], say: Callable[[str], None]) -> MultiCell | None:
    """The first rail layout of the grid whose programs the booth builds (module doc), or None
    (why each failed appended to `tried`)."""
    from paintcell.booth.booth import patch_pass_counts
    from paintcell.booth.booth_programs import booth_programs

    plan = pp.plans[0]
    patches = patch_pass_counts(plan) is not None
    jobs = 2 if patches else 1
    n_frames, verified, first_why = 0, 0, None
    jumpy: MultiCell | None = None
    for gap in RAIL_GAPS_M:
        for drop in RAIL_DROPS_M:
            if verified == LAYOUTS_VERIFIED:
                break
            n_frames += 1
            robots = rail_robots(n, lo, hi, gap, drop, model)
            cand = replace(booth, robots=tuple(robots), max_jobs_per_robot=jobs)
            problem, reach = layout_problem(cand, pp)
            if problem is not None:
                first_why = first_why or f"gap {gap} m, drop {drop} m: {problem}"
                continue
            verified += 1
            for traj in TRAJECTORY_TRIES:
                say(f"init: building the programs of {n} robots, rails {gap} m beside the part "
                    f"and {drop} m below its top, {traj}")
                try:
                    progs = booth_programs(replace(cand, trajectory=dict(traj)), True, pp)
                except PaintcellError as exc:
                    first_why = first_why or (f"gap {gap} m, drop {drop} m: "
                                              f"{str(exc).split('; ')[0][:200]}")
                    continue
                cell = _cell(cand, traj, gap, drop, len(plan.passes), patches, reach, progs)
                if cell.jumps == 0:
                    return cell
                first_why = first_why or (f"gap {gap} m, drop {drop} m: {cell.jumps} poses "
                                          "after a joint jump")
                jumpy = jumpy or cell
                verified -= 1       # the poses are the frame's: the next frame, not counted
                break
    if jumpy is not None:
        tried.append(f"{n_frames} rail frames, every one built with a joint jump")
        return jumpy
    tried.append(f"{n_frames} rail frames, {verified} built"
                 + (f" (first: {first_why})" if first_why else ""))
    return None


def layout_problem(booth: Any, pp: Any) -> tuple[str | None, list[int]]:
    """(why the layout is no candidate, or None; the passes each robot reaches in closed form)."""
    from paintcell.booth.booth import (
        BoothError,
        arm_points,
        pass_feasible,
        patch_pass_counts,
        rank_allocations,
    )
    from paintcell.booth.booth_clearance import BodyProbe
    from paintcell.booth.booth_plans import finish_plans
    from paintcell.booth.booth_programs import load_robots

    plan = finish_plans(booth, pp, pp.plans).plans[0]
    robots = load_robots(booth)
    T = booth.body_placement.matrix @ booth.parts[0].placement.matrix
    ok = np.array([[pass_feasible(r, T @ plan.tcp_frames(i)) for i in range(len(plan.passes))]
                   for r in robots])
    reach = [int(x) for x in ok.sum(1)]
    if not ok.any(0).all():
        return f"{int((~ok.any(0)).sum())} of {len(plan.passes)} passes out of every robot's " \
               "reach", reach
    durations = [np.array([p.duration_s for p in plan.passes])]
    try:
        rank_allocations(len(robots), [len(plan.passes)], durations,
                         lambda r, j: bool(ok[r, j.first:j.end].all()),
                         booth.max_jobs_per_robot, [patch_pass_counts(plan)])
    except BoothError:
        return "no allocation gives every robot passes it reaches", reach
    homes = []
    for r, br in zip(robots, booth.robots, strict=True):
        q = np.array([[s, *HOME[1:]] for s in (br.rail_m[0], 0.0, br.rail_m[1])])
        probe = BodyProbe(r, pp.surfaces[0], T, np.zeros(len(pp.surfaces[0].vertices), int))
        d = probe.distance(q, HOME_CLEARANCE_M)
        if d < HOME_CLEARANCE_M:
            return f"{br.name} at home comes {d * 1e3:.0f} mm from the part", reach
        homes.append(arm_points(r, q))
    limit = booth.thresholds.min_bell_distance_m or 0.0
    for a in range(len(homes)):
        for b in range(a + 1, len(homes)):
            gap = float(np.linalg.norm(homes[a][:, None, :, None] - homes[b][None, :, None],
                                       axis=-1).min())
            if gap < limit:
                return (f"{booth.robots[a].name} and {booth.robots[b].name} at home come "
                        f"{gap:.2f} m apart (< {limit} m)"), reach
    return None, reach


def _cell(booth: Any, traj: dict[str, Any], gap: float, drop: float, n_passes: int,
          patches: bool, reach: list[int], progs: Any) -> MultiCell:
    """The chosen cell and why (module doc)."""
    names = [r.name for r in booth.robots]
    share = {names[r]: "+".join(f"{j.first}–{j.end - 1}" for j in js)
             for r, js in sorted(progs.jobs.items())}
    clear = progs.record.get("body_clearance", {})
    gaps = [c.get("min_distance_m") for c in clear.values() if isinstance(c, dict)]
    known = [float(g) for g in gaps if g is not None]
    gap_txt = (f"; every program keeps ≥ {min(known) * 1e3:.0f} mm from the part"
               if known and len(known) == len(gaps) else "")
    why = {
        "reach": ", ".join(f"{nm} reaches {k} of {n_passes} passes" for nm, k in
                           zip(names, reach, strict=True)),
        "jobs": ", ".join(f"{nm} passes {s}" for nm, s in share.items()) + gap_txt,
        "delays": ", ".join(f"{d:.1f} s" for d in progs.record.get("start_delays_s", [])),
    }
    return MultiCell(replace(booth, robot_aware_speeds=True), {}, dict(traj), gap, drop,
                     n_passes, patches, why, sum(_jumps(t) for t in progs.static))


def _jumps(traj: Any) -> int:
    """Poses of a robot's program whose joints jump from the pose before by more than the IK
    report's threshold (the run counts them lost to a joint jump)."""
    rep = (traj.meta or {}).get("reachability") or {}
    jj = (rep.get("poses") or {}).get("joint_jump_rad") or []
    th = float(rep.get("thresholds", {}).get("max_joint_jump_rad", 0.2))
    return int(sum(1 for x in jj if x is not None and x > th))
