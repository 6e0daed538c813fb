"""Where each panel of a generated car body lies on its surfaces: `cut_panels`.

Every panel is an outline in a plane domain [mm] and a map from that domain onto the body
(`paintcell.surface.body_shape`):
- side panels (front fender, front and rear door, rear quarter) in the left side's developed
  (x, ζ) plane, cut along the wheel arches, the belt line, the A-, B- and C-pillar lines and the
  roof, hood and trunk creases; each stops `gap` short of its front neighbour (the neighbour's
  outline grown by the gap), so a gap drawn is a gap on the body. Doors (and an SUV's quarter
  panels) keep narrow members round their window openings;
- the hood, roof and trunk lid in the (x, y) plan, their edges inset from the crease with the
  wall by `crease_insets`, their corners over the plan outline's corner arcs cut round;
- the bumper fascias in the wall's (s, ζ) plane (front and round the corners onto the sides),
  and an SUV's tailgate in the rear face's (y, ζ) plane with its rear window.

The right side's panels are the left's mirrored (`paintcell.surface.car_body`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from paintcell.surface.body_shape import BodyShape, crease_insets, crown

__all__ = ["Joint", "PanelOutline", "SIDE_PANELS", "cut_panels"]

#: The left side's panels front to rear (each also mirrored on the right).
SIDE_PANELS = ("front_fender", "front_door", "rear_door", "rear_quarter")
Surf = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class PanelOutline:
    """A panel's `domain` (shapely, mm), the `surf` map (u, w) → (…, 3) body points [mm], the
    painter's `side` ("left" for the side panels, mirrored later), and `extra` truth."""

    domain: shapely.Polygon
    surf: Surf
    side: str
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Joint:
    """Two neighbouring panels (side panels by their left name) and the gap drawn [mm]."""

    a: str
    b: str
    gap_mm: float


def _box(x0: float, y0: float, x1: float, y1: float) -> shapely.Polygon:
    return shapely.box(min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))


def _between(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> shapely.Polygon:
    """The region between the curves lo(x) and hi(x) over the samples x."""
    return shapely.Polygon(np.concatenate([np.c_[x, lo], np.c_[x[::-1], hi[::-1]]]))


def _halfplane(p0: tuple[float, float], p1: tuple[float, float],
               toward: tuple[float, float]) -> shapely.Polygon:
    """The half of the plane on the side of the line p0 → p1 that holds `toward`."""
    a, b = np.asarray(p0), np.asarray(p1)
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]])
    n = n if float((np.asarray(toward) - a) @ n) > 0 else -n
    big = 1e5
    return shapely.Polygon([a - big * d, b + big * d, b + big * d + big * n,
                            a - big * d + big * n])


def _largest(g: shapely.Geometry) -> shapely.Polygon:
    """The largest polygon of `g` (a cut can leave slivers)."""
    if isinstance(g, shapely.Polygon):
        return g
    polys = [q for q in getattr(g, "geoms", []) if isinstance(q, shapely.Polygon)]
    return max(polys, key=lambda q: q.area) if polys else shapely.Polygon()


def _window(dom: shapely.Polygon, member_mm: float) -> tuple[shapely.Polygon, list[float]]:
    """`dom` with the window cut from its part above the belt (ζ > 0), `member_mm` in from its
    outline; and the window's area [m²] (none when the part is too narrow)."""
    upper = dom.intersection(_box(-1e5, 0.0, 1e5, 1e5))
    win = _largest(upper.buffer(-member_mm, join_style="mitre"))
    if win.is_empty or win.area <= 0:
        return dom, []
    return _largest(dom.difference(win)), [win.area / 1e6]


