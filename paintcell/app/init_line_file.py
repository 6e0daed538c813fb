"""What `paintcell init BODY --line --takt T` writes: the body's panels as mesh files (binary STL in
metres, body frame, in `<out stem>_panels/` beside the booth file) and a booth TOML (the format of
`paintcell.booth.booth_data`: `[[parts]]` with `[parts.part]` tables, `[[robots]]` on rails, the
conveyor at the takt's speed, the fixed `[allocation]`), with a comment giving the reason for each
choice: the count, the kind and place of each robot, the conveyor speed, the allocation and each
robot's estimated program against the takt (`write_line`). Nothing is written unless the line
was laid out and verified (`paintcell.app.init_line.choose_line`); the panels are planned from
a temporary folder first.
"""

from __future__ import annotations

import json
import math
import tempfile
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.app.init_line import Line
from paintcell.booth.line_takt import UTILISATION
from paintcell.core.errors import PaintcellError
from paintcell.core.placement import triple
from paintcell.motion.moves import APPROACH_RETRACT_S, TURN_S

__all__ = ["init_body_line", "init_line", "line_toml"]

def _v(x: Any) -> str:
    return json.dumps(list(x) if isinstance(x, tuple) else x)


def _fill(text: str) -> str:
    return textwrap.fill(text, 96, initial_indent="# ", subsequent_indent="# ")


