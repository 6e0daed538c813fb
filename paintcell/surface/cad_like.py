"""Seeded generator of car-part meshes as a CAD system exports them (test fixtures with truth).

Each part is an outer panel — a crowned skin with a character crease (a door also has a handle
recess and a window opening), hemmed all round: the skin turns 180° round a bend of radius
`BEND_R_MM` at its edge and runs back under itself as a flange `HEM_MM` wide — plus an inner panel
(a frame under the skin, its edge held inside the hem) as a separate piece. Coordinates are in
millimetres; the tessellation is coarse and uneven (grid lines up to 170 mm apart, jittered by the
seed, random diagonals, refined only at the crease and the recess) and has a few slivers (grid
lines 2 µm apart, the needles a CAD exporter leaves at trimmed edges).

Truth is by construction, independent of any detection: `CadPart.truth` holds the area of the
skin, of the hem (the half of the bend past 90° and the flange), of the inner panel, and of each
opening (the polygon of its fold line), all in m².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = ["BEND_R_MM", "CadPart", "HEM_MM", "PART_KINDS", "make_part"]

BEND_R_MM = 1.0
HEM_MM = 12.0
_BEND_SEGMENTS = 6          # 30° each: the 90° line is a mesh line
_INNER_FRAME_MM = 90.0      # width of the inner panel's frame inside the outline
_SLIVER_GAP_MM = 0.002

#: Sizes [mm] (u along the part, w across), crowns [mm radius] and features of each kind.
_SPECS: dict[str, dict[str, float]] = {
    "door": dict(W=1100.0, H=1150.0, Ru=9000.0, Rw=3000.0, crease_w=-80.0, crease_s=0.06,
                 window=1.0, handle=1.0),
    "hood": dict(W=1500.0, H=1250.0, Ru=3500.0, Rw=2500.0, crease_w=300.0, crease_s=0.05,
                 window=0.0, handle=0.0),
    "fender": dict(W=1000.0, H=700.0, Ru=5000.0, Rw=700.0, crease_w=120.0, crease_s=0.05,
                   window=0.0, handle=0.0),
    "roof": dict(W=1600.0, H=1300.0, Ru=6000.0, Rw=3500.0, crease_w=-450.0, crease_s=0.04,
                 window=0.0, handle=0.0),
}
PART_KINDS = tuple(_SPECS)


@dataclass(frozen=True, eq=False)
class CadPart:
    """A generated part: mesh in mm, per-face construction label, and truth areas [m²].

    labels: (F,) "skin" | "hem" | "inner" (the bend's front half counts as skin).
    truth: skin_m2, hem_m2, inner_m2, window_m2 (0 without a window), size_m (W, H).
    """

    kind: str
    mesh: trimesh.Trimesh
    labels: np.ndarray
    truth: dict[str, float]


def _lines(rng: np.random.Generator, lo: float, hi: float, must: list[float],
           fine: tuple[float, float, float] | None) -> np.ndarray:
    """Uneven grid coordinates from lo to hi [mm]: 60–170 mm steps, `must` lines included,
    10 mm steps inside `fine` = (a, b, step)."""
    pts = [lo, hi, *must]
    x = lo
    while x < hi:
        x += rng.uniform(60.0, 170.0)
        if x < hi - 30.0:
            pts.append(x)
    if fine is not None:
        pts.extend(np.arange(fine[0], fine[1] + 1e-9, fine[2]))
    xs = np.unique(np.round(np.asarray(pts), 6))
    keep = np.concatenate([[True], np.diff(xs) > 8.0])  # drop lines closer than 8 mm
    for m in must:
        keep |= np.isclose(xs, m)
    return np.unique(xs[keep])


def make_part(kind: str, seed: int = 0) -> CadPart:
    """Generate a door, hood, fender or roof (mm) with its truth; deterministic for a seed."""
    if kind not in _SPECS:
        raise ValueError(f"unknown part kind {kind!r}; choose one of {', '.join(PART_KINDS)}")
    s = _SPECS[kind]
    rng = np.random.default_rng(seed)
    W, H = s["W"], s["H"]
    win = (-0.36 * W, 0.36 * W, 0.17 * H, 0.45 * H) if s["window"] else None
    hu, hw = (0.22 * W, 0.05 * H) if s["handle"] else (0.0, 0.0)

    def height(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        z = -(u**2) / (2 * s["Ru"]) - w**2 / (2 * s["Rw"])
        z = z - s["crease_s"] * np.sqrt((w - s["crease_w"]) ** 2 + 9.0)   # crease, ~3 mm round
        if s["handle"]:
            z = z - 18.0 * np.exp(-((u - hu) / 80.0) ** 4 - ((w - hw) / 30.0) ** 4)
        return z

    must_u = [-W / 2, W / 2] + ([win[0], win[1]] if win else [])
    must_w = [-H / 2, H / 2, s["crease_w"]] + ([win[2], win[3]] if win else [])
    us = _lines(rng, -W / 2, W / 2, must_u, (hu - 130, hu + 130, 10.0) if s["handle"] else None)
    ws = _lines(rng, -H / 2, H / 2, must_w, (hw - 60, hw + 60, 10.0) if s["handle"] else None)
    # Slivers: two grid lines a hair's width beside existing ones.
    for arr in (us,):
        i = rng.choice(np.arange(2, len(arr) - 2), 2, replace=False)
        arr = np.sort(np.concatenate([arr, arr[i] + _SLIVER_GAP_MM]))
        us = arr
    U, Wg = np.meshgrid(us, ws, indexing="ij")
    P = np.stack([U, Wg, height(U, Wg)], -1)
    nu, nw = U.shape
    idx = np.arange(nu * nw).reshape(nu, nw)
    cu = 0.5 * (us[:-1] + us[1:])
    cw = 0.5 * (ws[:-1] + ws[1:])
    inside = np.ones((nu - 1, nw - 1), bool)
    if win:
        inside &= ~((cu[:, None] > win[0]) & (cu[:, None] < win[1])
                    & (cw[None, :] > win[2]) & (cw[None, :] < win[3]))
    a, b = idx[:-1, :-1][inside], idx[1:, :-1][inside]
    c, d = idx[1:, 1:][inside], idx[:-1, 1:][inside]
    flip = rng.random(len(a)) < 0.5
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    V = [P.reshape(-1, 3)]
    F = [np.concatenate([t1, t2])]
    L = [np.full(2 * len(a), "skin")]
    nv = len(V[0])

    def add(verts: np.ndarray, faces: np.ndarray, label: np.ndarray) -> None:
        nonlocal nv
        V.append(verts)
        F.append(faces + nv)
        L.append(label)
        nv += len(verts)

    def loop(iu0: int, iu1: int, iw0: int, iw1: int) -> np.ndarray:
        """Grid indices round a rectangle of grid lines, counter-clockwise in (u, w)."""
        bot = idx[iu0:iu1, iw0]
        right = idx[iu1, iw0:iw1]
        top = idx[iu1:iu0:-1, iw1]
        left = idx[iu0, iw1:iw0:-1]
        return np.concatenate([bot, right, top, left])

    outer = loop(0, nu - 1, 0, nw - 1)
    loops = [(outer, 1.0)]
    if win:
        iu = [int(np.argmin(abs(us - x))) for x in win[:2]]
        iw = [int(np.argmin(abs(ws - x))) for x in win[2:]]
        loops.append((loop(iu[0], iu[1], iw[0], iw[1])[::-1], -1.0))
    pn = trimesh.Trimesh(P.reshape(-1, 3), F[0], process=False).vertex_normals
    window_m2 = 0.0
    for lp, sgn in loops:
        p = P.reshape(-1, 3)[lp]
        n = pn[lp] * np.sign(pn[lp][:, 2:3])                   # skin normal, +z side
        t = np.roll(p, -1, 0) - np.roll(p, 1, 0)               # loop tangent
        m = np.cross(t, n)                                      # outward in the skin
        m -= (m * n).sum(1, keepdims=True) * n
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        # Mitre at corners: the offset along m must move both edges by the same distance.
        e_prev = p - np.roll(p, 1, 0)
        e_prev /= np.linalg.norm(e_prev, axis=1, keepdims=True)
        sin_edge = np.linalg.norm(np.cross(e_prev, m), axis=1)
        m = m / np.clip(sin_edge, 0.5, 1.0)[:, None]
        th = np.linspace(0.0, np.pi, _BEND_SEGMENTS + 1)
        ring = [p + BEND_R_MM * ((np.cos(t_) - 1) * n + np.sin(t_) * m) for t_ in th[1:]]
        ring += [p - 2 * BEND_R_MM * n - HEM_MM * m]
        k = len(p)
        rows = np.stack([lp] + [nv + i * k + np.arange(k) for i in range(len(ring))])
        verts = np.concatenate(ring)
        faces, labs = [], []
        for r in range(len(rows) - 1):
            r0, r1 = rows[r], rows[r + 1]
            q0, q1 = np.roll(r0, -1), np.roll(r1, -1)
            fa = np.concatenate([np.stack([r0, q0, q1], 1), np.stack([r0, q1, r1], 1)])
            faces.append(fa)
            labs.append(np.full(len(fa), "skin" if r < _BEND_SEGMENTS // 2 else "hem"))
        fa = np.concatenate(faces)
        # Wind the strips as the skin: their first ring must face the skin's side.
        allv = np.concatenate([P.reshape(-1, 3), np.zeros((nv - len(P.reshape(-1, 3)), 3)),
                               verts])
        first = fa[: len(fa) // len(faces)]
        nf = np.cross(allv[first[:, 1]] - allv[first[:, 0]], allv[first[:, 2]] - allv[first[:, 0]])
        if float((nf * n[np.arange(len(first)) % k]).sum()) < 0:
            fa = fa[:, ::-1]
        V.append(verts)
        F.append(fa)
        L.append(np.concatenate(labs))
        nv += len(verts)
        if sgn < 0:
            q = np.roll(p, -1, 0)
            window_m2 = 0.5 * float(np.linalg.norm(np.cross(p - p.mean(0), q - p.mean(0)).sum(0)))
    # Inner panel: a frame held in the hem's middle at the outline, sloping 40 mm down inside.
    fr = _INNER_FRAME_MM
    iu_ = np.array([-W / 2 + 1, -W / 2 + fr, W / 2 - fr, W / 2 - 1])
    iw_ = np.array([-H / 2 + 1, -H / 2 + fr, H / 2 - fr, H / 2 - 1])
    IU, IW = np.meshgrid(iu_, iw_, indexing="ij")
    depth = np.where((np.abs(IU) < W / 2 - 2) & (np.abs(IW) < H / 2 - 2), 40.0, 0.0)
    IP = np.stack([IU, IW, height(IU, IW) - BEND_R_MM - depth], -1).reshape(-1, 3)
    ii = np.arange(16).reshape(4, 4)
    quads = [(i, j) for i in range(3) for j in range(3) if (i, j) != (1, 1)]
    inner_f = np.array([f for i, j in quads for f in
                        ([ii[i, j], ii[i + 1, j], ii[i + 1, j + 1]],
                         [ii[i, j], ii[i + 1, j + 1], ii[i, j + 1]])])
    add(IP, inner_f, np.full(len(inner_f), "inner"))
    v = np.concatenate(V)
    f = np.concatenate(F).astype(np.int64)
    lab = np.concatenate(L)
    mesh = trimesh.Trimesh(v, f, process=False)
    area = mesh.area_faces * 1e-6
    truth = {"skin_m2": float(area[lab == "skin"].sum()), "hem_m2": float(area[lab == "hem"].sum()),
             "inner_m2": float(area[lab == "inner"].sum()), "window_m2": window_m2 * 1e-6,
             "width_m": W * 1e-3, "height_m": H * 1e-3}
    return CadPart(kind, mesh, lab, truth)
