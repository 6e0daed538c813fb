"""Index-width optimization (paper §4): the planar σ/μ curve (Fig. 5), and the extruded /
curved-surface search over known and future passes (eq. 3) on reduced-dimension cross profiles.

Reduced model. Around a pass sample, the surface is approximated by the extrusion of its indexing
curve along the pass tangent T (paper §4.3, Fig. 7(a)). A straight pass along T with the gun at
standoff h over the curve point c(σ) deposits, at curve point c(s), the line integral of the real
deposition rate (`paintcell.paint.deposition.deposition_rate`) over the gun's travel x:

    film(σ → s) = (1 / v) ∫ rate(c(σ) + h n(σ) + x T ; c(s), n(s)) dx

`cross_profiles` tabulates film(σ_g → s_p) for gun positions on a grid of the search resolution
and profile points along the curve (a (G, P) matrix); the deposition of any set of passes on the
optimization profile is then a sum of rows, so the brute-force search over future widths is a few
array operations. On a plane the same integral at all passes gives the Fig. 5 curve.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PlanError
from paintcell.coverage.offset import IndexingCurve
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate

#: Step of the gun's travel x in the line integral, as a fraction of the smallest Gaussian σ of the
#: model [-]. The integrand is a sum of smooth Gaussians in x, for which the plain sum converges
#: spectrally: error ~ exp(-2π²σ²/dx²) ≈ 1e-21 at dx = σ/2.5 (checked against the closed form in
#: tests/test_index_width.py).
_DX_PER_SIGMA = 0.4
#: Travel range of the line integral on a curved section, in footprint radii [-] (see
#: `cross_profiles`).
_X_RANGE_FACTOR = 1.25
#: Rows of gun positions per `deposition_rate` call (keeps the dense temporaries ~20 MB).
_ROWS_PER_CALL = 8


def _dx(app: Applicator) -> float:
    sig = [app.sigma_x_m, app.sigma_y_m]
    sig += [float(s) for a, s in zip(app.ring_amplitudes_m_s, app.ring_sigmas_m, strict=True)
            if a > 0]
    return _DX_PER_SIGMA * min(sig)


def profile_size(app: Applicator) -> tuple[int, int]:
    """(gun samples, profile points) of the index-width curve's dense matrix for `app`, the
    sizes `paintcell.core.budget.check_profile_budget` checks against the memory there is."""
    r = app.footprint_radius_m
    n_gun = int(2 * _X_RANGE_FACTOR * r / _dx(app)) + 1
    n_pts = int(2 * r / min(5e-4, r / 400)) + 1
    return n_gun, n_pts


#: Default bell's footprint radius [m] (`paintcell.paint.applicator.Applicator.default`): the
#: width-search budget's assumption when a scenario's applicator is not read yet.
DEFAULT_FOOTPRINT_M = 0.3


def search_size(st: Any, footprint_radius_m: float = DEFAULT_FOOTPRINT_M) -> dict[str, int]:
    """The sides of the width search's dense arrays for `PlannerSettings` `st` (as
    `paintcell.coverage.coverage_planner` builds them for `search_widths`): widths tried W,
    future-width sets C, profile points P, gun positions G, future passes n — the sizes
    `paintcell.core.budget.check_planner_budget` checks against the memory there is."""
    w = len(search_range(st.w_min_m, st.w_max_m, st.w_res_m))
    c = min(max(1, st.future_grid_n), w) ** max(st.n_future - 1, 0)
    p = int(2 * st.w_max_m / st.profile_spacing_m) + 1
    g = 2 * int(np.ceil((st.w_max_m + footprint_radius_m + st.w_res_m) / st.w_res_m)) + 1
    return {"W": w, "C": c, "P": p, "G": g, "n": st.n_future}


def search_range(w_min_m: float, w_max_m: float, w_res_m: float) -> np.ndarray:
    """(W,) the index-width search range SR: multiples of w_res in [w_min, w_max] [m]."""
    if not (0 < w_min_m <= w_max_m) or not w_res_m > 0:
        raise PlanError(f"index search range [{w_min_m}, {w_max_m}] at {w_res_m} is invalid; "
                        "need 0 < w_min <= w_max and w_res > 0 [m]")
    k = np.arange(int(np.ceil(w_min_m / w_res_m - 1e-9)), int(np.floor(w_max_m / w_res_m + 1e-9))
                  + 1)
    if len(k) == 0:
        raise PlanError(f"no multiple of w_res = {w_res_m} m lies in [{w_min_m}, {w_max_m}]; "
                        "widen the range or refine w_res")
    return k * w_res_m


def single_pass_profile(app: Applicator, lateral_m: npt.ArrayLike,
                        speed_m_s: float = 1.0) -> np.ndarray:
    """(P,) film [m] across one straight pass over a plane at standoff, at lateral offsets (P,) [m].

    The gun runs along x at height h over the plane z = 0 (spray axis −z) at `speed_m_s`; the
    film at (0, y) is (1/v) ∫ rate dx (which on a facing plane is ∫ f(x, y) dx / v).
    """
    y = np.asarray(lateral_m, float).reshape(-1)
    r = _X_RANGE_FACTOR * app.footprint_radius_m     # the same travel range as cross_profiles
    dx = _dx(app)
    x = np.arange(-r, r + 0.5 * dx, dx)
    gun = np.stack([x, np.zeros_like(x), np.full_like(x, app.standoff_m)], axis=1)
    axes = np.tile([0.0, 0.0, -1.0], (len(x), 1))
    travel = np.tile([1.0, 0.0, 0.0], (len(x), 1))
    pts = np.stack([np.zeros_like(y), y, np.zeros_like(y)], axis=1)
    nrm = np.tile([0.0, 0.0, 1.0], (len(y), 1))
    return deposition_rate(app, gun, axes, travel, pts, nrm).sum(axis=0) * dx / speed_m_s


def nsd_vs_index_width(app: Applicator, widths: npt.ArrayLike,
                       n_profile: int = 200) -> np.ndarray:
    """(W,) σ/μ (fraction) of the film of infinitely many parallel straight passes on a plane at
    each index width (W,) [m] — the paper's Fig. 5.

    All passes that reach the profile are summed (|k w| ≤ footprint radius + w); the profile is
    one period between two central passes, sampled at `n_profile` uniform points (the film is
    periodic, so this is the σ/μ of the whole interior).
    """
    w = np.asarray(widths, float).reshape(-1)
    if np.any(w <= 0) or not np.all(np.isfinite(w)):
        raise PlanError("index widths must be finite and > 0 [m]")
    r = app.footprint_radius_m
    dy = min(5e-4, r / 400)
    y = np.arange(-r, r + 0.5 * dy, dy)
    g = single_pass_profile(app, y)
    out = np.empty(len(w))
    for i, wi in enumerate(w):           # a handful of widths; each row is vectorized
        k = np.arange(-int(np.ceil(r / wi)) - 1, int(np.ceil(r / wi)) + 2)
        yq = (np.arange(n_profile) + 0.5) / n_profile * wi
        film = np.interp(yq[None, :] - k[:, None] * wi, y, g, left=0.0, right=0.0).sum(axis=0)
        out[i] = film.std() / film.mean()
    return out


@dataclass(frozen=True)
class PlanarWidth:
    """Planar index-width choice (paper §4.1).

    width_m: the largest robustly feasible width (see `planar_index_width`), or the σ/μ
        minimizer when none is feasible [m]; feasible: whether u_max was met; widths_m / nsd: the
        Fig. 5 curve over the search range (σ/μ as fractions); tolerance_m: the sensitivity
        window used.
    """

    width_m: float
    feasible: bool
    widths_m: np.ndarray
    nsd: np.ndarray
    tolerance_m: float = 0.0


def robust_feasible(widths_m: np.ndarray, nsd: np.ndarray, u_max: float,
                    tolerance_m: float) -> np.ndarray:
    """(W,) bool: σ/μ ≤ u_max at w and at every searched width within ±tolerance_m of it.

    The paper (§4.1) chooses w_max "according to the standard deviation sensitivity": near the
    sweet spot σ/μ changes fast with the width, so a width is only accepted when a pass placed
    `tolerance_m` [m] off still meets u_max. widths_m (W,) increasing [m]; nsd (W,) fractions.
    Widths whose window reaches past the searched range are judged on the part inside it.
    """
    w = np.asarray(widths_m, float)
    ok = np.asarray(nsd, float) <= u_max
    if tolerance_m <= 0:
        return ok
    near = np.abs(w[:, None] - w[None, :]) <= tolerance_m + 1e-9
    return np.all(~near | ok[None, :], axis=1)


def planar_index_width(app: Applicator, w_min_m: float, w_max_m: float, w_res_m: float,
                       u_max: float, tolerance_m: float = 0.0) -> PlanarWidth:
    """Choose the planar index width (paper §4.1): cost ∝ 1/w over the feasible set, i.e. the
    largest width whose σ/μ stays ≤ u_max within ±tolerance_m [m] (`robust_feasible`; 0: the
    plain rule σ/μ(w) ≤ u_max). u_max is a fraction (0.04 = 4 %)."""
    widths = search_range(w_min_m, w_max_m, w_res_m)
    # the curve is evaluated a tolerance beyond SR so the window of the widest width is judged
    pad = np.arange(1, int(np.ceil(tolerance_m / w_res_m - 1e-9)) + 1) * w_res_m
    ext = np.concatenate([widths[0] - pad[::-1], widths, widths[-1] + pad])
    ext = ext[ext > 0]
    nsd_ext = nsd_vs_index_width(app, ext)
    inside = (ext >= widths[0] - 1e-12) & (ext <= widths[-1] + 1e-12)
    ok = robust_feasible(ext, nsd_ext, u_max, tolerance_m)[inside]
    nsd = nsd_ext[inside]
    if ok.any():
        return PlanarWidth(float(widths[ok].max()), True, widths, nsd, tolerance_m)
    return PlanarWidth(float(widths[int(np.argmin(nsd))]), False, widths, nsd, tolerance_m)


def cross_profiles(app: Applicator, curve: IndexingCurve, travel_dir: npt.ArrayLike,
                   gun_s: npt.ArrayLike, point_s: npt.ArrayLike) -> np.ndarray:
    """(G, P) film [m] at 1 m/s on the local extruded surface: row g is the cross profile at the
    curve points `point_s` (P,) [m] of a straight pass along `travel_dir` (3,) with the gun at
    standoff over curve position `gun_s[g]` (G,) [m].

    The extrusion runs along travel_dir, so normals are projected onto the indexing plane
    (⟂ travel_dir). Beyond the curve's ends the curve continues straight (virtual extension).
    """
    t = np.asarray(travel_dir, float)
    t = t / np.linalg.norm(t)
    gp, gn, _ = curve.sample(gun_s)
    pp, pn, _ = curve.sample(point_s)
    gn = gn - np.outer(gn @ t, t)
    gn /= np.linalg.norm(gn, axis=1, keepdims=True)
    pn = pn - np.outer(pn @ t, t)
    pn /= np.linalg.norm(pn, axis=1, keepdims=True)
    # On a convex section the surface falls away from the reference plane (dz up to ~1.2 h inside
    # the spray cone of a 1 m radius), so the travel range reaching a point grows as R·dz/h.
    r = _X_RANGE_FACTOR * app.footprint_radius_m
    dx = _dx(app)
    x = np.arange(-r, r + 0.5 * dx, dx)
    nx = len(x)
    film = np.empty((len(gp), len(pp)))
    for i in range(0, len(gp), _ROWS_PER_CALL):       # chunks of gun positions (memory bound)
        sl = slice(i, min(i + _ROWS_PER_CALL, len(gp)))
        g = len(gp[sl])
        pos = (gp[sl] + app.standoff_m * gn[sl])[:, None, :] + x[None, :, None] * t
        axes = np.repeat(-gn[sl], nx, axis=0)
        rate = deposition_rate(app, pos.reshape(-1, 3), axes, np.tile(t, (g * nx, 1)), pp, pn)
        film[sl] = rate.reshape(g, nx, -1).sum(axis=1) * dx
    return film


@dataclass(frozen=True)
class WidthSearch:
    """Result of the brute-force search at one marker (eq. 3).

    widths_m: (W,) candidate w0 [m]; best_nsd: (W,) min over future-width sets of σ/μ on the
    optimization profile (fraction); feasible = best_nsd ≤ u_max.
    """

    widths_m: np.ndarray
    best_nsd: np.ndarray


def search_widths(film: np.ndarray, gun_step_m: float, gun_s0_index: int, point_s: np.ndarray,
                  known_s: npt.ArrayLike, widths: np.ndarray, future_widths: np.ndarray,
                  n_future: int, w_prev_m: float | None) -> WidthSearch:
    """Brute force over future passes (paper §4.2): for each candidate w0 the best σ/μ on the
    optimization profile between C−1 and C1 over all future-width sets.

    film: (G, P) cross profiles (`cross_profiles`) for gun positions s_g = (g − gun_s0_index) ·
        gun_step_m [m] and profile points point_s (P,) [m] (uniform spacing).
    known_s: positions of the known passes other than the current one (≤ 0) [m]; the current
        pass C0 is at s = 0. widths: (W,) candidate w0 (multiples of gun_step_m) [m];
    future_widths: (F,) widths tried for C1→C2, …, C(n−1)→Cn [m]; n_future: n ≥ 1.
    w_prev_m: w−1 [m] (the profile starts at −w−1), or None when C0 is the start curve with no
        known neighbour: the other side is assumed to mirror the candidate set (profile
        [−w0, w0]).
    """
    g_count, _ = film.shape
    zero = np.zeros((1, film.shape[1]))
    table = np.concatenate([film, zero])                 # row G: a pass out of reach
    fut = np.array(list(itertools.product(future_widths, repeat=max(n_future - 1, 0))),
                   dtype=float).reshape(-1, max(n_future - 1, 0))
    steps = np.concatenate([np.broadcast_to(widths[:, None, None], (len(widths), len(fut), 1)),
                            np.broadcast_to(fut[None], (len(widths), len(fut), fut.shape[1]))],
                           axis=2)
    right = np.cumsum(steps, axis=2)                     # (W, C, n) positions of C1..Cn
    parts = [right]
    if w_prev_m is None:
        parts.append(-right)                             # mirrored future passes on the left
    pos = np.concatenate(parts, axis=2)

    def rows(s: np.ndarray) -> np.ndarray:
        k = np.rint(s / gun_step_m).astype(np.int64) + gun_s0_index
        return np.where((k >= 0) & (k < g_count), k, g_count)

    base = table[rows(np.array([0.0]))].sum(axis=0)
    known = np.asarray(known_s, float).reshape(-1)
    if len(known):
        base = base + table[rows(known)].sum(axis=0)
    total = base[None, None, :] + table[rows(pos)].sum(axis=2)      # (W, C, P)
    left = -widths if w_prev_m is None else np.full(len(widths), -float(w_prev_m))
    mask = (point_s[None, :] >= left[:, None] - 1e-9) & (point_s[None, :] <= widths[:, None]
                                                         + 1e-9)    # (W, P)
    m = mask[:, None, :].astype(float)
    cnt = m.sum(axis=2)
    mean = (total * m).sum(axis=2) / cnt
    var = (((total - mean[..., None]) ** 2) * m).sum(axis=2) / cnt
    nsd = np.sqrt(var) / np.where(mean > 0, mean, np.inf)
    nsd = np.where(mean > 0, nsd, np.inf)
    return WidthSearch(widths_m=widths, best_nsd=nsd.min(axis=1))


def choose_constant_width(searches: list[WidthSearch], u_max: float, w_prev_m: float | None,
                          change_weight: float = 1.0,
                          tolerance_m: float = 0.0) -> tuple[float, bool, float]:
    """Pick w0 under the constant-index restriction (paper §4.3): feasible at every marker, cost
    w_max/w0 + change_weight · |w0 − w−1| / w_max (small widths and width changes penalized).

    tolerance_m: a width is feasible only when the worst-marker σ/μ meets u_max within ±tolerance_m
    [m] of it too (`robust_feasible`, the paper's sensitivity rule for w_max).
    Returns (w0 [m], feasible, worst-marker σ/μ at w0 (fraction)). When no width is feasible at
    all markers, the width with the smallest worst-marker σ/μ is returned with feasible False.
    """
    widths = searches[0].widths_m
    worst = np.max(np.stack([s.best_nsd for s in searches]), axis=0)
    ok = robust_feasible(widths, worst, u_max, tolerance_m)
    wmax = float(widths.max())
    if ok.any():
        cost = wmax / widths
        if w_prev_m is not None:
            cost = cost + change_weight * np.abs(widths - w_prev_m) / wmax
        cost = np.where(ok, cost, np.inf)
        i = int(np.argmin(cost))
        return float(widths[i]), True, float(worst[i])
    i = int(len(worst) - 1 - np.argmin(worst[::-1]))     # ties → the larger width
    return float(widths[i]), False, float(worst[i])