def line_toml(line: Line, files: Sequence[str], sides: Sequence[Sequence[float]],
              source: str, generated: dict[str, Any] | None = None) -> str:
    """The booth file of `line` (module doc); files: each panel's mesh file relative to the
    written file; sides: each panel's painted side (body frame); source: the body file named
    in the header; generated: the body generator's seed and read (`paintcell.surface.
    generated_body.generated_origin`) and each panel file's area [m²] ("areas_m2"), written as
    the `[generated_body]` table."""
    b, t = line.booth, line.takt
    names = [p.part for p in b.parts]
    rows = []
    for r, s, est, built, frame in zip(b.robots, line.shares, [s.program_s for s in line.shares],
                                       line.built_s, line.frames, strict=True):
        jobs = ", ".join(names[j.part] + ("" if j.first == 0 and j.end == line.n_passes[j.part]
                                           else f" passes {j.first}–{j.end - 1}")
                         for j in s.jobs)
        rows.append(f"{r.name}: {jobs}; program {est:.1f} s estimated, {built:.1f} s built, "
                    f"+ return {t.robot_cycle_s(built) - built:.1f} s = "
                    f"{t.robot_cycle_s(built):.1f} s ≤ takt {t.takt_s:g} s ({frame})")
    head = [
        f"Written by `paintcell init {source} --line --takt {t.takt_s:g}`: a paint line of "
        f"{len(b.robots)} robots for a body every {t.takt_s:g} s; every choice below is editable.",
        f"Conveyor: pitch = body length {t.body_length_m:.3f} m + gap {t.gap_m:g} m = "
        f"{t.pitch_m:.3f} m; speed = pitch / takt = {t.conveyor_speed_m_s:.5f} m/s "
        f"({t.conveyor_speed_m_s * 60:.2f} m/min).",
        f"Why {len(b.robots)} robots: the panels' programs total {line.total_s:.1f} s (paint at "
        f"each pass's planned speed + {TURN_S} s per turn-around + {APPROACH_RETRACT_S} s "
        f"approach and retract per job); a first estimate of ⌈total / (takt × {UTILISATION})⌉ "
        f"= {line.first_count}; the smallest count from there whose every robot's program plus "
        "its carriage's return home (the distance the body carried it, at the rail's 1.5 m/s, "
        "4 m/s²) fits the takt, every robot reaches its passes in closed form and the booth "
        "builds every program clear of the body with the arms staggered apart"
        + (f" (before it: {'; '.join(line.failed)})" if line.failed else "") + ".",
        "Which robots: IRB 5500 paint arms on rails along the conveyor (closed-form IK for the "
        "reach checks; the carriage tracks the body). Floor rails on each side (0.3 m up, else "
        "on a pedestal for passes high at the centre line) paint that side's panels and its "
        "half of each bumper fascia, cut at the car's centre line (a fascia's passes run up and "
        "down it, stepping across the car; its far half is beyond one side's reach); the top "
        "robots, wall-mounted 3 m up beside the body (above the floor robots' arms, as the IRB "
        "5500 is mounted in scenarios/booth.toml), else on elevated rails, paint the hood, roof "
        "and trunk and a fascia above the belt line (a tailgate), each cut at the centre line "
        "between the left and right top robots (the hood's and roof's passes run along the "
        "car). Each rail is centred on its robot's stretch of the car (robots of one zone at "
        "least 1.5 m apart) and reaches that stretch plus the body's travel while it paints and "
        "0.3 m at each end; a floor robot sharing its side parks at its stretch's end, a top "
        "robot past it and past the body's travel; then each robot in turn is tried parked at "
        "its station instead, kept where the booth verifies a shorter cycle (said in its line "
        "below). The floor robots of one side share its rail "
        "line: each carriage keeps to its own stretch of it as planned (`carriage`), at least "
        "1.5 m from its neighbour's, and the conveyor tracking moves every carriage alike, so "
        "they never pass each other; both run "
        "their panels front to rear, the top robots theirs rear to front.",
        "Allocation (fixed below, pass ranges of the plan at 0.025 m, which both resolutions "
        "use): by zone, each zone's jobs front to rear cut into contiguous runs of least longest "
        "program (bisection with a greedy fill; a panel cut once at a pass boundary when it "
        "does not fit whole), robots given to the zone with the longest program.",
        *rows,
        f"Verified booth cycle (one body, start delays "
        f"{', '.join(f'{d:.1f}' for d in line.record.get('start_delays_s', []))} s): "
        f"{line.cycle_s:.1f} s. Every carriage tracks the body to the cycle's end and all run "
        "back together (the body's travel over the cycle, so carriages of one rail line keep "
        "their order); the threshold is the longest cycle whose return still fits the takt: "
        f"{t.max_cycle_s():.2f} s + {t.robot_cycle_s(t.max_cycle_s()) - t.max_cycle_s():.2f} s "
        f"= {t.takt_s:g} s.",
        "The film: each panel refined with every pass's duration held (film_refine_pace), so "
        "the programs keep the durations estimated; then the passes a robot ran slower than "
        "asked are planned again under the speeds it reached (robot_aware_speeds = true; kept "
        "only while the cycle grows at most 5 %). The verification above did the same from "
        "the unrefined plans, so the run's programs and cycle can differ a little from the "
        "verified ones; the run checks its cycle against max_cycle_time_s. Each seam between "
        "two panels is blended at its own share (seam_shares = \"per seam\": a door next to "
        "the roof and a fender next to a door want different ones; only paint switches), then "
        "every panel's passes are re-timed together against the body's film (the durations "
        "free this time: each pass moves by a fraction of a second)."]
    text = "\n".join(_fill(h) for h in head)
    parts = ""
    for f, side, bp in zip(files, sides, b.parts, strict=True):
        planner = "".join(f"{k} = {_v(v)}\n" for k, v in bp.planner.items())
        rev = ("reverse = true   # its passes top to bottom (paintcell.app.init_line.top_first)"
               "\n" if bp.reverse else "")
        parts += f"""
[[parts]]
xyz_m = [0.0, 0.0, 0.0]
rpy_rad = [0.0, 0.0, 0.0]
{rev}[parts.part]
file = {_v(f)}   # relative to this file; the body frame, metres
units = "m"
pieces = "all"
side = {_v([round(float(x), 6) for x in side])}
"""
        parts += (f"[parts.planner]   # the passes' direction (module doc of "
                  f"paintcell.app.init_line)\n{planner}" if planner else "")
    robots = ""
    # angles written exactly: a rail off the line's direction by round-off leaves the conveyor's
    # motion across it to the arm's IK (`paintcell.booth.conveyor.track_program`)
    for r in b.robots:
        x, y, z = r.base.xyz_m
        carriage = "" if r.carriage_m is None else (
            f"# its own stretch of the side's rail line as planned (the body at its place)\n"
            f"carriage = {_v([round(v, 4) for v in r.carriage_m])}\n")
        robots += f"""
[[robots]]
name = {_v(r.name)}
model = "irb5500"
rail = {_v([round(v, 4) for v in r.rail_m])}
{carriage}home = {_v(list(r.home))}
# rail frame at x = {x:.2f} m, {abs(y):.2f} m {'left (+y)' if y > 0 else 'right (−y)'}, {z:.2f} m
# up; the arm faces the body, the carriage runs along the conveyor
[robots.base]
xyz_m = {_v([round(v, 4) for v in r.base.xyz_m])}
rpy_rad = {_v([float(v) for v in r.base.rpy_rad])}
"""
    gen = ""
    if generated:
        how = ("its one mesh, the panels found from the gaps" if generated["read"] == "mesh"
               else "its panel folder's body.json")
        why = (f"The panels are those of `paintcell generate body --seed {generated['seed']}` "
               f"read from {how}: a panel file missing or changed (its area) is written again "
               "from the generator, so the line needs no mesh files beside it.")
        gen = (f"\n{_fill(why)}\n[generated_body]\nseed = {generated['seed']}\n"
               f"read = {_v(generated['read'])}\n"
               f"areas_m2 = {_v([float(a) for a in generated['areas_m2']])}\n")
    alloc = "".join(f"{name} = {_v([list(j) for j in jobs])}\n"
                    for name, jobs in b.allocation.items())
    traj = "".join(f"{k} = {_v(v)}\n" for k, v in b.trajectory.items())
    cycle = math.floor(t.max_cycle_s() * 100) / 100
    seam = (f"max_seam_nsd_ratio = {b.thresholds.max_seam_nsd_ratio}\n"
            if b.thresholds.max_seam_nsd_ratio is not None else
            "# (no max_seam_nsd_ratio: no two panels meet, so the body has no seam to judge)\n")
    return f"""{text}
name = {_v(b.name)}
resolution_m = {b.fast_resolution_m}
fast_resolution_m = {b.fast_resolution_m}
film_refine_pace = true
robot_aware_speeds = true
seam_shares = "per seam"

# the body frame at conveyor position 0: lifted on its skid so its lowest pass is 0.6 m up
[body_placement]
xyz_m = {_v(list(b.body_placement.xyz_m))}
rpy_rad = [0.0, 0.0, 0.0]

{gen}
# pitch {t.pitch_m:.4f} m / takt {t.takt_s:g} s
[conveyor]
speed_m_s = {t.conveyor_speed_m_s!r}
direction = [1.0, 0.0, 0.0]
{parts}{robots}
# robot = [[panel index, first pass, end pass], ...], run one after the other
[allocation]
{alloc}
[trajectory]
{traj}
# gains from each joint's effective inertia (the IRB 5500's J3 loop rings with the diagonal
# inertia in fast turn-arounds)
[servo]
gain_inertia = "effective"

[thresholds]
reachability_pct = 100.0
max_collisions = 0
max_robot_collisions = 0
min_bell_distance_m = {b.thresholds.min_bell_distance_m}
max_cycle_time_s = {cycle}
# the film: every panel's executed σ/μ [%], the whole body's [%], and the seams' σ/μ over the
# panels' interiors' [-]
max_executed_nsd_pct = {b.thresholds.max_executed_nsd_pct}
max_body_nsd_pct = {b.thresholds.max_body_nsd_pct}
{seam}"""


