"""Seeded families of car-body parts with their truth, for measuring how general paintcell is.

Each family is a shape a paint shop sends that a flat crowned panel does not cover: a door with
an open window frame (narrow sash members and a B-pillar strip), the same door delivered as
separate pieces with stray clips and a sealer bead, the door as a closed thin solid, a hood with
steeply rolled front corners, a tailgate with a licence-plate recess, a bumper fascia wrapping
more than 120°, a fender with a wheel arch and a roof with a sunroof opening.

The seed varies sizes, curvatures, member widths, tessellation, the file's units (mm or m) and
its orientation. Truth is by construction, measured on the generated triangles before units and
orientation are applied: the painted side's area, each piece's area and role, member widths,
openings, and the rotation from the part frame (painted side +z) to the file's frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

if TYPE_CHECKING:
    import trimesh

__all__ = ["FAMILIES", "FamilyPart", "make_family_part"]

FAMILIES = ("door_frame", "door_pieces", "door_solid", "hood_rolled", "tailgate", "bumper",
            "fender_arch", "roof_sunroof")


@dataclass(frozen=True, eq=False)
class FamilyPart:
    """A generated part: `mesh` in the file's units and frame, `truth` (JSON-ready: areas in
    m², widths in m, `units`, `R_file_part` the part frame's rotation into the file's)."""

    family: str
    seed: int
    mesh: trimesh.Trimesh
    truth: dict[str, Any]


def _box(u0: float, w0: float, u1: float, w1: float) -> shapely.Polygon:
    return shapely.box(min(u0, u1), min(w0, w1), max(u0, u1), max(w0, w1))


def _crown(u: np.ndarray, w: np.ndarray, Ru: float, Rw: float) -> np.ndarray:
    return -(u ** 2) / (2 * Ru) - (w ** 2) / (2 * Rw)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _door(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    """Lower door panel with its window frame: (domain, map, truth extras)."""
    W = rng.uniform(1000, 1200)
    Hp = rng.uniform(580, 700)           # panel below the belt line
    Hf = rng.uniform(420, 520)           # window frame height
    top, front, pillar = rng.uniform(40, 80), rng.uniform(40, 80), rng.uniform(80, 120)
    slope = rng.uniform(150, 300)        # the frame's front edge leans back by this much
    Ru, Rw = rng.uniform(6000, 12000), rng.uniform(2500, 4000)
    tumble = rng.uniform(800, 1400)      # the frame leans in above the belt [mm radius]
    panel = _box(-W / 2, 0, W / 2, Hp)
    outer = shapely.Polygon([(-W / 2, Hp - 1), (W / 2, Hp - 1), (W / 2, Hp + Hf),
                             (-W / 2 + slope, Hp + Hf)])
    dx = front * np.hypot(1.0, slope / Hf)   # the sash's front member `front` wide, square on
    window = shapely.Polygon([(-W / 2 + dx, Hp), (W / 2 - pillar, Hp),
                              (W / 2 - pillar, Hp + Hf - top),
                              (-W / 2 + dx + slope * (Hf - top) / Hf, Hp + Hf - top)])
    domain = shapely.union(panel, outer.difference(window))

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        z = _crown(u, w - Hp / 2, Ru, Rw)
        z = z - 0.05 * np.sqrt((w - 0.62 * Hp) ** 2 + 9.0)            # character line
        z = z - np.maximum(w - Hp, 0.0) ** 2 / (2 * tumble)
        return np.stack([u, w, z], -1)

    extra = {"members": [{"name": "sash_top", "width_m": top / 1e3},
                         {"name": "sash_front", "width_m": front / 1e3},
                         {"name": "b_pillar", "width_m": pillar / 1e3}],
             "openings": [{"name": "window", "area_m2": window.area / 1e6}],
             "panel": panel, "frame": outer.difference(window).difference(panel)}
    return domain, surf, extra


def _hood(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    W, L = rng.uniform(1400, 1600), rng.uniform(1100, 1300)
    Ru, Rw = rng.uniform(3000, 5000), rng.uniform(2500, 4000)
    h_roll, L_roll = rng.uniform(60, 100), rng.uniform(80, 120)    # front roll: 56°–75° slope
    h_side, L_side = rng.uniform(50, 90), rng.uniform(90, 140)

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        z = _crown(u, w - L / 2, Ru, Rw)
        z = z - h_roll * np.clip(1 - w / L_roll, 0, 1) ** 3
        edge = np.clip(1 - (W / 2 - np.abs(u)) / L_side, 0, 1) ** 3
        z = z - h_side * edge * np.exp(-w / 300.0)                    # the front corners roll
        return np.stack([u, w, z], -1)

    # the steepest slope of the analytic surface, on a 2 mm grid over the front half
    gu, gw = np.meshgrid(np.arange(-W / 2, W / 2 + 1e-9, 2.0), np.arange(0, L / 2, 2.0),
                         indexing="ij")
    zu, zw = np.gradient(surf(gu, gw)[..., 2], 2.0, 2.0)
    steep = float(np.degrees(np.arctan(np.hypot(zu, zw).max())))
    return _box(-W / 2, 0, W / 2, L), surf, {"max_edge_slope_deg": steep}


def _tailgate(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    W, H = rng.uniform(1100, 1300), rng.uniform(700, 900)
    Ru, Rw = rng.uniform(4000, 8000), rng.uniform(1500, 3000)
    depth, wall = rng.uniform(20, 40), rng.uniform(12, 20)
    pu, pw = 540.0 / 2 + 20, 130.0 / 2 + 15                         # plate and its margin
    cw = -H / 2 + rng.uniform(0.2, 0.3) * H

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        z = _crown(u, w, Ru, Rw)
        su = _smoothstep((pu - np.abs(u)) / wall + 1)
        sw = _smoothstep((pw - np.abs(w - cw)) / wall + 1)
        return np.stack([u, w, z - depth * su * sw], -1)

    return _box(-W / 2, -H / 2, W / 2, H / 2), surf, {
        "recess": {"width_m": 2 * pu / 1e3, "height_m": 2 * pw / 1e3, "depth_m": depth / 1e3}}


def _bumper(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    Lf, Rc = rng.uniform(900, 1200), rng.uniform(150, 300)
    theta = np.radians(rng.uniform(65, 80))                          # each corner's turn
    Ls, H, Rv = rng.uniform(100, 200), rng.uniform(350, 500), rng.uniform(600, 1200)
    arc = Rc * theta
    total = Lf + 2 * (arc + Ls)

    def plan_view(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plan-view point and outward normal at arc length s from the middle (|s| symmetric)."""
        a = np.abs(s)
        sg = np.where(s < 0, -1.0, 1.0)
        phi = np.clip((a - Lf / 2) / Rc, 0, theta)                   # turn so far
        x = np.where(a <= Lf / 2, a, Lf / 2 + Rc * np.sin(phi))
        y = np.where(a <= Lf / 2, 0.0, -Rc * (1 - np.cos(phi)))
        rest = np.maximum(a - Lf / 2 - arc, 0.0)
        x = x + rest * np.cos(theta)
        y = y - rest * np.sin(theta)
        nx, ny = np.sin(phi), np.cos(phi)
        return np.stack([sg * x, y], -1), np.stack([sg * nx, ny], -1)

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        p, n = plan_view(u)
        bulge = -((w - H / 2) ** 2) / (2 * Rv)
        xy = p + bulge[..., None] * n
        # part frame: the painted side faces +z at the middle (plan y → z, height → y)
        return np.stack([xy[..., 0], w, xy[..., 1]], -1)

    return _box(-total / 2, 0, total / 2, H), surf, {"wrap_deg": float(np.degrees(2 * theta))}


