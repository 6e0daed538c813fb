"""`paintcell inspect`, `paintcell init` and `paintcell generate`: real part files in.

- inspect PART_FILE: what the import finds (units and why, size, pieces, openings, hems, repairs,
  curvature) and a PNG of the regions seen from the painted side; with --body, the panels of a
  car body (a mesh, or a folder holding body.json: `paintcell.surface.body_panels.load_body`).
- init PART_FILE --out scenarios/NAME.toml: a commented TOML scenario (part, placement in front of
  the robot, the first robot model whose base reaches the fast plan, `init_cell.choose_cell`)
  that `paintcell run` and `plan` accept as written; none reaches it: a one-line refusal.
- generate KIND --out FILE: a CAD-like or seeded-family mesh with its truth
  (`paintcell.cli.generate`).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.app.init_layout import MAX_ROBOTS
from paintcell.cli.common import RESOLUTION_M, add_out_force, number_option
from paintcell.cli.generate import add_generate
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import check_new_target, check_write_target
from paintcell.surface.part_spec import PIECES_GAP_RANGE_M, MeshPart

__all__ = ["register"]

_COLOURS = {"skin": "#4c9be8", "hem": "#e8894c", "inner": "#9a9a9a", "back": "#6b4ce8",
            "edge": "#e8d24c"}


def register(add_parser: Callable[..., argparse.ArgumentParser]) -> None:
    """Add the inspect/init/generate subcommands (`paintcell.cli.main.build_parser` calls
    this)."""
    i = add_parser("inspect", help="what paintcell finds in a part file",
                   description="Read, repair and classify a mesh (STL/OBJ/PLY) or CAD (STEP/IGES) "
                   "part file; print units chosen and why, size, pieces with areas, openings, "
                   "hems, repairs and curvature range; write a PNG of the regions. With --body, "
                   "read a whole car body instead (one mesh split into panels at their gaps, or "
                   "a folder holding a body.json manifest) and list its panels: name, area, the "
                   "side the paint goes on, and how many pieces each is made of.")
    _part_options(i)
    i.add_argument("--png", type=Path, default=None,
                   help="regions picture (default: <file stem>_regions.png in the current folder)")
    i.add_argument("--body", action="store_true",
                   help="FILE is a car body (a mesh, or a folder holding body.json): list its "
                   "panels instead of importing one part (--units applies)")
    i.set_defaults(func=_cmd_inspect)
    n = add_parser("init", help="write a ready scenario for a part file",
                   description="Write a commented TOML scenario for a part file: units, pieces, "
                   "side, placement in front of the robot, and the first robot model whose base "
                   "(paintcell.robots.placement.find_base_pose) or rail reaches every pose of a "
                   "fast plan, else a booth of 2-4 rail robots (--robots). `paintcell run` "
                   "accepts it as written; when nothing works: one line, no file.")
    _part_options(n, resolution=False)
    add_out_force(n, "scenario file to write (.toml)")
    n.add_argument("--robot", default="auto",
                   help="robot name (abb_paint, irb5500, ur10, abb_paint_rail, irb5500_rail), or "
                   "auto: the first of abb_paint, irb5500, irb5500_rail that reaches every pose "
                   "of the part's fast plan (init says which and why; when none does, it lays "
                   "out several rail robots, see --robots)")
    n.add_argument("--robots", default=None, metavar="N",
                   type=number_option("--robots", int, low=1, high=MAX_ROBOTS, example="2"),
                   help="number of robots. Default: one (as --robots 1) when one reaches every "
                   "pose, else 2, 3, then 4 irb5500 robots on rails along the part, the passes "
                   "split by the booth's automatic allocation; the file is then a booth "
                   "([[robots]]) with the reason for each choice. 1: one robot only (refused "
                   "when none reaches); 2–4: that many, laid out the same way")
    n.add_argument("--name", default=None, help="scenario name (default: the stem of --out)")
    n.add_argument("--line", action="store_true", help="FILE is a car body (`paintcell generate "
                   "body`): write a paint line for it from --takt (a booth file + its panels' "
                   "meshes in <out stem>_panels/), once the booth's checks pass on it")
    n.add_argument("--takt", default=None, metavar="SECONDS", help="with --line: a body every "
                   "SECONDS [s]; the conveyor runs one body length + 1 m per takt",
                   type=number_option("--takt", float, low=1.0, high=3600.0, unit="s",
                                      example="75"))
    n.add_argument("--max-robots", default=10, metavar="N", help="with --line: most robots "
                   "the line may have [robots] (default 10)",
                   type=number_option("--max-robots", int, low=1, high=30, example="10"))
    n.set_defaults(func=_cmd_init)
    add_generate(add_parser)


def _part_options(p: argparse.ArgumentParser, resolution: bool = True) -> None:
    """The part file and how to read it; resolution: also --resolution (inspect's remesh; init
    plans at the fast resolution it writes into the scenario)."""
    p.add_argument("file", type=Path, help="part file: STL/OBJ/PLY mesh or STEP/IGES CAD")
    p.add_argument("--units", default="auto", choices=("auto", "m", "mm", "cm", "in"),
                   help="length unit of the file's coordinates (auto: the first of m, mm, in, "
                   "cm that makes the part 0.1-6 m across; it says when another would too, and "
                   "init writes the unit it used into the scenario)")
    p.add_argument("--pieces", default="auto",
                   help="pieces to paint: auto (the largest and every piece within --pieces-gap "
                   "of it facing its painted side; stray bits under 1 %% of its area left out), "
                   "largest (by area), all, or indices like 0,2")
    p.add_argument("--pieces-gap", default=None, metavar="M",
                   type=number_option("--pieces-gap", float, low=PIECES_GAP_RANGE_M[0],
                                      high=PIECES_GAP_RANGE_M[1], unit="m", example="0.04"),
                   help="with --pieces auto: the largest gap between pieces painted as one part "
                   "[m] (default 0.04)")
    p.add_argument("--side", default="auto",
                   help="painted side: auto (the convex skin) or a direction like 0,0,1")
    if resolution:
        p.add_argument("--resolution", type=RESOLUTION_M, default=0.025,
                       help="remesh edge length [m] (0: keep the repaired tessellation)")


def _spec(args: argparse.Namespace) -> MeshPart:
    pieces: Any = args.pieces
    if pieces not in ("auto", "largest", "all"):
        try:
            pieces = tuple(int(x) for x in str(pieces).split(","))
        except ValueError:
            raise PaintcellError(f"--pieces {args.pieces!r}: write auto, largest, all or indices "
                                 "like 0,2") from None
    side: Any = args.side
    if side != "auto":
        try:
            side = tuple(float(x) for x in str(side).split(","))
        except ValueError:
            raise PaintcellError(f"--side {args.side!r}: write auto or a direction like 0,0,1") \
                from None
    gap = {} if args.pieces_gap is None else {"pieces_gap_m": args.pieces_gap}
    return MeshPart(file=str(args.file), units=args.units, pieces=pieces, side=side, **gap)


def _cmd_inspect(args: argparse.Namespace) -> int:
    from paintcell.surface.part_import import import_part

    if args.body:
        return _inspect_body(args)
    if args.png is not None:  # before the import's work, not after
        check_write_target(args.png, "--png")
    res = args.resolution if args.resolution > 0 else None
    surf, rep = import_part(_spec(args), resolution_m=res, setting="--resolution")
    print(_describe(rep, surf))
    png = args.png or Path(f"{surf.name}_regions.png")
    _plot_regions(surf, png)
    print(f"regions picture: {png}")
    return 0


def _inspect_body(args: argparse.Namespace) -> int:
    """`inspect --body`: the panels `load_body` finds, one line each."""
    import trimesh

    from paintcell.surface.body_panels import load_body

    if args.png is not None:
        raise PaintcellError("--png draws one part's regions; drop it with --body")
    panels = load_body(args.file, units=args.units)
    print(f"body: {args.file}: {len(panels)} panels, "
          f"{sum(p.area_m2 for p in panels):.3f} m² in all")
    print(f"  {'panel':<22} {'area m²':>8}  {'side':<5}  pieces")
    for p in panels:
        m = p.mesh
        n = len(trimesh.graph.connected_components(m.face_adjacency, nodes=np.arange(len(m.faces)),
                                                   min_len=1))
        print(f"  {p.name:<22} {p.area_m2:8.4f}  {p.side:<5}  {n}")
    return 0


def _describe(rep: Any, surf: Any) -> str:
    ext = " × ".join(f"{x:.3f}" for x in np.array(rep.extent_m))
    lines = [f"file: {rep.spec.file} ({rep.fmt.upper()})",
             f"units: {rep.units.units} — {rep.units.reason}",
             f"size: {ext} m",
             f"pieces: {len(rep.pieces)} (kept {list(rep.selected)})"]
    for p in rep.pieces[:10]:
        lines.append(f"  piece {p.index}: {p.area_m2:.4f} m², {p.n_faces} faces, "
                     f"{' × '.join(f'{x:.3f}' for x in p.extent_m)} m, "
                     f"{'painted' if p.painted else 'NOT painted'}: {p.why}")
    if len(rep.pieces) > 10:
        lines.append(f"  … {len(rep.pieces) - 10} more pieces")
    for r in (surf.regions.pieces if surf.regions is not None else ()):
        if r["piece"].endswith("back side"):
            lines.append(f"  piece {r['piece']}: {r['area_m2']:.4f} m², NOT painted: {r['why']}")
    d = ", ".join(f"{x:.3f}" for x in rep.painted_direction)
    lines.append(f"painted side: [{d}] — {rep.side_reason}"
                 + ("; closed shell reduced to its skin" if rep.closed_shell else ""))
    lines.append("regions: " + ", ".join(f"{k} {v:.4f} m²" for k, v in rep.region_areas_m2.items()))
    ops = rep.openings
    lines.append(f"openings: {len(ops)}" + "".join(
        f"\n  {o.area_m2:.4f} m², perimeter {o.perimeter_m * 1e3:.0f} mm at "
        f"({', '.join(f'{c:.3f}' for c in o.centre_m)}) m" for o in ops))
    lines.append(f"repairs: {rep.repair.summary()}")
    if rep.resolution_m:
        lines.append(f"remesh: {len(surf.faces)} faces at {rep.resolution_m * 1e3:.0f} mm, area "
                     f"{rep.area_before_remesh_m2:.4f} → {rep.area_after_remesh_m2:.4f} m² "
                     f"({100 * (rep.area_after_remesh_m2 / rep.area_before_remesh_m2 - 1):+.2f} %)")
    lo, hi = rep.mean_curvature_range_1_m
    lines.append(f"skin mean curvature (1st–99th percentile): {lo:.2f} … {hi:.2f} 1/m")
    return "\n".join(lines)


def _plot_regions(surf: Any, png: Path) -> None:
    """Orthographic views of the regions from the painted side and from behind (mirrored),
    openings labelled with their area."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from paintcell.core.atomic_io import atomic_path
    from paintcell.surface.regions import REGION_NAMES

    d = surf.regions.painted_direction
    e1 = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    depth = surf.vertices[surf.faces].mean(1) @ d
    fig, axes = plt.subplots(1, 2, figsize=(13, 6), dpi=100)
    views = ((axes[0], 1.0, "from the painted side"), (axes[1], -1.0, "from behind"))
    for ax, sign, title in views:
        # Behind: seen from -d, so left and right swap; far faces are drawn first.
        xy = np.stack([sign * (surf.vertices @ e1), surf.vertices @ e2], 1)
        order = np.argsort(sign * depth)
        cols = [_COLOURS[REGION_NAMES[i]] for i in surf.regions.face_labels[order]]
        ax.add_collection(PolyCollection(xy[surf.faces[order]], facecolors=cols,
                                         edgecolors="none"))
        ax.autoscale()
        ax.set_aspect("equal")
        for o in surf.regions.openings:
            c = np.array(o.centre_m)
            ax.annotate(f"opening {o.area_m2 * 1e4:.0f} cm²", (sign * (c @ e1), c @ e2),
                        ha="center")
        ax.set_title(f"{surf.name}: regions seen {title} [m]")
    for name in REGION_NAMES:
        axes[0].plot([], [], "s", color=_COLOURS[name], label=name)
    axes[0].legend(loc="upper right")
    with atomic_path(png) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    from scipy.spatial.transform import Rotation

    r = Rotation.from_matrix(R).as_euler("xyz")
    return (float(r[0]), float(r[1]), float(r[2]))