def panels_meet(surfaces: Sequence[Any]) -> bool:
    """Whether the panels (surfaces in the body frame) have seams to judge: some vertex within
    `paintcell.booth.booth_seams.SEAM_BAND_M` of another panel, and some vertex farther than
    that (the interior the seams are judged against)."""
    from paintcell.booth.booth_seams import seam_band

    band = seam_band(np.concatenate([np.asarray(s.vertices, float) for s in surfaces]),
                     [len(s.vertices) for s in surfaces])
    return bool(band.any() and not band.all())


def init_line(panels: Sequence[Any], out: Path, takt_s: float, max_robots: int, force: bool,
              source: str, name: str | None = None, say: Callable[[str], None] = print,
              generated: dict[str, Any] | None = None) -> Line:
    """Lay out, verify and write the line for `panels` (`paintcell.surface.body_panels.BodyPanel`s:
    `name`, `mesh` — a trimesh in metres, body frame — and `direction`, toward the painter) to
    `out` (module doc); generated: the body generator's {"seed", "read"} when the panels are its
    body (`paintcell.surface.generated_body.generated_origin`: the file then carries a
    `[generated_body]` table). Raises PaintcellError (one line) with nothing written when no
    line up to `max_robots` makes the takt."""
    from dataclasses import replace

    from paintcell.app.init_line import choose_line, panel_booth
    from paintcell.booth.booth_plans import plan_parts
    from paintcell.booth.line_allocation import check_body_frame
    from paintcell.booth.line_takt import LineTakt
    from paintcell.core.atomic_io import atomic_path, atomic_write_text
    from paintcell.core.safe_paths import check_new_target
    from paintcell.surface.generated_body import file_area_m2
    from paintcell.surface.part_spec import MeshPart

    if out.suffix != ".toml":
        raise PaintcellError(f"--out {out}: a booth file ends in .toml")
    check_new_target(out, "--out", force)
    folder = out.parent / f"{out.stem}_panels"
    if folder.exists() and (not folder.is_dir() or folder.is_symlink() or not force):
        raise PaintcellError(f"{folder} exists (the panels' folder of --out {out}); pass --force "
                             "to replace its panel files, or choose another --out")
    if not panels:
        raise PaintcellError(f"{source} holds no panel; give a body file with panels")
    stems = [f"{i:02d}_" + "".join(c if c.isalnum() or c in "_-" else "_" for c in str(p.name))
             for i, p in enumerate(panels)]
    verts = np.concatenate([np.asarray(p.mesh.vertices, float) for p in panels])
    check_body_frame(verts.min(0), verts.max(0), [p.direction for p in panels],
                     [np.asarray(p.mesh.vertices, float).mean(0) for p in panels])
    takt = LineTakt(float(takt_s), float(np.ptp(verts[:, 0])))
    name = name or "".join(c if c.isalnum() or c in "_-" else "_" for c in out.stem)
    sides = [triple(p.direction) for p in panels]
    with tempfile.TemporaryDirectory(prefix="paintcell-line-") as tmp:
        specs = []
        for stem, p, side in zip(stems, panels, sides, strict=True):
            f = Path(tmp) / f"{stem}.stl"
            p.mesh.export(f, file_type="stl")
            specs.append(MeshPart(file=str(f), units="m", pieces="all", side=side))
        booth = panel_booth(name, specs, takt)
        say(f"init: planning {len(specs)} panels (fast resolution, no film refinement)")
        pp = plan_parts(booth, fast=True)
        line = choose_line(booth, pp, takt, max_robots, say=say)
        if not panels_meet(pp.surfaces):     # no seam to judge: the seams' check left out
            line.booth = replace(line.booth, thresholds=replace(line.booth.thresholds,
                                                                max_seam_nsd_ratio=None))
        check_new_target(out, "--out", force)
        folder.mkdir(parents=True, exist_ok=True)
        rel = []
        for stem, spec in zip(stems, specs, strict=True):
            with atomic_path(folder / f"{stem}.stl") as dst:
                dst.write_bytes(Path(spec.file).read_bytes())
            rel.append(f"{folder.name}/{stem}.stl")
        line.booth = replace(line.booth, parts=tuple(
            replace(bp, planner={k: v for k, v in bp.planner.items() if k != "film_refine"},
                    mesh=replace(bp.mesh, file=str(folder / f"{stem}.stl")))
            for bp, stem in zip(line.booth.parts, stems, strict=True)))
        gen = None if generated is None else {
            **generated, "areas_m2": [file_area_m2(spec.file) for spec in specs]}
        atomic_write_text(out, line_toml(line, rel, sides, source, gen))
    return line


