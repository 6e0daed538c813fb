"""A seeded car body's exterior panels in millimetres, with their truth: `generate_body`.

Even seeds make a compact sedan (front doors, rear doors, fenders, rear quarter panels with their
C-pillar sail, hood, roof, trunk lid, bumper fascias), odd seeds an SUV (a tailgate instead of the
trunk lid, its quarter panels rising to the roof round the rear side window); the seed also draws
the sizes, the radii of the wall and the tops, the window-frame member widths, every gap and the
tessellation. Both sides of the car, 14 panels in all.

Every panel is a thin sheet: a region of a plane domain meshed as a CAD exporter would
(`paintcell.surface.sheet_mesh.tessellate`) and mapped onto the body's surfaces
(`paintcell.surface.body_shape`). Side panels and the tailgate are cut from the wall's developed
(x, ζ) or (s, ζ) plane, neighbours `gap` apart there, so a gap drawn is a gap on the body; a top
meets the wall panels below it along a crease, both stopping short of it by `crease_insets`. Doors
are a lower panel and a window frame of narrow members round the window opening.

Truth is by construction: each panel's area measured on its triangles, bounding box, mean outward
normal, the painter's side, its outline area in the developed plane (side panels, tailgate: the
wall is a cylinder there, so this is the panel's area), the window openings, every joint with the
gap drawn, and the figures the bumper's closed-form area needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
import trimesh

from paintcell.surface.body_panels import SIDE_DIRECTIONS
from paintcell.surface.body_shape import BodyShape, crease_insets, crown
from paintcell.surface.sheet_mesh import tessellate

__all__ = ["CarBody", "generate_body"]

_SIDE_PANELS = ("front_fender", "front_door", "rear_door", "rear_quarter")


@dataclass(frozen=True, eq=False)
class CarBody:
    """A generated body: `panels` (name → mesh in mm, body frame, faces wound toward the
    painter), `sides` (name → "left" | "right" | "top" | "front" | "rear") and `truth`
    (JSON-ready: module doc)."""

    seed: int
    kind: str
    panels: dict[str, trimesh.Trimesh]
    sides: dict[str, str]
    truth: dict[str, Any]

    def mesh(self) -> trimesh.Trimesh:
        """Every panel in one mesh [mm] (panels in `panels` order)."""
        return trimesh.util.concatenate(list(self.panels.values()))

    def manifest(self, suffix: str) -> dict[str, Any]:
        """The `body.json` of a folder holding each panel as `<name>.<suffix>` in the body frame
        (`paintcell.surface.body_panels`)."""
        return {"units": "mm", "frame": self.truth["frame"], "seed": self.seed,
                "kind": self.kind,
                "panels": [{"name": n, "file": f"{n}.{suffix}", "side": self.sides[n],
                            "placement": {"xyz_m": [0.0, 0.0, 0.0], "rpy_rad": [0.0, 0.0, 0.0]}}
                           for n in self.panels]}


def _box(x0: float, y0: float, x1: float, y1: float) -> shapely.Polygon:
    return shapely.box(min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))


def _curve_poly(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> shapely.Polygon:
    """The region between the curves lo(x) and hi(x) over the samples x."""
    return shapely.Polygon(np.concatenate([np.c_[x, lo], np.c_[x[::-1], hi[::-1]]]))


def _params(seed: int) -> dict[str, float]:
    """The body's dimensions [mm] and radii for `seed` (even: compact sedan, odd: SUV)."""
    rng = np.random.default_rng([seed, 7919])
    U = rng.uniform
    suv = seed % 2 == 1
    p = dict(L=U(4330, 4480), W=U(1730, 1780), wb=U(2600, 2700), z_belt=U(990, 1030),
             z_roof=U(1580, 1630), r_w=U(345, 365), z_low=U(350, 380), Rc=U(240, 280),
             fb=(U(300, 330), U(700, 740)), rb=(U(330, 360), U(720, 760)), drop=U(60, 110),
             ws=U(740, 820), C=U(0, 40), R_top=U(850, 1000)) if suv else \
        dict(L=U(4150, 4350), W=U(1720, 1790), wb=U(2520, 2650), z_belt=U(880, 930),
             z_roof=U(1400, 1470), r_w=U(300, 320), z_low=U(270, 300), Rc=U(200, 240),
             fb=(U(190, 220), U(580, 640)), rb=(U(220, 250), U(620, 670)), drop=U(90, 150),
             ws=U(600, 700), C=U(150, 250), R_top=U(1000, 1400))
    p.update(R_low=U(3500, 5000), oh_f=U(0.5, 0.56), arch=U(45, 60),
             cowl=U(40, 80), x4=U(0.2, 0.4), fd=U(0.52, 0.56), Rrx=U(6000, 9000),
             hc_hood=U(30, 50), hc_roof=U(25, 40), hc_deck=U(20, 35), rh=U(100, 160),
             rw=U(420, 520), hood_front=U(160, 240), member=U(45, 70), lamp=U(50, 90),
             step=U(30, 42))
    p["gaps"] = rng.uniform(3.5, 4.4, 16)
    p["rng"] = rng
    return p