def _placement(surf: Any) -> np.ndarray:
    """T_world_part: painted side toward a robot at the origin (−x), the part's longest extent
    horizontal (along y), its centre 1.4 m in front of the robot and its lower edge ≥ 0.5 m above
    the floor (the wrist of a pass along that edge stays clear of the floor)."""
    d = surf.regions.painted_direction
    skin = surf.vertices[surf.regions.vertex_mask(surf.faces, ("skin",))]
    c = skin.mean(0)
    q = skin - c
    q = q - np.outer(q @ d, d)
    w, vec = np.linalg.eigh(q.T @ q)
    long_ax = vec[:, -1]
    # Part frame → world: d → −x, long axis → −y (right-handed: third = up).
    up = np.cross(d, long_ax)
    R = np.stack([-d, -long_ax, up], 0)  # rows: world x, y, z expressed in part coordinates
    if np.linalg.det(R) < 0:
        R[1] = -R[1]
    z_half = float(np.ptp((surf.vertices - c) @ R[2]) / 2)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [1.4, 0.0, max(1.0, z_half + 0.5)] - R @ c
    return T


def _cmd_init(args: argparse.Namespace) -> int:
    from paintcell.app.init_cell import AUTO_ROBOTS, choose_cell
    from paintcell.app.init_layout import MAX_ROBOTS
    from paintcell.app.init_toml import scenario_toml
    from paintcell.app.init_verify import ProgramCheck, planned_nsd_pct
    from paintcell.app.pipeline import make_plan
    from paintcell.app.scenario import Scenario
    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.placement import Placement
    from paintcell.robots.catalog import ROBOT_NAMES
    from paintcell.surface.part_import import import_part

    out: Path = args.out
    if args.line or args.takt is not None:      # a paint line (`init_line_file`)
        from paintcell.app.init_line_file import init_body_line
        print(init_body_line(args.file, out, args.takt, args.max_robots, args.force, args.name,
                             args.line, args.robots is not None or args.robot != "auto"))
        return 0
    if out.suffix != ".toml":
        raise PaintcellError(f"--out {out}: a scenario file ends in .toml")
    check_new_target(out, "--out", args.force)  # before minutes of planning, and again below
    if args.robot != "auto" and args.robot not in ROBOT_NAMES:  # before minutes of planning
        raise PaintcellError(f"--robot {args.robot!r} is not a robot paintcell ships; write "
                             f"--robot auto or one of {', '.join(ROBOT_NAMES)}")
    if args.robots is not None and not 1 <= args.robots <= MAX_ROBOTS:
        raise PaintcellError(f"--robots {args.robots}: write 1 to {MAX_ROBOTS}, or leave it out "
                             "(one robot when one reaches the part, else more)")
    several = args.robot.removesuffix("_rail") in ("abb_paint", "irb5500", "auto")
    if (args.robots or 1) > 1 and not several:
        raise PaintcellError(f"--robot {args.robot} with --robots {args.robots}: several robots "
                             "need closed-form IK; write --robot irb5500, abb_paint or auto")
    spec = _spec(args)
    spec_rel = replace(spec, file=_relpath(Path(spec.file), out.parent))
    surf, rep = import_part(spec, resolution_m=0.025)
    name = args.name or "".join(c if c.isalnum() or c in "_-" else "_" for c in out.stem)
    if (args.robots or 1) > 1:
        return _init_multi(args, name, spec, spec_rel, surf, rep, (args.robots,),
                           f"--robots {args.robots} asked for {args.robots}")
    T = _placement(surf)
    pl = Placement(tuple(float(x) for x in T[:3, 3]), _rpy(T[:3, :3]))  # type: ignore[arg-type]
    tried: list[str] = []
    plans: list[tuple[float, int, dict[str, Any], Any, Any]] = []
    for k, planner in enumerate(_PLANNER_TRIES):
        scn = Scenario(name=name, part=spec_rel, part_placement=pl,
                       robot="abb_paint" if args.robot == "auto" else args.robot,
                       planner=dict(planner), fast_planner=dict(_INIT_PLANNER))
        try:
            plan = make_plan(scn, surf, fast=True)
            run_plan = make_plan(replace(scn, fast_planner={}), surf, fast=True)
        except PaintcellError as exc:
            tried.append(f"{planner or 'defaults'}: {exc}")
            continue
        plans.append((planned_nsd_pct(run_plan, surf), k, planner, plan, run_plan))
        if plans[-1][0] <= GOOD_PLANNED_NSD_PCT:
            break
    if not plans:
        raise PaintcellError(f"no planner setting plans {spec.file} ({len(tried)} tried; first: "
                             f"{tried[0]}); see `paintcell inspect` for its regions")
    _, _, planner, plan, run_plan = min(plans, key=lambda x: x[:2])

    def named(p: dict[str, Any]) -> str:
        return ", ".join(f"{k} = {v}" for k, v in p.items()) or "defaults"

    planner_why = "" if len(plans) == 1 else (
        "planned σ/μ over the skin (fast plan, film refined) by planner setting: " + "; ".join(
            f"{named(p)} {x:.2f} %" for x, _, p, _, _ in plans)
        + f"; kept the most even ({named(planner)})")
    paths = [pl.matrix @ plan.tcp_frames(i) for i in range(len(plan.passes))]
    # The lowest pass (edge passes run outside the part) at least _MIN_TCP_Z_M above the floor:
    # below that the wrist and the bell sweep the floor. The plan is in the part frame: lift both.
    lift = _MIN_TCP_Z_M - min(float(p[:, 2, 3].min()) for p in paths)
    if lift > 0:
        T[2, 3] += lift
        pl = Placement(tuple(float(x) for x in T[:3, 3]), pl.rpy_rad)  # type: ignore[arg-type]
        paths = [pl.matrix @ plan.tcp_frames(i) for i in range(len(plan.passes))]
    # scored by what the run suffers: the plan's speeds, clearance from the part and the floor;
    # the first robot model that reaches every pose (`init_cell.AUTO_ROBOTS` with --robot auto)
    part_world = surf.vertices @ pl.matrix[:3, :3].T + pl.matrix[:3, 3]
    robots = AUTO_ROBOTS if args.robot == "auto" else (args.robot,)
    def candidate(robot_name: str, T_cell: np.ndarray, trajectory: dict[str, Any]) -> Scenario:
        return Scenario(name=name, part=spec_rel, part_placement=pl, robot=robot_name,
                        base=Placement(tuple(float(x) for x in T_cell[:3, 3]),  # type: ignore[arg-type]
                                       _rpy(T_cell[:3, :3])), trajectory=trajectory,
                        planner=dict(planner), fast_planner=dict(_INIT_PLANNER))

    # what `run` does first, the joint program, and what its execution will touch: the part
    check = ProgramCheck(candidate, plan, surf, run_plan)
    try:
        cell = choose_cell(robots, paths, [p.speeds_m_s for p in plan.passes], part_world,
                           str(spec.file), floor_z_m=0.0, verify=check)
    except PaintcellError as exc:
        if args.robots is not None or not several:    # --robots 1 (or a UR10): one or none
            raise
        alone = str(exc).split(": ", 1)[-1].split("; paint it in pieces")[0][:400]
        print(f"init: no one robot reaches every pose ({alone}); laying out several")
        return _init_multi(args, name, spec, spec_rel, surf, rep, tuple(range(2, MAX_ROBOTS + 1)),
                           f"no one robot reaches every pose of the part ({alone})")
    trajectory = check.trajectory.get(cell.robot, {})
    capped = check.capped_nsd_pct.get(cell.robot)
    if capped is not None:      # what `run` plans: the plan above re-planned under speed caps
        planner_why = "; ".join(x for x in (planner_why, (
            f"{cell.robot} cannot follow every planned speed: run caps them and plans again, "
            f"laying {capped:.2f} % σ/μ on the skin (fast plan)")) if x)
    T_base = cell.T_base
    base = Placement(tuple(float(x) for x in T_base[:3, 3]), _rpy(T_base[:3, :3]))  # type: ignore[arg-type]
    text = scenario_toml(name, cell.robot, spec_rel, rep, pl, base,
                          f"{cell.why}. {cell.verdict}", len(plan.passes), planner, tried,
                          trajectory, check.clearance_m.get(cell.robot), planner_why)
    check_new_target(out, "--out", args.force)
    atomic_write_text(out, text)
    print(_describe(rep, surf))
    print(f"cell: {cell.why}")
    print(f"placement: {cell.verdict}")
    if planner_why:
        print(f"planner: {planner_why}")
    _warn_uneven(min(x for x, *_ in plans), "[planner]")     # the kept plan's
    print(f"scenario written: {out}")
    return 0