def init_body_line(body: Path, out: Path, takt_s: float | None, max_robots: int, force: bool,
                   name: str | None, line_flag: bool, robot_options: bool) -> str:
    """`paintcell init BODY --line --takt T`: the options checked (one line each), the body read
    (`paintcell.surface.body_panels.load_body`), the line laid out and written; what to print."""
    from paintcell.core.safe_paths import check_new_target
    from paintcell.surface.body_panels import load_body
    from paintcell.surface.generated_body import generated_origin

    if not line_flag or takt_s is None:
        raise PaintcellError("--line and --takt go together: write `paintcell init BODY --line "
                             "--takt 75 --out line.toml` (a body every 75 s)")
    if robot_options:
        raise PaintcellError("--robot/--robots do not apply to --line (its robots are IRB 5500s, "
                             "their count from --takt); use --max-robots N")
    check_new_target(out, "--out", force)    # before minutes of planning
    panels = load_body(body)
    line = init_line(panels, out, takt_s, max_robots, force, str(body), name,
                     generated=generated_origin(body, panels))
    t = line.takt
    return (f"line: {len(line.booth.robots)} robots for a body every {t.takt_s:g} s; conveyor "
            f"{t.conveyor_speed_m_s:.4f} m/s (pitch {t.pitch_m:.3f} m); longest program + return "
            f"{max(t.robot_cycle_s(b) for b in line.built_s):.1f} s\nscenario written: {out}")
