"""A seeded car body's exterior panels in millimetres, with their truth: `generate_body`.

Even seeds make a compact sedan (front doors, rear doors, front fenders, rear quarter panels with
their C-pillar sail, hood, roof, trunk lid, front and rear bumper fascias), odd seeds an SUV (a
tailgate with its rear window instead of the trunk lid, quarter panels rising to the roof round
the rear side window); the seed also draws the sizes, the radii of the wall and the tops, the
window-frame member widths, every gap (3.5–4.4 mm) and the tessellation. Both sides of the car:
13 panels.

Every panel is a thin sheet, one skin surface with gentle crowns: its outline
(`paintcell.surface.panel_outlines`) meshed as a CAD exporter would
(`paintcell.surface.sheet_mesh.tessellate`) and mapped onto the body's surfaces
(`paintcell.surface.body_shape`), wound toward the painter.

Truth is by construction: each panel's area measured on its triangles, bounding box, mean outward
normal and the painter's side; for the side panels and the tailgate the outline's area in the
wall's developed plane (the wall is a cylinder there, so this is the panel's area) and the window
openings; for the bumpers the figures of their closed-form area; every joint with the gap drawn.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

from paintcell.surface.body_panels import SIDE_DIRECTIONS
from paintcell.surface.body_shape import BodyShape
from paintcell.surface.panel_outlines import SIDE_PANELS, cut_panels
from paintcell.surface.sheet_mesh import tessellate

__all__ = ["CarBody", "generate_body"]

#: The order of the panels in the body's mesh and manifest after the side panels.
_ORDER = ("front_bumper", "hood", "roof", "trunk_lid", "tailgate", "rear_bumper")


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
        m = trimesh.util.concatenate(list(self.panels.values()))
        assert isinstance(m, trimesh.Trimesh)
        return m

    def manifest(self, suffix: str) -> dict[str, Any]:
        """The `body.json` of a folder holding each panel as `<name>.<suffix>` in the body frame
        (`paintcell.surface.body_panels`)."""
        return {"units": "mm", "frame": self.truth["frame"], "seed": self.seed,
                "kind": self.kind,
                "panels": [{"name": n, "file": f"{n}.{suffix}", "side": self.sides[n],
                            "placement": {"xyz_m": [0.0, 0.0, 0.0], "rpy_rad": [0.0, 0.0, 0.0]}}
                           for n in self.panels]}


def _params(seed: int) -> dict[str, Any]:
    """The body's dimensions [mm] and radii for `seed` (even: compact sedan, odd: SUV)."""
    rng = np.random.default_rng([seed, 7919])
    U = rng.uniform
    suv = seed % 2 == 1
    p = dict(L=U(4280, 4400), W=U(1730, 1770), wb=U(2600, 2700), z_belt=U(990, 1030),
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
    p["gaps"] = rng.uniform(3.5, 4.4, 10)
    p["rng"] = rng
    return p



def generate_body(seed: int = 0) -> CarBody:
    """The body of `seed`, deterministic: module doc."""
    p = _params(seed)
    suv = seed % 2 == 1
    shape = BodyShape(Xf=p["L"] / 2, Xr=-p["L"] / 2, Wh=p["W"] / 2, Rc=p["Rc"],
                      z_belt=p["z_belt"], R_low=p["R_low"], R_top=p["R_top"])
    outlines, joints = cut_panels(shape, p, suv, iter(p["gaps"].tolist()))
    rng = p["rng"]
    bstep = min(15.0, 0.4 * p["member"])     # two boundary points across a narrow member
    panels: dict[str, trimesh.Trimesh] = {}
    sides: dict[str, str] = {}
    extra: dict[str, dict[str, Any]] = {}
    for name in [*SIDE_PANELS, *_ORDER]:
        if name not in outlines:
            continue
        o = outlines[name]
        sheet = tessellate(o.domain, p["step"], bstep, rng)
        v = o.surf(sheet.uv[:, 0], sheet.uv[:, 1])
        mirrors = (("_left", 1.0, "left"), ("_right", -1.0, "right")) if o.side == "left" \
            else (("", 1.0, o.side),)
        for suffix, sign, side in mirrors:
            m = trimesh.Trimesh(v * [1.0, sign, 1.0], sheet.faces, process=False)
            panels[name + suffix] = _outward(m, side)
            sides[name + suffix] = side
            extra[name + suffix] = o.extra
    pairs = []
    for j in joints:   # a side panel's joint on each side; a top's or an end's with both sides
        for a, b in zip(_both(j.a), _both(j.b), strict=True):
            rec = {"panels": [a, b], "gap_mm": j.gap_mm}
            if rec not in pairs:
                pairs.append(rec)
    recs = []
    for name, m in panels.items():
        n = (m.face_normals * m.area_faces[:, None]).sum(0)
        recs.append({"name": name, "side": sides[name], "area_m2": m.area / 1e6,
                     "bbox_mm": m.bounds.tolist(), "normal_mean": (n / np.linalg.norm(n)).tolist(),
                     "faces": len(m.faces), **extra[name]})
    truth = {"seed": seed, "kind": "suv" if suv else "compact", "units": "mm",
             "frame": "x forward, y left, z up; origin on the floor under the body's centre",
             "length_mm": p["L"], "width_mm": p["W"], "wheelbase_mm": p["wb"],
             "height_mm": p["z_roof"] + p["hc_roof"],
             "wall": {"R_low_mm": shape.R_low, "R_top_mm": shape.R_top,
                      "z_belt_mm": shape.z_belt},
             "tessellation_step_mm": p["step"], "panels": recs,
             "total_area_m2": float(sum(r["area_m2"] for r in recs)), "joints": pairs}
    return CarBody(seed, truth["kind"], panels, sides, _jsonable(truth))


def _both(name: str) -> list[str]:
    """The left and right panel of a side panel's name; the panel twice for another."""
    return [name + "_left", name + "_right"] if name in SIDE_PANELS else [name, name]


def _outward(m: trimesh.Trimesh, side: str) -> trimesh.Trimesh:
    """`m` wound so its area-weighted normal points to the painter's `side`."""
    n = (m.face_normals * m.area_faces[:, None]).sum(0)
    if float(n @ np.asarray(SIDE_DIRECTIONS[side])) < 0:
        return trimesh.Trimesh(m.vertices, m.faces[:, ::-1], process=False)
    return m


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x