def _init_multi(args: argparse.Namespace, name: str, spec: MeshPart, spec_rel: MeshPart,
                surf: Any, rep: Any, counts: tuple[int, ...], why_n: str) -> int:
    """`init` with several robots (`paintcell.app.init_layout`): the booth file, once built."""
    from paintcell.app.init_booth_file import booth_toml
    from paintcell.app.init_layout import ARM, choose_layout
    from paintcell.core.atomic_io import atomic_write_text

    model = ARM if args.robot == "auto" else args.robot.removesuffix("_rail")
    cell = choose_layout(name, spec, surf, counts, model)
    text = booth_toml(cell, spec_rel, rep, why_n.replace("\n", " "))
    check_new_target(args.out, "--out", args.force)
    atomic_write_text(args.out, text)
    print(_describe(rep, surf))
    print(f"cell: {len(cell.booth.robots)} {model} robots on rails; {cell.why['jobs']}")
    _warn_uneven(cell.planned_nsd_pct, "[parts.planner]")
    print(f"scenario written: {args.out}")
    return 0


def _warn_uneven(nsd_pct: float, table: str) -> None:
    """Say so when the kept plan's film [% σ/μ, fast plan, refined] is over the spec init wrote:
    `run` will fail its spec; table: the file's planner table ("[planner]", "[parts.planner]")."""
    from paintcell.app.init_toml import SPEC

    if nsd_pct > SPEC.max_nsd_pct:
        print(f"init: warning: the plan kept lays {nsd_pct:.1f} % σ/μ on the skin (fast plan, "
              f"film refined), over the spec's {SPEC.max_nsd_pct:g} %: `paintcell run` will "
              f"fail it; write its {table} table (another `orientation`, `patches = true`: "
              "every key is in the scenario file reference, built by `make docs`)")


