"""The cell file `paintcell init` writes for several robots: a booth TOML (`[[parts]]` with the
part's `[parts.part]` table, `[[robots]]` on rails; the format of
`paintcell.booth.booth_data`) with a comment giving the reason for each choice (why N robots,
which model, where each rail is and why, the plan, the moves)."""

from __future__ import annotations

import json
import textwrap
from typing import Any

from paintcell.app.init_layout import (
    HOME_CLEARANCE_M,
    LAYOUTS_VERIFIED,
    PART_LOW_Z_M,
    RAIL_DROPS_M,
    RAIL_GAPS_M,
    MultiCell,
)
from paintcell.app.init_toml import SPEC

__all__ = ["booth_toml"]


def _v(x: Any) -> str:
    return json.dumps(list(x) if isinstance(x, tuple) else x)


def booth_toml(cell: MultiCell, spec: Any, rep: Any, why_n: str) -> str:
    """The booth file of `cell` (module doc). spec: the part's `MeshPart` as the file names it
    (relative to the written file); rep: the part import's report; why_n: why one robot is not
    enough (or that the count was forced)."""
    b = cell.booth
    pl = b.parts[0].placement
    n = len(b.robots)
    model = b.robots[0].model.removesuffix("_rail")
    ops = rep.openings
    regions = ", ".join(f"{k} {v:.3f} m²" for k, v in rep.region_areas_m2.items())
    robots = ""
    for r in b.robots:
        x, y, z = r.base.xyz_m
        robots += f"""
[[robots]]
name = {_v(r.name)}
model = {_v(model)}
rail = {_v([round(v, 4) for v in r.rail_m])}
home = {_v(list(r.home))}
# rail frame {abs(y):.2f} m {'left (+y)' if y > 0 else 'right (−y)'} of the part's axis,
# centred at x = {x:.2f} m, {z:.2f} m up; the arm faces the part, the carriage runs along x
[robots.base]
xyz_m = {_v([round(v, 4) for v in r.base.xyz_m])}
rpy_rad = {_v([round(v, 6) for v in r.base.rpy_rad])}
"""
    planner = "".join(f"{k} = {_v(v)}\n" for k, v in cell.planner.items())
    plan_why = ("a patch plan: straight passes per patch along the rails, each patch cut once "
                "so a robot takes one wing of every patch (two jobs per robot)"
                if cell.patches else "one family of passes along the rails")
    traj = "".join(f"{k} = {_v(v)}\n" for k, v in cell.trajectory.items())
    speed = (f"passes at {cell.planner['v_nominal_m_s']} m/s nominal (the arms' J2/J3 "
             "accelerations limit the time law on the part's wings)"
             if "v_nominal_m_s" in cell.planner else "")
    head = [
        f"Written by `paintcell init {rep.spec.file}`: a cell of {n} robots; every choice below "
        "is editable.",
        f"Why {n} robots: {why_n}.",
        f"Which model: {model} on a rail (closed-form IK for the booth's automatic allocation; "
        "the carriage follows the passes along the part).",
        f"Where: rails parallel to the part's axis (world x), {cell.gap_m} m beside its sides "
        f"and {cell.drop_m} m below its top, the first of the "
        f"{len(RAIL_GAPS_M) * len(RAIL_DROPS_M)} frames tried (gaps "
        f"{', '.join(str(g) for g in RAIL_GAPS_M)} m, drops "
        f"{', '.join(str(d) for d in RAIL_DROPS_M)} m, at most {LAYOUTS_VERIFIED} built) where "
        "every pass is reached, an allocation exists, every arm at home keeps "
        f"{HOME_CLEARANCE_M * 1e3:.0f} mm from the part and the booth's bell distance from the "
        "others, and the booth builds every program clear of the part with the arms staggered "
        + ("apart and no pose after a joint jump" if cell.jumps == 0 else
           f"apart (every frame built has a joint jump: this one {cell.jumps} poses)")
        + f". On the fast plan ({cell.n_passes} passes): {cell.why.get('reach', '')}.",
        f"Allocation is automatic; on the fast plan it gave {cell.why.get('jobs', '')} (start "
        f"delays {cell.why.get('delays', '')}).",
        f"The part: {cell.why.get('pose', '')}; its lowest point {PART_LOW_Z_M} m above the "
        "floor.",
        f"The plan: {plan_why}" + (f"; {speed}" if speed else "")
        + (f" ({cell.why['plan']})" if cell.why.get("plan") else "")
        + f"; its film {cell.planned_nsd_pct:.1f} % σ/μ over the skin (fast plan, refined)."]
    text = "\n".join(textwrap.fill(h, 96, initial_indent="# ", subsequent_indent="# ")
                     for h in head)
    return f"""{text}
name = {_v(b.name)}
resolution_m = 0.01            # remesh edge length of a full run [m]
fast_resolution_m = 0.025      # remesh edge length of a --fast run [m]
max_jobs_per_robot = {b.max_jobs_per_robot}

[body_placement]
xyz_m = [0.0, 0.0, 0.0]
rpy_rad = [0.0, 0.0, 0.0]

# A static cell (no line motion while the part is painted).
[conveyor]
speed_m_s = 0.0
direction = [1.0, 0.0, 0.0]

[[parts]]
xyz_m = {_v(list(pl.xyz_m))}
rpy_rad = {_v([round(v, 6) for v in pl.rpy_rad])}
[parts.part]
file = {_v(spec.file)}   # relative to this file
# units: {rep.units.units} — {rep.units.reason}
units = {_v(rep.units.units)}
pieces = {_v(spec.pieces)}
side = {_v(spec.side)}
# regions: {regions}; openings: {len(ops)}
judge = ["skin"]
[parts.planner]
{planner}{robots}
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

[spec]
# the paint spec every part's executed film is judged against (paintcell.validation.paint_spec)
window_pct = {_v(SPEC.window_pct)}               # the window: target ± this [%]
min_inside_pct = {_v(SPEC.min_inside_pct)}           # least share of the judged area inside it [%]
max_nsd_pct = {_v(SPEC.max_nsd_pct)}              # largest executed σ/μ [%]
"""