def generate_body(seed: int = 0) -> CarBody:
    """The body of `seed` (deterministic): module doc."""
    p = _params(seed)
    suv = seed % 2 == 1
    shape = BodyShape(Xf=p["L"] / 2, Xr=-p["L"] / 2, Wh=p["W"] / 2, Rc=p["Rc"],
                      z_belt=p["z_belt"], R_low=p["R_low"], R_top=p["R_top"])
    gaps = iter(p["gaps"].tolist())
    b = _Builder(shape, p, suv)
    joints = b.side_cells(gaps)
    joints += b.tops(gaps)
    joints += b.ends(gaps)
    return b.finish(seed, "suv" if suv else "compact", joints)


class _Builder:
    """Cuts the panels of one body from its surfaces (the steps of `generate_body`)."""

    def __init__(self, shape: BodyShape, p: dict[str, Any], suv: bool) -> None:
        self.s, self.p, self.suv = shape, p, suv
        self.domains: dict[str, tuple[shapely.Geometry, Any, str]] = {}
        self.extra: dict[str, dict[str, Any]] = {}
        s = shape
        oh_f = (p["L"] - p["wb"]) * p["oh_f"]
        self.x_wf = s.Xf - oh_f
        self.x_wr = self.x_wf - p["wb"]
        self.Ra = p["r_w"] + p["arch"]
        ls_f = float(np.clip(oh_f - self.Ra - 70 - s.Rc, 40, 160))
        ls_r = float(np.clip(self.x_wr - s.Xr - self.Ra - 70 - s.Rc, 40, 160))
        self.x1 = s.Xf - s.Rc - ls_f                   # front bumper wing ends
        self.x2 = self.x_wf - self.Ra - 60             # fender | front door
        self.x4 = self.x_wr + self.Ra * p["x4"]        # rear door | quarter at the sill
        self.x3 = self.x2 - (self.x2 - self.x4) * p["fd"]
        self.x5 = s.Xr + s.Rc + ls_r                   # rear bumper wing ends
        self.x_cowl = self.x2 + p["cowl"]
        self.x_hf = s.Xf - p["hood_front"]
        self.x_ws = self.x_cowl - p["ws"]
        self.x_Ct = self.x4 + p["C"]
        self.x_rh = self.x_Ct - p["rh"] if not suv else s.Xr
        self.x_df = self.x_rh - p["rw"]
        self.zeta_low = float(s.zeta(p["z_low"]))

    # -- heights of the tops ------------------------------------------------------------
    def h_hood(self, x: np.ndarray) -> np.ndarray:
        t = np.clip((x - self.x_cowl) / (self.x_hf - self.x_cowl), 0, 1)
        return self.s.z_belt - self.p["drop"] * t ** 1.5

    def h_roof(self, x: np.ndarray) -> np.ndarray:
        xm = 0.5 * (self.x_ws + (self.x_rh if not self.suv else self.s.Xr))
        return self.p["z_roof"] - (x - xm) ** 2 / (2 * self.p["Rrx"])

    def top_edge(self, h: Any, gap: float) -> tuple[Any, Any]:
        """(a, wall ζ of the panel's top edge) for a crease with a top at heights h(x)."""
        def edge(x: np.ndarray) -> np.ndarray:
            a, b = crease_insets(gap, self.s.inset_slope(h(x)))
            return self.s.zeta(h(x)) - b
        return edge

    # -- side panels ----------------------------------------------------------------------
    def side_cells(self, gaps: Any) -> list[dict[str, Any]]:
        s, p = self.s, self.p
        g = {k: next(gaps) for k in ("bf", "ff", "fr", "rq", "qb", "hood", "roof", "deck")}
        self.g = g
        z0 = self.zeta_low
        top = 2000.0
        xs = np.linspace(s.Xr, s.Xf, 801)
        hood_top = self.top_edge(self.h_hood, g["hood"])
        roof_top = self.top_edge(self.h_roof, g["roof"])
        arches = shapely.union(
            shapely.Point(self.x_wf, float(s.zeta(p["r_w"]))).buffer(self.Ra, quad_segs=32),
            shapely.Point(self.x_wr, float(s.zeta(p["r_w"]))).buffer(self.Ra, quad_segs=32))
        below_roof = _curve_poly(xs, np.full_like(xs, z0 - 10), roof_top(xs))
        up = _box(-1e4, 0.0, 1e4, top).intersection(below_roof)
        zt = {x: float(roof_top(np.array([x]))[0]) for x in (self.x_ws - 20, self.x_Ct)}
        behind_a = _halfplane((self.x2, 0.0), (self.x_ws - 20, zt[self.x_ws - 20]),
                              (self.x4, 1.0))
        behind_c = _halfplane((self.x4, 0.0), (self.x_Ct, zt[self.x_Ct]), (self.x5, 1.0))
        fender = _curve_poly(xs, np.full_like(xs, z0), hood_top(xs)).intersection(
            _box(self.x2, -top, self.x1 - g["bf"], top))
        lower = _box(self.x4, z0, self.x2, 0.0)
        doors = shapely.union(lower, up.intersection(behind_a).difference(behind_c))
        fd = doors.intersection(_box(self.x3, -top, self.x2 + 1, top))
        rd = doors.intersection(_box(-1e4, -top, self.x3, top))
        if not self.suv:   # deck crease behind the rear window, the sail up to the roof
            deck_top = self.top_edge(lambda x: np.full_like(x, s.z_belt), g["deck"])
            qz = np.where(xs <= self.x_df, deck_top(xs), 0.0)
            window = _halfplane((self.x_df, 0.0), (self.x_rh, float(roof_top(
                np.array([self.x_rh]))[0])), (self.x4, 1.0))
            upper = up.intersection(behind_c).intersection(window)
        else:
            qz = np.zeros_like(xs)
            upper = up.intersection(behind_c)
        quarter = shapely.union(_curve_poly(xs, np.full_like(xs, z0), qz), upper).intersection(
            _box(self.x5 + g["qb"], -top, self.x4 + 1000, top))
        cells = [c.difference(arches) for c in (fender, fd, rd, quarter)]
        panels = [cells[0]]
        for k, key in enumerate(("ff", "fr", "rq"), start=1):
            panels.append(cells[k].difference(cells[k - 1].buffer(g[key], quad_segs=16)))
        for name, dom in zip(_SIDE_PANELS, panels, strict=True):
            dom = _largest(dom)
            windows = []
            if name in ("front_door", "rear_door") or (name == "rear_quarter" and self.suv):
                upper = dom.intersection(_box(-1e5, 0.0, 1e5, top))
                win = _largest(upper.buffer(-p["member"], join_style="mitre"))
                if not win.is_empty and win.area > 0:
                    dom = dom.difference(win)
                    windows.append(win.area / 1e6)
            self.domains[name] = (dom, s.side, "left")
            self.extra[name] = {"developed_area_m2": dom.area / 1e6,
                                "openings_m2": windows, "member_width_mm": p["member"]
                                if windows else None}
        pairs = [("front_bumper", "front_fender", "bf"), ("front_fender", "front_door", "ff"),
                 ("front_door", "rear_door", "fr"), ("rear_door", "rear_quarter", "rq"),
                 ("rear_quarter", "rear_bumper", "qb"), ("hood", "front_fender", "hood"),
                 ("roof", "front_door", "roof"), ("roof", "rear_door", "roof"),
                 ("roof", "rear_quarter", "roof")]
        if not self.suv:
            pairs.append(("trunk_lid", "rear_quarter", "deck"))
        return [{"panels": [a, b], "gap_mm": g[k]} for a, b, k in pairs]

    # -- hood, roof, trunk lid --------------------------------------------------------------
    def tops(self, gaps: Any) -> list[dict[str, Any]]:
        s, p, g = self.s, self.p, self.g
        xs = np.linspace(s.Xr, s.Xf, 801)

        def top(h: Any, hc: float, gap: float, x0: float, x1: float
                ) -> tuple[shapely.Geometry, Any]:
            hx = h(xs)
            a, _ = crease_insets(gap, s.inset_slope(hx))
            half = s.crease_y(hx) - a
            dom = _curve_poly(xs, -half, half).intersection(_box(x0, -1e4, x1, 1e4))

            def surf(x: np.ndarray, y: np.ndarray) -> np.ndarray:
                hh = h(x)
                return np.stack([x, y, hh + crown(y, s.crease_y(hh), hc)], -1)
            return dom, surf

        hood, hs = top(self.h_hood, p["hc_hood"], g["hood"], self.x_cowl, self.x_hf)
        self.domains["hood"] = (self._round(hood, 30.0), hs, "top")
        x_rear = s.Xr if self.suv else self.x_rh
        roof, rs = top(self.h_roof, p["hc_roof"], g["roof"], x_rear, self.x_ws)
        joints: list[dict[str, Any]] = []
        if self.suv:
            g_tg = next(gaps)
            self.g["tailgate_roof"] = g_tg
            ys = np.linspace(-s.Wh, s.Wh, 401)
            xc, zc, a = self._rear_crease(ys, rs, g_tg)
            keep = shapely.Polygon(np.r_[np.c_[xc + a, ys], [[1e4, ys[-1]], [1e4, ys[0]]]])
            roof = roof.intersection(keep)
            joints.append({"panels": ["tailgate", "roof"], "gap_mm": g_tg})
        self.domains["roof"] = (self._round(roof, float(s.inset(p["z_roof"])) + 30.0), rs, "top")
        if not self.suv:
            deck, ds = top(lambda x: np.full_like(x, s.z_belt), p["hc_deck"], g["deck"],
                           s.Xr + 30.0, self.x_df - 40.0)
            self.domains["trunk_lid"] = (self._round(deck, 30.0), ds, "top")
        return joints

    def _rear_crease(self, ys: np.ndarray, roof_surf: Any, gap: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The roof's crease with the rear face at ys: x, z and the roof's inset a [mm]."""
        s = self.s
        xc = np.full_like(ys, s.Xr + float(s.inset(self.p["z_roof"])))
        for _ in range(6):
            zc = roof_surf(xc, ys)[:, 2]
            xc = s.Xr + s.inset(zc)
        rise = (roof_surf(xc + 1.0, ys)[:, 2] - roof_surf(xc - 1.0, ys)[:, 2]) / 2.0
        a, _ = crease_insets(gap, s.inset_slope(zc), rise)
        return xc, zc, a

    def _round(self, dom: shapely.Geometry, inset: float) -> shapely.Geometry:
        """`dom` with its corners over the plan outline's corner arcs cut round."""
        s = self.s
        outline = _box(s.Xr + s.Rc, -(s.Wh - s.Rc), s.Xf - s.Rc, s.Wh - s.Rc).buffer(
            s.Rc - inset, quad_segs=32)
        keep = shapely.union_all([outline, _box(s.Xr + s.Rc, -1e4, s.Xf - s.Rc, 1e4),
                                  _box(-1e4, -(s.Wh - s.Rc), 1e4, s.Wh - s.Rc)])
        return _largest(dom.intersection(keep))

    # -- bumpers and tailgate --------------------------------------------------------------
    def ends(self, gaps: Any) -> list[dict[str, Any]]:
        s, p, g = self.s, self.p, self.g
        S_f = s.front_end_s + (s.Xf - s.Rc - self.x1)
        S_r = s.front_end_s + (self.x5 - s.Xr - s.Rc)
        zf = [float(v) for v in s.zeta(np.array(p["fb"]))]
        zr = [float(v) for v in s.zeta(np.array(p["rb"]))]

        def rear(u: np.ndarray, zeta: np.ndarray) -> np.ndarray:
            return s.wall(np.where(u < 0, -1.0, 1.0) * (s.half_perimeter - np.abs(u)), zeta)

        self.domains["front_bumper"] = (_box(-S_f, zf[0], S_f, zf[1]), s.wall, "front")
        self.domains["rear_bumper"] = (_box(-S_r, zr[0], S_r, zr[1]), rear, "rear")
        for name, S, zz in (("front_bumper", S_f, p["fb"]), ("rear_bumper", S_r, p["rb"])):
            self.extra[name] = {"s_half_mm": S, "z_mm": list(zz), "corner_radius_mm": s.Rc,
                                "corner_turn_rad": np.pi}
        if not self.suv:
            return []
        g_tb = next(gaps)
        half = s.Wh - s.Rc - p["lamp"]
        ys = np.linspace(-half, half, 201)
        _, zc, _ = self._rear_crease(ys, self.domains["roof"][1], g["tailgate_roof"])
        _, b = crease_insets(g["tailgate_roof"], s.inset_slope(zc))
        dom = _curve_poly(ys, np.full_like(ys, zr[1] + g_tb), s.zeta(zc) - b)
        upper = dom.intersection(_box(-1e4, 0.0, 1e4, 1e4))
        win = _largest(upper.buffer(-p["member"], join_style="mitre"))
        dom = dom.difference(win)
        self.domains["tailgate"] = (dom, rear, "rear")
        self.extra["tailgate"] = {"developed_area_m2": dom.area / 1e6,
                                  "openings_m2": [win.area / 1e6],
                                  "member_width_mm": p["member"]}
        return [{"panels": ["tailgate", "rear_bumper"], "gap_mm": g_tb}]

    # -- meshes and truth -------------------------------------------------------------------
    def finish(self, seed: int, kind: str, joints: list[dict[str, Any]]) -> CarBody:
        p, s = self.p, self.s
        rng = p["rng"]
        step = p["step"]
        bstep = min(15.0, 0.4 * p["member"])
        panels: dict[str, trimesh.Trimesh] = {}
        sides: dict[str, str] = {}
        extra: dict[str, dict[str, Any]] = {}
        order = ["front_bumper", "hood", "roof", "trunk_lid", "tailgate", "rear_bumper"]
        for name in [*_SIDE_PANELS, *order]:
            if name not in self.domains:
                continue
            dom, surf, side = self.domains[name]
            sheet = tessellate(dom, step, bstep, rng)
            v = surf(sheet.uv[:, 0], sheet.uv[:, 1])
            m = _outward(trimesh.Trimesh(v, sheet.faces, process=False), side)
            if side == "left":
                for sd, sign in (("left", 1.0), ("right", -1.0)):
                    mm = trimesh.Trimesh(v * [1.0, sign, 1.0], sheet.faces, process=False)
                    panels[f"{name}_{sd}"] = _outward(mm, sd)
                    sides[f"{name}_{sd}"] = sd
                    extra[f"{name}_{sd}"] = self.extra[name]
            else:
                panels[name], sides[name] = m, side
                extra[name] = self.extra.get(name, {})
        all_joints = []
        for j in joints:
            a, b = j["panels"]
            for sd in ("left", "right"):
                na = f"{a}_{sd}" if a in _SIDE_PANELS else a
                nb = f"{b}_{sd}" if b in _SIDE_PANELS else b
                pair = {"panels": [na, nb], "gap_mm": j["gap_mm"]}
                if pair not in all_joints:
                    all_joints.append(pair)
        recs = []
        for name, m in panels.items():
            n = (m.face_normals * m.area_faces[:, None]).sum(0)
            recs.append({"name": name, "side": sides[name], "area_m2": m.area / 1e6,
                         "bbox_mm": m.bounds.tolist(),
                         "normal_mean": (n / np.linalg.norm(n)).tolist(),
                         "faces": len(m.faces), **extra[name]})
        truth = {"seed": seed, "kind": kind, "units": "mm", "frame": "x forward, y left, z up; "
                 "origin on the floor under the body's centre",
                 "length_mm": p["L"], "width_mm": p["W"], "wheelbase_mm": p["wb"],
                 "height_mm": p["z_roof"] + p["hc_roof"], "belt_z_mm": s.z_belt,
                 "wall": {"R_low_mm": s.R_low, "R_top_mm": s.R_top, "z_belt_mm": s.z_belt},
                 "tessellation_step_mm": step, "panels": recs,
                 "total_area_m2": float(sum(r["area_m2"] for r in recs)),
                 "joints": all_joints}
        return CarBody(seed, kind, panels, sides, _jsonable(truth))


def _outward(m: trimesh.Trimesh, side: str) -> trimesh.Trimesh:
    """`m` wound so its area-weighted normal points to the painter's `side`."""
    n = (m.face_normals * m.area_faces[:, None]).sum(0)
    if float(n @ np.asarray(SIDE_DIRECTIONS[side])) < 0:
        return trimesh.Trimesh(m.vertices, m.faces[:, ::-1], process=False)
    return m


def _halfplane(p0: tuple[float, float], p1: tuple[float, float],
               toward: tuple[float, float]) -> shapely.Polygon:
    """The half of the plane on the side of the line p0 → p1 that holds the point `toward`
    (a large polygon)."""
    a, b = np.asarray(p0), np.asarray(p1)
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]])
    n = n if float((np.asarray(toward) - a) @ n) > 0 else -n
    big = 1e5
    return shapely.Polygon([a - big * d, b + big * d, b + big * d + big * n,
                            a - big * d + big * n])


def _largest(g: shapely.Geometry) -> shapely.Geometry:
    """The largest polygon of `g` (cuts can leave slivers), or `g` when it is one polygon."""
    if isinstance(g, shapely.Polygon):
        return g
    polys = [q for q in getattr(g, "geoms", []) if isinstance(q, shapely.Polygon)]
    return max(polys, key=lambda q: q.area) if polys else shapely.Polygon()


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x
