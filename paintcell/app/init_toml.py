"""The commented TOML scenario `paintcell init` writes: every choice it made, why, and the
defaults it states (the thresholds and the paint spec, `paintcell.validation.paint_spec`)."""

from __future__ import annotations

import json
import textwrap
from typing import Any

from paintcell.surface.part_spec import MeshPart
from paintcell.validation.paint_spec import PaintSpec

__all__ = ["SPEC", "scenario_toml", "toml_value"]

#: The paint spec `init` writes: the defaults, stated.
SPEC = PaintSpec()


def toml_value(x: Any) -> str:
    """A TOML value of a number, string or list (tuples as arrays)."""
    return json.dumps(list(x) if isinstance(x, tuple) else x)


def scenario_toml(name: str, robot: str, spec: MeshPart, rep: Any, pl: Any, base: Any,
                  verdict: str, n_passes: int, planner: dict[str, Any], tried: list[str],
                  trajectory: dict[str, Any], clearance_m: float | None,
                  planner_why: str = "") -> str:
    """The scenario text: name, robot, the `[part]` table `spec` with what the import found
    (`rep`, an `ImportReport`), the placements `pl` and `base` (`Placement`), the base's
    `verdict`, the planner settings that planned the part (and the `tried` ones that failed),
    the trajectory settings and the program's clearance [m], the servo's gain rule, thresholds
    and the paint spec; planner_why: why these planner settings, when others were tried too,
    and the film of the plan `run` makes under the robot's speed caps, when init made it."""
    ops = rep.openings
    pieces = ", ".join(f"{p.index}: {p.area_m2:.3f} m² {'painted' if p.painted else 'not'}"
                       for p in rep.pieces[:6])
    pieces += ", …" if len(rep.pieces) > 6 else ""
    d = [round(x, 3) for x in rep.painted_direction]
    regions = ", ".join(f"{k} {v:.3f} m²" for k, v in rep.region_areas_m2.items())
    planner_lines = "".join(f"# failed: {t[:300]}\n" for t in tried)
    planner_lines += "".join(f"# {line}\n" for line in textwrap.wrap(planner_why, 96))
    planner_lines += "".join(f"{k} = {toml_value(v)}\n" for k, v in planner.items()) or \
        "# the planner's defaults plan this part\n"
    gap = f"at least {(clearance_m or 0.0) * 1e3:.0f} mm"   # init_verify's sweep of the program
    traj_lines = "".join(f"{k} = {toml_value(v)}\n" for k, v in trajectory.items())
    if traj_lines:
        traj_lines = (f"# the default moves came close to the part on the fast plan; folded (the "
                      f"arm pulls back toward its base before it turns) they keep {gap} from "
                      "it\n" + traj_lines)
    else:
        traj_lines = f"# the default moves keep {gap} from the part on the fast plan\n"
    window, inside, nsd = (toml_value(getattr(SPEC, k))
                           for k in ("window_pct", "min_inside_pct", "max_nsd_pct"))
    return f"""# Written by `paintcell init {rep.spec.file}`: every choice below is editable.
name = {toml_value(name)}
robot = {toml_value(robot)}               # see [base] for why this robot
resolution_m = 0.01            # remesh edge length of a full run [m]
fast_resolution_m = 0.025      # remesh edge length of a --fast run [m]

[part]
file = {toml_value(spec.file)}   # relative to this file
# units: {rep.units.units} — {rep.units.reason}
units = {toml_value(rep.units.units)}
# pieces: {len(rep.pieces)} found ({pieces}); "auto" paints the largest and the pieces
# within pieces_gap_m of it that face its painted side; "largest" the largest alone
pieces = {toml_value(spec.pieces)}
pieces_gap_m = {toml_value(spec.pieces_gap_m)}
# side: painted direction {d} in the part frame ({rep.side_reason})
side = {toml_value(spec.side)}
# regions: {regions}; openings: {len(ops)}
judge = ["skin"]               # film metrics judged on the skin (add "hem" to include hems)

[part_placement]
# painted side toward the robot (world −x), longest extent horizontal, centre 1.4 m in front
xyz_m = {toml_value([round(x, 4) for x in pl.xyz_m])}
rpy_rad = {toml_value([round(x, 6) for x in pl.rpy_rad])}

[base]
# paintcell.robots.placement.find_base_pose on the fast plan ({n_passes} passes): {verdict}
xyz_m = {toml_value([round(x, 4) for x in base.xyz_m])}
rpy_rad = {toml_value([round(x, 6) for x in base.rpy_rad])}

[planner]
{planner_lines}
[trajectory]
{traj_lines}
# gains from each joint's effective inertia: with the diagonal one a joint coupled to others
# (the IRB 5500's J3) is tuned stiffer than it moves, and its loop rings in fast turn-arounds
[servo]
gain_inertia = "effective"

[thresholds]
reachability_pct = 100.0
max_collisions = 0

[spec]
# the paint spec the executed film is judged against (paintcell.validation.paint_spec):
# target_film_um = 30.0        # centre of the window [µm]; unset: the plan's own target film
window_pct = {window}               # the window: target ± this [%]
min_inside_pct = {inside}           # least share of the judged area inside it [%]
max_nsd_pct = {nsd}              # largest executed σ/μ [%]
"""