def _fender(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    W, H = rng.uniform(900, 1100), rng.uniform(600, 750)
    Ru, Rw = rng.uniform(4000, 7000), rng.uniform(700, 1000)
    Ra, uc = rng.uniform(330, 380), rng.uniform(-0.1, 0.1) * W
    flare = rng.uniform(8, 20)
    arch = shapely.Point(uc, -H / 2 + 40).buffer(Ra, 64)
    domain = _box(-W / 2, -H / 2, W / 2, H / 2).difference(arch)

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        z = _crown(u, w, Ru, Rw)
        r = np.hypot(u - uc, w + H / 2 - 40)
        return np.stack([u, w, z + flare * np.exp(-((r - Ra - 40) / 40) ** 2)], -1)

    return domain, surf, {"openings": [{"name": "wheel_arch",
                                        "area_m2": (domain.envelope.area - domain.area) / 1e6}]}


def _roof(rng: np.random.Generator) -> tuple[shapely.Geometry, Any, dict[str, Any]]:
    W, L = rng.uniform(1200, 1400), rng.uniform(1500, 1900)
    Ru, Rw = rng.uniform(2500, 4000), rng.uniform(5000, 9000)
    sw, sl, r = rng.uniform(700, 850), rng.uniform(450, 550), rng.uniform(40, 80)
    cw = -L / 2 + rng.uniform(0.3, 0.4) * L
    hole = _box(-sw / 2 + r, cw - sl / 2 + r, sw / 2 - r, cw + sl / 2 - r).buffer(r, 16)
    domain = _box(-W / 2, -L / 2, W / 2, L / 2).difference(hole)

    def surf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.stack([u, w, _crown(u, w, Ru, Rw)], -1)

    return domain, surf, {"openings": [{"name": "sunroof", "area_m2": hole.area / 1e6}]}


def _pieces(domain: shapely.Geometry, extra: dict[str, Any], gap: float) -> shapely.Geometry:
    """The door cut into its lower panel, the sash and the B-pillar strip, `gap` [mm] apart."""
    panel, frame = extra["panel"], extra["frame"]
    pil_u = max(x for x, _ in panel.exterior.coords) - extra["members"][2]["width_m"] * 1e3
    cut = _box(pil_u - gap / 2, -1e4, pil_u + gap / 2, 1e4)
    pillar = frame.intersection(_box(pil_u + gap / 2, -1e4, 1e4, 1e4))
    sash = frame.difference(cut).difference(pillar)
    shift = panel.buffer(gap)
    return shapely.MultiPolygon([panel, *[p for g in (sash, pillar)
                                          for p in _as_list(g.difference(shift))]])


def _as_list(g: shapely.Geometry) -> list[shapely.Polygon]:
    return [g] if isinstance(g, shapely.Polygon) else [p for p in getattr(g, "geoms", [])
                                                       if isinstance(p, shapely.Polygon)]


def _strays(rng: np.random.Generator, pts: np.ndarray) -> tuple[list[trimesh.Trimesh], list]:
    """Clips (small boxes) and a sealer bead (a thin strip) behind the panel [mm]."""
    import trimesh

    lo, hi = pts.min(0), pts.max(0)
    out, info = [], []
    for k in range(3):
        c = [rng.uniform(lo[0] + 100, hi[0] - 100), lo[1] + 30 + 120 * k, lo[2] - 25]
        b = trimesh.creation.box([14, 14, 6], trimesh.transformations.translation_matrix(c))
        out.append(b)
        info.append({"name": f"clip_{k}", "role": "stray", "area_m2": b.area / 1e6})
    bead = trimesh.creation.box([0.6 * (hi[0] - lo[0]), 5, 3],
                                trimesh.transformations.translation_matrix(
                                    [(lo[0] + hi[0]) / 2, lo[1] + 10, lo[2] - 30]))
    out.append(bead)
    info.append({"name": "sealer_bead", "role": "stray", "area_m2": bead.area / 1e6})
    return out, info


def _face_areas(p: np.ndarray, f: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1)


_SHAPES = {"door_frame": _door, "door_pieces": _door, "door_solid": _door, "hood_rolled": _hood,
           "tailgate": _tailgate, "bumper": _bumper, "fender_arch": _fender,
           "roof_sunroof": _roof}


def make_family_part(family: str, seed: int = 0) -> FamilyPart:
    """Generate one part of `family` for `seed` (deterministic), with its truth."""
    import trimesh  # here, not at the top: the command line lists FAMILIES without loading it
    from scipy.spatial.transform import Rotation

    from paintcell.surface.sheet_mesh import tessellate, thin_solid

    if family not in _SHAPES:
        raise ValueError(f"unknown part family {family!r}; choose one of {', '.join(FAMILIES)}")
    rng = np.random.default_rng([seed, FAMILIES.index(family)])
    domain, surf, extra = _SHAPES[family](rng)
    truth: dict[str, Any] = {"family": family, "seed": seed}
    if family == "door_pieces":
        gap = float(rng.uniform(15, 35))
        domain = _pieces(domain, extra, gap)
        truth["gap_m"] = gap / 1e3
    step = rng.uniform(25, 60)
    members = [m["width_m"] * 1e3 for m in extra.get("members", [])]
    bstep = min(step, *(0.5 * w for w in members)) if members else min(step, 30.0)
    sheet = tessellate(domain, step, bstep, rng)
    pts = surf(sheet.uv[:, 0], sheet.uv[:, 1])
    faces = sheet.faces
    skin_area = _face_areas(pts, faces)
    truth["painted_area_m2"] = float(skin_area.sum() / 1e6)
    truth["pieces"] = [{"name": "panel" if k == 0 else f"piece_{k}", "role": "skin",
                        "area_m2": float(skin_area[sheet.piece == k].sum() / 1e6)}
                       for k in range(int(sheet.piece.max()) + 1)]
    meshes: list[trimesh.Trimesh] = []
    if family == "door_solid":
        normals = trimesh.Trimesh(pts, faces, process=False).vertex_normals
        thick = float(rng.uniform(30, 60))
        pts, faces, lab = thin_solid(pts, faces, normals, thick)
        a = _face_areas(pts, faces)
        truth["thickness_m"] = thick / 1e3
        truth["inner_skin_area_m2"] = float(a[lab == 1].sum() / 1e6)
        truth["rim_area_m2"] = float(a[lab == 2].sum() / 1e6)
    if family == "door_pieces":
        meshes, info = _strays(rng, pts)
        truth["pieces"] += info
    for key in ("members", "openings", "max_edge_slope_deg", "recess", "wrap_deg"):
        if key in extra:
            truth[key] = extra[key]
    parts = [trimesh.Trimesh(pts, faces, process=False), *meshes]
    v_all = np.concatenate([m.vertices for m in parts])
    offsets = np.cumsum([0] + [len(m.vertices) for m in parts[:-1]])
    f_all = np.concatenate([m.faces + o for m, o in zip(parts, offsets, strict=True)])
    # The file's frame and units: mm or m by the seed's parity, the z-up or y-up car-frame
    # convention by its next bit (so any four consecutive seeds hold every pair), and a yaw.
    units, up = ("mm", "m")[seed % 2], ("z", "y")[(seed // 2) % 2]
    R = Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)
    if up == "y":
        R = Rotation.from_euler("x", -90, degrees=True) * R
    scale = 1.0 if units == "mm" else 1e-3
    v = R.apply(v_all) * scale
    truth.update(units=units, up_axis=up, R_file_part=R.as_matrix().round(12).tolist(),
                 faces=int(len(f_all)), tessellation_step_m=step / 1e3)
    return FamilyPart(family, seed, trimesh.Trimesh(v, f_all, process=False), truth)