def _relpath(p: Path, start: Path) -> str:
    import os
    return os.path.relpath(p.resolve(), start.resolve())


#: Lowest TCP height of a pass `init` accepts [m]; the part is lifted until its plan clears it.
_MIN_TCP_Z_M = 0.6

#: What init's own plan leaves out (not written to the scenario): the film refinement re-times
#: the passes along the same poses (the cell's reach, moves and clearance are those of the
#: unrefined plan) and its bounded least squares over every knot of the part was 292 of
#: crs_cowling_creases' 404 s plan (profiled, 2 cores under load).
_INIT_PLANNER: dict[str, Any] = {"film_refine": False}

#: Planner settings `init` tries in turn (the first is the defaults): it keeps the first whose
#: plan, as `run --fast` makes it (film refined), lays a film of σ/μ ≤ `GOOD_PLANNED_NSD_PCT` on
#: the skin, else the one of the lowest σ/μ of those that plan the part.
_PLANNER_TRIES: tuple[dict[str, Any], ...] = (
    {}, {"orientation": "zero-curvature"}, {"orientation": "max-curvature"},
    {"orientation": "auto", "w_max_m": 0.3})

#: A planned film this even [%] (σ/μ over the skin's area) is kept without trying the other
#: planner settings; the default spec allows 10 % executed. Seeded doors the defaults planned
#: unevenly (`paintcell generate`, film refined): door_solid seed 7 at 14.06 % (w_max_m 0.3:
#: 5.83 %), door_pieces seed 7 as OBJ at 9.39 % (zero-curvature: 3.12 %; as PLY, whose floats
#: round otherwise, zero-curvature plans it at 8.63 % and max-curvature at 3.61 %).
GOOD_PLANNED_NSD_PCT = 7.0
