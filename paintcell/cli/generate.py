"""`paintcell generate KIND --out FILE`: a CAD-like door/hood/fender/roof mesh in mm
(`paintcell.surface.cad_like`), a part of a seeded family with its truth beside it
(`paintcell.surface.part_families`), or a whole car body (`paintcell.surface.car_body`): one
mesh, a folder of its panels with their `body.json` manifest, and its truth. An existing file is
replaced only with --force.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from paintcell.cli.common import SEED, add_out_force
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import check_new_target
from paintcell.surface.part_families import FAMILIES

__all__ = ["add_generate"]


def add_generate(add_parser: Any) -> None:
    """Register `generate` with the CLI's `add_parser(name, **kw)`."""
    g = add_parser("generate", help="write a generated car-part mesh with its truth",
                   description="Write a generated part, seeded and deterministic. The CAD-like "
                   "kinds (door, hood, fender, roof) are an outer skin hemmed onto an inner panel "
                   "in millimetres, with coarse uneven tessellation and a few slivers. The "
                   "families (door_frame, door_pieces, door_solid, hood_rolled, tailgate, bumper, "
                   "fender_arch, roof_sunroof) are the shapes a paint shop sends — window frames "
                   "of narrow members, parts in pieces with stray clips, closed thin solids, "
                   "rolled corners, recesses, wraps past 120°, arches and openings — with sizes, "
                   "curvatures, member widths, tessellation, units (mm or m) and orientation "
                   "drawn from the seed; their truth (areas, pieces, widths, openings, units, "
                   "rotation) is written beside the mesh as <stem>.truth.json. The body is a "
                   "car's exterior in millimetres (x forward, y left, z up, origin on the floor "
                   "under its centre): front and rear doors with window frames, fenders, rear "
                   "quarter panels, hood, roof, trunk lid (even seeds: a compact sedan) or "
                   "tailgate (odd seeds: an SUV), bumper fascias, both sides, 3.5-4.4 mm gaps "
                   "between neighbours; written as one mesh, a folder <stem>_panels/ with one "
                   "file per panel and their body.json manifest (paintcell.surface.body_panels "
                   "reads either), and <stem>.truth.json (areas, sides, normals, joints and "
                   "their gaps).")
    kinds = ("door", "hood", "fender", "roof", *FAMILIES, "body")   # cad_like, families, body
    g.add_argument("kind", choices=kinds, metavar="KIND", help=f"part kind: {', '.join(kinds)}")
    add_out_force(g, "mesh file to write (.stl/.ply/.obj; a family's or the body's "
                  "<stem>.truth.json too, and the body's <stem>_panels/ folder)")
    g.add_argument("--seed", type=SEED, default=0,
                   help="seed of the sizes, shape, tessellation, units and orientation; of "
                   "a body its kind (even: compact sedan, odd: SUV), sizes, gaps and "
                   "tessellation (default 0)")
    g.set_defaults(func=_cmd_generate)


def _cmd_generate(args: argparse.Namespace) -> int:
    from paintcell.core.atomic_io import atomic_path, atomic_write_text
    from paintcell.surface.cad_like import make_part
    from paintcell.surface.part_families import make_family_part

    suffix = args.out.suffix.lower().lstrip(".")
    if suffix not in ("stl", "ply", "obj"):
        raise PaintcellError(f"--out {args.out}: write a .stl, .ply or .obj file")
    check_new_target(args.out, "--out", args.force)
    if args.kind == "body":
        return _write_body(args, suffix)
    family = args.kind in FAMILIES
    truth_path = args.out.with_name(args.out.stem + ".truth.json")
    if family:
        check_new_target(truth_path, "the truth file", args.force)
    part = (make_family_part if family else make_part)(args.kind, args.seed)
    with atomic_path(args.out) as tmp:
        part.mesh.export(tmp, file_type=suffix)
    t: dict[str, Any] = part.truth
    if family:
        atomic_write_text(truth_path, json.dumps(t, indent=1) + "\n")
        print(f"{args.kind} (seed {args.seed}): {len(part.mesh.faces)} faces in {t['units']}, "
              f"{t['up_axis']} up → {args.out}; painted side {t['painted_area_m2']:.4f} m², "
              f"{len(t['pieces'])} piece(s); truth → {truth_path}")
        return 0
    print(f"{args.kind} (seed {args.seed}): {len(part.mesh.faces)} faces in mm → {args.out}; "
          f"truth: skin {t['skin_m2']:.4f} m², hem {t['hem_m2']:.4f} m², inner panel "
          f"{t['inner_m2']:.4f} m², window {t['window_m2']:.4f} m²")
    return 0


def _write_body(args: argparse.Namespace, suffix: str) -> int:
    """The body's mesh, its panel folder with body.json, and its truth; every target checked
    before anything is written."""
    from paintcell.core.atomic_io import atomic_path, atomic_write_text
    from paintcell.core.safe_paths import UnsafePathError, kind_of
    from paintcell.surface.body_panels import MANIFEST_NAME
    from paintcell.surface.car_body import generate_body

    out: Path = args.out
    folder = out.with_name(out.stem + "_panels")
    truth_path = out.with_name(out.stem + ".truth.json")
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise UnsafePathError(f"panel folder {folder} is a {kind_of(folder.lstat().st_mode)}, "
                              "not a folder; remove it or choose another --out")
    body = generate_body(args.seed)
    files = {folder / f"{n}.{suffix}": m for n, m in body.panels.items()}
    for f in files:
        check_new_target(f, "panel file", args.force)
    check_new_target(folder / MANIFEST_NAME, "the manifest", args.force)
    check_new_target(truth_path, "the truth file", args.force)
    folder.mkdir(parents=True, exist_ok=True)
    for f, m in files.items():
        with atomic_path(f) as tmp:
            m.export(tmp, file_type=suffix)
    atomic_write_text(folder / MANIFEST_NAME, json.dumps(body.manifest(suffix), indent=1) + "\n")
    atomic_write_text(truth_path, json.dumps(body.truth, indent=1) + "\n")
    with atomic_path(out) as tmp:
        body.mesh().export(tmp, file_type=suffix)
    t = body.truth
    gaps = [j["gap_mm"] for j in t["joints"]]
    print(f"body (seed {args.seed}): {t['kind']}, {t['length_mm'] / 1e3:.2f} × "
          f"{t['width_mm'] / 1e3:.2f} × {t['height_mm'] / 1e3:.2f} m, {len(body.panels)} panels, "
          f"{t['total_area_m2']:.2f} m² painted, gaps {min(gaps):.1f}–{max(gaps):.1f} mm → "
          f"{out}; panels and {MANIFEST_NAME} → {folder}/; truth → {truth_path}")
    return 0
