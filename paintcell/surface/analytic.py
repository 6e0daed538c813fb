"""Surfaces to paint from parametric patches: `Surface`s (a triangle mesh in the part frame [m]
with normals and curvature per vertex) sampled from analytic shapes.

Parametric constructors (`plane`, `cylinder`, `extruded`, `bspline_patch`) sample a regular
(u, v) grid and compute normals and curvature analytically from the first and second fundamental
forms. The `Surface` type (with `surface_from_triangles` and `Surface.from_mesh`, which reads
STL/OBJ/PLY through trimesh and estimates normals and curvature discretely) is in
`paintcell.surface.surface_data`, mesh reading in `paintcell.surface.surface_mesh_input`.

Curvature sign (docs/interfaces.md): with the unit normal n pointing to the painted side, a
principal curvature k is positive when the surface bends away from n — dn = k dr along a principal
direction, so a sphere with outward normal has k1 = k2 = H = +1/R.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.interpolate import BSpline, CubicSpline

from paintcell.core.errors import SurfaceError
from paintcell.surface.surface_data import (
    Surface,
    vertex_areas_barycentric,
)

__all__ = [
    "bspline_patch",
    "cylinder",
    "extruded",
    "greville_abscissae",
    "grid_faces",
    "plane",
    "surface_from_grid",
]

# Parameter-space sampling used to measure arc length of a curve before resampling it [-].
_ARC_SAMPLES = 4001


# --- grid construction helpers ---------------------------------------------------------------
def grid_faces(nu: int, nv: int) -> np.ndarray:
    """(2(nu-1)(nv-1), 3) triangles of a row-major grid, CCW seen from the side of r_u × r_v."""
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    b, c, d = a + nv, a + nv + 1, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)


def _n_samples(length_m: float, resolution_m: float) -> int:
    return max(2, int(np.ceil(length_m / resolution_m - 1e-9)) + 1)


def _check_resolution(resolution_m: float, *lengths: float) -> None:
    if not np.isfinite(resolution_m) or resolution_m <= 0:
        raise SurfaceError(f"resolution_m={resolution_m}; pass a positive grid spacing [m]")
    for length in lengths:
        if not np.isfinite(length) or length <= 0:
            raise SurfaceError(f"surface size {length} m is not positive; pass sizes > 0 [m]")
    if max(lengths) / resolution_m > 20000:
        raise SurfaceError(f"resolution_m={resolution_m} gives > 20000 samples a side; "
                           "use a coarser resolution")


def surface_from_grid(name: str, r: np.ndarray, r_u: np.ndarray, r_v: np.ndarray,
                      r_uu: np.ndarray, r_uv: np.ndarray, r_vv: np.ndarray,
                      uv: np.ndarray, flip: bool = False) -> Surface:
    """Surface from a sampled parametric patch and its derivatives (analytic curvature).

    r, r_u, r_v, r_uu, r_uv, r_vv: (nu, nv, 3) position [m] and partial derivatives.
    uv: (nu, nv, 2) parameters to store [m of arc length].
    flip: painted side is -(r_u × r_v) instead of +(r_u × r_v).
    """
    nu, nv = r.shape[:2]
    f = lambda a: a.reshape(nu * nv, 3)  # noqa: E731
    r, r_u, r_v, r_uu, r_uv, r_vv = map(f, (r, r_u, r_v, r_uu, r_uv, r_vv))
    cr = np.cross(r_u, r_v)
    norm = np.linalg.norm(cr, axis=1)
    if np.any(norm < 1e-12 * np.maximum(1.0, np.linalg.norm(r_u, axis=1) ** 2)):
        raise SurfaceError(f"patch {name!r} is singular (r_u x r_v = 0 somewhere); "
                           "move coincident control points apart")
    sign = -1.0 if flip else 1.0
    n = sign * cr / norm[:, None]
    E, F, G = (r_u * r_u).sum(1), (r_u * r_v).sum(1), (r_v * r_v).sum(1)
    # Second form with the project's sign (k > 0 bends away from n): II = -r_xy · n.
    L, M, N = -(r_uu * n).sum(1), -(r_uv * n).sum(1), -(r_vv * n).sum(1)
    det = E * G - F * F
    K = (L * N - M * M) / det
    H = (E * N - 2 * F * M + G * L) / (2 * det)
    disc = np.sqrt(np.maximum(H * H - K, 0.0))
    k1, k2 = H + disc, H - disc
    # Direction of k1 in (du, dv): a row of (II - k1 I) is orthogonal to it.
    d_a = np.stack([M - k1 * F, -(L - k1 * E)], 1)
    d_b = np.stack([N - k1 * G, -(M - k1 * F)], 1)
    use_b = (d_b * d_b).sum(1) > (d_a * d_a).sum(1)
    d = np.where(use_b[:, None], d_b, d_a)
    t1 = d[:, :1] * r_u + d[:, 1:] * r_v
    t1_norm = np.linalg.norm(t1, axis=1)
    umbilic = t1_norm <= 1e-9 * np.maximum(1.0, np.abs(k1)) * np.sqrt(E * G)
    t1 = np.where(umbilic[:, None], r_u, t1)
    t1 = t1 - (t1 * n).sum(1, keepdims=True) * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    faces = grid_faces(nu, nv)
    if flip:
        faces = faces[:, ::-1].copy()
    return Surface(
        name=name, vertices=np.ascontiguousarray(r), faces=faces, normals=n,
        vertex_areas=vertex_areas_barycentric(r, faces),
        gaussian_curvature=K, mean_curvature=H,
        principal_curvatures=np.stack([k1, k2], 1),
        principal_directions=np.stack([t1, t2], 1),
        uv=np.ascontiguousarray(uv.reshape(nu * nv, 2), dtype=float),
        grid_shape=(int(nu), int(nv)),
    )


# --- parametric constructors -----------------------------------------------------------------
def plane(width_m: float, length_m: float, resolution_m: float = 0.005,
          name: str = "plane") -> Surface:
    """Flat rectangle in z = 0 centred at the origin, painted side +z.

    width_m: extent along x [m] (u direction); length_m: extent along y [m] (v direction).
    resolution_m: grid spacing [m] (rounded so the edges are sampled exactly).
    uv = (x + width/2, y + length/2) [m].
    """
    _check_resolution(resolution_m, width_m, length_m)
    u = np.linspace(0.0, width_m, _n_samples(width_m, resolution_m))
    v = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    U, V = np.meshgrid(u, v, indexing="ij")
    r = np.stack([U - width_m / 2, V - length_m / 2, np.zeros_like(U)], -1)
    one, zero = np.ones_like(U), np.zeros_like(U)
    r_u = np.stack([one, zero, zero], -1)
    r_v = np.stack([zero, one, zero], -1)
    z3 = np.zeros_like(r)
    return surface_from_grid(name, r, r_u, r_v, z3, z3, z3, np.stack([U, V], -1))


def cylinder(radius_m: float, length_m: float, arc_rad: float, resolution_m: float = 0.005,
             name: str = "cylinder") -> Surface:
    """Convex cylinder sector, outside painted, axis along x at (y, z) = (0, -radius).

    The apex line (θ = 0) lies on the x axis at z = 0 with normal +z; θ ∈ [-arc/2, arc/2] turns
    toward ±y. radius_m [m], length_m along x [m], arc_rad opening angle [rad] (< 2π).
    uv = (x + length/2, radius·(θ + arc/2)) [m]. Analytic: K = 0, H = 1/(2R), k1 = 1/R around
    the arc, k2 = 0 along the axis.
    """
    _check_resolution(resolution_m, radius_m, length_m, radius_m * arc_rad)
    if arc_rad >= 2 * np.pi:
        raise SurfaceError(f"arc_rad={arc_rad} >= 2π would close the cylinder; pass < 2π")
    u = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    s = np.linspace(0.0, radius_m * arc_rad, _n_samples(radius_m * arc_rad, resolution_m))
    U, S = np.meshgrid(u, s, indexing="ij")
    th = S / radius_m - arc_rad / 2
    c, sn = np.cos(th), np.sin(th)
    zero, one = np.zeros_like(U), np.ones_like(U)
    r = np.stack([U - length_m / 2, radius_m * sn, radius_m * c - radius_m], -1)
    r_u = np.stack([one, zero, zero], -1)
    r_v = np.stack([zero, c, -sn], -1)
    r_vv = np.stack([zero, -sn, -c], -1) / radius_m
    z3 = np.zeros_like(r)
    return surface_from_grid(name, r, r_u, r_v, z3, z3, r_vv, np.stack([U, S], -1))


def extruded(profile_xy: npt.ArrayLike, length_m: float, resolution_m: float = 0.005,
             name: str = "extruded") -> Surface:
    """Sheet swept along x from a planar profile given in the part's (y, z) plane.

    profile_xy: (P, 2) profile points (y, z) [m], P >= 4, ordered along the profile; they are
        interpolated by a C² cubic spline (chord-length parameter) and resampled at equal arc
        length, so pass points dense enough to define the shape (~1 cm or finer).
    length_m: extrusion length along x [m], centred on x = 0.
    The painted side is the one whose normals point on average toward +z (the profile's left
    side when it runs toward +y). uv = (x + length/2, profile arc length) [m]; curvature is
    analytic from the spline: k1/k2 = profile curvature and 0, K = 0.
    """
    p = np.asarray(profile_xy, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 4 or not np.all(np.isfinite(p)):
        raise SurfaceError(f"profile has shape {p.shape}; pass (P >= 4, 2) finite (y, z) points")
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    if np.any(seg <= 1e-12):
        raise SurfaceError("profile has repeated consecutive points; remove duplicates")
    t = np.concatenate([[0.0], np.cumsum(seg)])
    spl = CubicSpline(t, p, bc_type="natural")
    # Arc length of the spline (trapezoid on a fine grid), then equal-arc-length parameters.
    tf = np.linspace(0.0, t[-1], max(_ARC_SAMPLES, 8 * len(p)))
    sf = np.concatenate([[0.0], np.cumsum(0.5 * (np.linalg.norm(spl(tf, 1), axis=1)[1:]
                                                 + np.linalg.norm(spl(tf, 1), axis=1)[:-1])
                                          * np.diff(tf))])
    arc = float(sf[-1])
    _check_resolution(resolution_m, length_m, arc)
    s = np.linspace(0.0, arc, _n_samples(arc, resolution_m))
    ts = np.interp(s, sf, tf)
    q, dq, ddq = spl(ts), spl(ts, 1), spl(ts, 2)
    u = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    nu, nv = len(u), len(s)
    x = np.broadcast_to((u - length_m / 2)[:, None], (nu, nv))
    zero = np.zeros((nu, nv))

    def lift(yz: np.ndarray, xval: np.ndarray | float) -> np.ndarray:
        return np.stack([np.broadcast_to(xval, (nu, nv)),
                         np.broadcast_to(yz[None, :, 0], (nu, nv)),
                         np.broadcast_to(yz[None, :, 1], (nu, nv))], -1)

    r = lift(q, x)
    r_u = np.stack([np.ones((nu, nv)), zero, zero], -1)
    r_v, r_vv = lift(dq, 0.0), lift(ddq, 0.0)
    z3 = np.zeros_like(r)
    # r_u × r_v = (0, -z', y'): flip when it points on average toward -z (weighted by |r_v|).
    flip = bool(np.sum(dq[:, 0] * np.gradient(s)) < 0)
    U, S = np.meshgrid(u, s, indexing="ij")
    return surface_from_grid(name, r, r_u, r_v, z3, z3, r_vv, np.stack([U, S], -1), flip=flip)


def _clamped_knots(n_ctrl: int, degree: int) -> np.ndarray:
    inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def greville_abscissae(n_ctrl: int, degree: int = 3) -> np.ndarray:
    """(n_ctrl,) Greville parameters in [0, 1] of the clamped uniform knot vector of
    `bspline_patch`; control points placed at linear functions of them reproduce that function."""
    t = _clamped_knots(n_ctrl, degree)
    return np.array([t[i + 1:i + degree + 1].mean() for i in range(n_ctrl)])


def _basis(knots: np.ndarray, degree: int, n_ctrl: int, params: np.ndarray) -> list[np.ndarray]:
    """[B, B', B''] each (len(params), n_ctrl): basis functions and parameter derivatives."""
    spl = BSpline(knots, np.eye(n_ctrl), degree, extrapolate=False)
    out = [spl(params)]
    for k in (1, 2):
        out.append(spl.derivative(k)(params) if degree >= k else np.zeros_like(out[0]))
    return [np.nan_to_num(b) for b in out]


def _arc_length_params(knots: np.ndarray, degree: int, curve_ctrl: np.ndarray,
                       resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameters in [0, 1] at equal arc length along the curve with control points (n, 3),
    and the arc lengths at them [m]."""
    tf = np.linspace(0.0, 1.0, _ARC_SAMPLES)
    _, d1, _ = _basis(knots, degree, len(curve_ctrl), tf)
    speed = np.linalg.norm(d1 @ curve_ctrl, axis=1)
    sf = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(tf))])
    if sf[-1] <= 0:
        raise SurfaceError("a B-spline iso-curve has zero length; spread the control points")
    s = np.linspace(0.0, sf[-1], _n_samples(float(sf[-1]), resolution_m))
    return np.interp(s, sf, tf), s


def bspline_patch(control_points: npt.ArrayLike, degree: int = 3, resolution_m: float = 0.005,
                  name: str = "bspline") -> Surface:
    """Tensor-product B-spline patch (clamped, uniform knots on [0, 1] in both directions).

    control_points: (nu, nv, 3) control net [m], nu, nv > degree; u runs along the first index.
    degree: polynomial degree in both directions (1..5).
    resolution_m: approximate grid spacing [m]: parameters are placed at equal arc length along
        the mid iso-curves, and uv stores those arc lengths [m].
    The painted side is r_u × r_v, flipped if it points on average toward -z.
    Normals, K, H, k1, k2 and principal directions are analytic (fundamental forms).
    """
    C = np.asarray(control_points, dtype=float)
    if C.ndim != 3 or C.shape[2] != 3 or not np.all(np.isfinite(C)):
        raise SurfaceError(f"control_points have shape {C.shape}; pass a finite (nu, nv, 3) net")
    if not 1 <= degree <= 5:
        raise SurfaceError(f"degree={degree}; pass a degree between 1 and 5")
    nu_c, nv_c = C.shape[:2]
    if nu_c <= degree or nv_c <= degree:
        raise SurfaceError(f"control net {nu_c}x{nv_c} is too small for degree {degree}; "
                           f"pass at least {degree + 1} points a side")
    if not np.isfinite(resolution_m) or resolution_m <= 0:
        raise SurfaceError(f"resolution_m={resolution_m}; pass a positive grid spacing [m]")
    tu, tv = _clamped_knots(nu_c, degree), _clamped_knots(nv_c, degree)
    # Mid iso-curves: v = 0.5 (varying u) and u = 0.5 (varying v), as control polygons.
    Bv_mid = _basis(tv, degree, nv_c, np.array([0.5]))[0][0]
    Bu_mid = _basis(tu, degree, nu_c, np.array([0.5]))[0][0]
    pu, su = _arc_length_params(tu, degree, np.einsum("ijk,j->ik", C, Bv_mid), resolution_m)
    pv, sv = _arc_length_params(tv, degree, np.einsum("ijk,i->jk", C, Bu_mid), resolution_m)
    _check_resolution(resolution_m, float(su[-1]), float(sv[-1]))
    Bu, Bu1, Bu2 = _basis(tu, degree, nu_c, pu)
    Bv, Bv1, Bv2 = _basis(tv, degree, nv_c, pv)
    ev = lambda A, B: np.einsum("ai,ijk,bj->abk", A, C, B, optimize=True)  # noqa: E731
    r, r_u, r_v = ev(Bu, Bv), ev(Bu1, Bv), ev(Bu, Bv1)
    r_uu, r_uv, r_vv = ev(Bu2, Bv), ev(Bu1, Bv1), ev(Bu, Bv2)
    flip = bool(np.cross(r_u, r_v)[..., 2].sum() < 0)
    U, V = np.meshgrid(su, sv, indexing="ij")
    return surface_from_grid(name, r, r_u, r_v, r_uu, r_uv, r_vv, np.stack([U, V], -1),
                             flip=flip)