class _Cutter:
    """The cut lines of one body [mm] and the steps of `cut_panels`."""

    def __init__(self, s: BodyShape, p: dict[str, Any], suv: bool) -> None:
        self.s, self.p, self.suv = s, p, suv
        oh_f = (p["L"] - p["wb"]) * p["oh_f"]
        self.x_wf = s.Xf - oh_f                         # front wheel centre
        self.x_wr = self.x_wf - p["wb"]
        self.Ra = p["r_w"] + p["arch"]                  # wheel arch radius
        self.x1 = s.Xf - s.Rc - float(np.clip(oh_f - self.Ra - 70 - s.Rc, 40, 160))
        self.x2 = self.x_wf - self.Ra - 60              # fender | front door
        self.x4 = self.x_wr + self.Ra * p["x4"]         # rear door | quarter at the sill
        self.x3 = self.x2 - (self.x2 - self.x4) * p["fd"]
        self.x5 = s.Xr + s.Rc + float(np.clip(self.x_wr - s.Xr - self.Ra - 70 - s.Rc, 40, 160))
        self.x_cowl = self.x2 + p["cowl"]               # the hood's rear edge
        self.x_hf = s.Xf - p["hood_front"]
        self.x_ws = self.x_cowl - p["ws"]               # windshield header
        self.x_Ct = self.x4 + p["C"]                    # C-pillar line at the roof
        self.x_rh = s.Xr if suv else self.x_Ct - p["rh"]    # rear window header
        self.x_df = self.x_rh - p["rw"]                 # the trunk lid's front edge
        self.xs = np.linspace(s.Xr, s.Xf, 801)
        self.g: dict[str, float] = {}
        self.out: dict[str, PanelOutline] = {}

    def h_hood(self, x: np.ndarray) -> np.ndarray:
        t = np.clip((x - self.x_cowl) / (self.x_hf - self.x_cowl), 0, 1)
        return self.s.z_belt - self.p["drop"] * t ** 1.5

    def h_roof(self, x: np.ndarray) -> np.ndarray:
        xm = 0.5 * (self.x_ws + self.x_rh)
        return self.p["z_roof"] - (x - xm) ** 2 / (2 * self.p["Rrx"])

    def h_deck(self, x: np.ndarray) -> np.ndarray:
        return np.full_like(x, self.s.z_belt)

    def below(self, h: Callable[[np.ndarray], np.ndarray], gap: float) -> np.ndarray:
        """ζ of a wall panel's top edge under the crease with a top of heights h, over xs."""
        hx = h(self.xs)
        return self.s.zeta(hx) - crease_insets(gap, self.s.inset_slope(hx))[1]

    def top_surf(self, h: Callable[[np.ndarray], np.ndarray], hc: float) -> Surf:
        s = self.s

        def surf(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            hh = h(x)
            return np.stack([x, y, hh + crown(y, s.crease_y(hh), hc)], -1)
        return surf

    def sides(self) -> None:
        s, p, g, xs = self.s, self.p, self.g, self.xs
        z0, top = float(s.zeta(p["z_low"])), 2000.0
        roof_top = self.below(self.h_roof, g["roof"])
        zt = {x: float(np.interp(x, xs, roof_top)) for x in (self.x_ws - 20, self.x_Ct)}
        up = _box(-1e4, 0.0, 1e4, top).intersection(_between(xs, xs * 0 + z0 - 10, roof_top))
        behind_a = _halfplane((self.x2, 0.0), (self.x_ws - 20, zt[self.x_ws - 20]), (self.x4, 1))
        behind_c = _halfplane((self.x4, 0.0), (self.x_Ct, zt[self.x_Ct]), (self.x5, 1.0))
        arch_z = float(s.zeta(p["r_w"]))
        arches = shapely.union(shapely.Point(self.x_wf, arch_z).buffer(self.Ra, quad_segs=32),
                               shapely.Point(self.x_wr, arch_z).buffer(self.Ra, quad_segs=32))
        fender = _between(xs, xs * 0 + z0, self.below(self.h_hood, g["hood"])).intersection(
            _box(self.x2, -top, self.x1 - g["bf"], top))
        doors = shapely.union(_box(self.x4, z0, self.x2, 0.0),
                              up.intersection(behind_a).difference(behind_c))
        fd = doors.intersection(_box(self.x3, -top, self.x2 + 1, top))
        rd = doors.intersection(_box(-1e4, -top, self.x3, top))
        upper = up.intersection(behind_c)
        qz = xs * 0.0
        if not self.suv:   # the deck's crease behind the rear window, the sail up to the roof
            qz = np.where(xs <= self.x_df, self.below(self.h_deck, g["deck"]), 0.0)
            zr = float(np.interp(self.x_rh, xs, roof_top))
            upper = upper.intersection(_halfplane((self.x_df, 0.0), (self.x_rh, zr),
                                                  (self.x4, 1.0)))
        quarter = shapely.union(_between(xs, xs * 0 + z0, qz), upper).intersection(
            _box(self.x5 + g["qb"], -top, self.x4 + 1000, top))
        cells = [c.difference(arches) for c in (fender, fd, rd, quarter)]
        doms = [cells[0]] + [cells[k].difference(cells[k - 1].buffer(g[key], quad_segs=16))
                             for k, key in enumerate(("ff", "fr", "rq"), start=1)]
        for name, dom in zip(SIDE_PANELS, doms, strict=True):
            dom, wins = _largest(dom), list[float]()
            if name in ("front_door", "rear_door") or (name == "rear_quarter" and self.suv):
                dom, wins = _window(dom, p["member"])
            self.out[name] = PanelOutline(dom, s.side, "left", {
                "developed_area_m2": dom.area / 1e6, "openings_m2": wins,
                "member_width_mm": p["member"] if wins else None})

    def tops(self) -> None:
        s, p, g, xs = self.s, self.p, self.g, self.xs

        def plan(h: Callable[[np.ndarray], np.ndarray], gap: float, x0: float, x1: float
                 ) -> shapely.Polygon:
            hx = h(xs)
            half = s.crease_y(hx) - crease_insets(gap, s.inset_slope(hx))[0]
            return _between(xs, -half, half).intersection(_box(x0, -1e4, x1, 1e4))

        hood = plan(self.h_hood, g["hood"], self.x_cowl, self.x_hf)
        self.out["hood"] = PanelOutline(self.round(hood, 30.0),
                                        self.top_surf(self.h_hood, p["hc_hood"]), "top")
        roof_surf = self.top_surf(self.h_roof, p["hc_roof"])
        roof = plan(self.h_roof, g["roof"], self.x_rh, self.x_ws)
        if self.suv:   # the roof's rear edge stops short of its crease with the tailgate
            ys = np.linspace(-s.Wh, s.Wh, 401)
            xc, _, a = self.rear_crease(ys, roof_surf)
            roof = roof.intersection(shapely.Polygon(
                np.r_[np.c_[xc + a, ys], [[1e4, ys[-1]], [1e4, ys[0]]]]))
        self.out["roof"] = PanelOutline(self.round(roof, float(s.inset(p["z_roof"])) + 30.0),
                                        roof_surf, "top")
        if not self.suv:
            deck = plan(self.h_deck, g["deck"], s.Xr + 30.0, self.x_df - 40.0)
            self.out["trunk_lid"] = PanelOutline(self.round(deck, 30.0),
                                                 self.top_surf(self.h_deck, p["hc_deck"]), "top")

    def rear_crease(self, ys: np.ndarray, roof: Surf
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The roof's crease with the rear face at ys: its x and z, and the roof's inset [mm]."""
        s = self.s
        xc = np.full_like(ys, s.Xr + float(s.inset(self.p["z_roof"])))
        for _ in range(6):   # the crease sits where the rear face reaches the roof's height
            zc = roof(xc, ys)[:, 2]
            xc = s.Xr + s.inset(zc)
        rise = (roof(xc + 1.0, ys)[:, 2] - roof(xc - 1.0, ys)[:, 2]) / 2.0
        return xc, zc, crease_insets(self.g["tailgate_roof"], s.inset_slope(zc), rise)[0]

    def round(self, dom: shapely.Geometry, inset: float) -> shapely.Polygon:
        """`dom` with its corners over the plan outline's corner arcs cut round, `inset` in."""
        s = self.s
        inner = _box(s.Xr + s.Rc, -(s.Wh - s.Rc), s.Xf - s.Rc, s.Wh - s.Rc)
        keep = shapely.union_all([inner.buffer(s.Rc - inset, quad_segs=32),
                                  _box(s.Xr + s.Rc, -1e4, s.Xf - s.Rc, 1e4),
                                  _box(-1e4, -(s.Wh - s.Rc), 1e4, s.Wh - s.Rc)])
        return _largest(dom.intersection(keep))

    def ends(self) -> None:
        s, p, g = self.s, self.p, self.g
        S_f = s.front_end_s + (s.Xf - s.Rc - self.x1)
        S_r = s.front_end_s + (self.x5 - s.Xr - s.Rc)
        zf, zr = (s.zeta(np.array(p[k])).tolist() for k in ("fb", "rb"))

        def rear(u: np.ndarray, zeta: np.ndarray) -> np.ndarray:
            return s.wall(np.where(u < 0, -1.0, 1.0) * (s.half_perimeter - np.abs(u)), zeta)

        for name, S, zz, surf, side, key in (("front_bumper", S_f, zf, s.wall, "front", "fb"),
                                             ("rear_bumper", S_r, zr, rear, "rear", "rb")):
            self.out[name] = PanelOutline(_box(-S, zz[0], S, zz[1]), surf, side, {
                "s_half_mm": S, "z_mm": list(p[key]), "corner_radius_mm": s.Rc,
                "corner_turn_rad": np.pi})
        if self.suv:
            half = s.Wh - s.Rc - p["lamp"]
            ys = np.linspace(-half, half, 201)
            _, zc, _ = self.rear_crease(ys, self.out["roof"].surf)
            b = crease_insets(g["tailgate_roof"], s.inset_slope(zc))[1]
            dom, wins = _window(_between(ys, ys * 0 + zr[1] + g["tb"], s.zeta(zc) - b),
                                p["member"])
            self.out["tailgate"] = PanelOutline(dom, rear, "rear", {
                "developed_area_m2": dom.area / 1e6, "openings_m2": wins,
                "member_width_mm": p["member"]})


def cut_panels(shape: BodyShape, p: dict[str, Any], suv: bool, gaps: Iterator[float]
               ) -> tuple[dict[str, PanelOutline], list[Joint]]:
    """The outlines of a body's panels (the left side's for the side panels) and its joints.

    p: the body's dimensions [mm] (`paintcell.surface.car_body`); gaps: the gap [mm] of each
    joint in turn.
    """
    c = _Cutter(shape, p, suv)
    keys = ["bf", "ff", "fr", "rq", "qb", "hood", "roof"] + \
        (["tailgate_roof", "tb"] if suv else ["deck"])
    c.g = {k: next(gaps) for k in keys}
    c.sides()
    c.tops()
    c.ends()
    pairs = [("front_bumper", "front_fender", "bf"), ("front_fender", "front_door", "ff"),
             ("front_door", "rear_door", "fr"), ("rear_door", "rear_quarter", "rq"),
             ("rear_quarter", "rear_bumper", "qb"), ("hood", "front_fender", "hood"),
             ("roof", "front_door", "roof"), ("roof", "rear_door", "roof"),
             ("roof", "rear_quarter", "roof")]
    pairs += [("tailgate", "roof", "tailgate_roof"), ("tailgate", "rear_bumper", "tb")] if suv \
        else [("trunk_lid", "rear_quarter", "deck")]
    return c.out, [Joint(a, b, c.g[k]) for a, b, k in pairs]
