"""Patches: split a part that one pass family cannot cover, plan each, blend the seams, order them.

Segmentation (`segment`): normal-cone clustering of the faces — k-means on the unit face normals
(area-weighted, deterministic seeds), k raised until every cluster's normals lie within
`max_cone_rad` of its mean, then split into connected pieces and pieces below `min_area_fraction`
of the part merged into the neighbour they share most edges with. Each patch is also measured for
pseudo-extrusion (`extrusion_residual`: how far its normals are from all being perpendicular to
one direction, the paper group's pseudo-extruded patches; 0 for an extruded surface), and
neighbouring patches whose seam is smooth and whose union is pseudo-extruded are merged
(`merge_extruded`): the cone cuts a smooth arch into strips along its axis that one pass family
covers whole (a scanned cowling: 11 strips, planned film σ/μ 29 %, against 2 patches, 8 %), while
a fold or crease (its dihedral angle) stays a seam.

Planning (`plan_patches`): Algorithm 1 on each patch (with its own start curve and widths), its
passes continuing over the seam as over any boundary (overspray and edge passes paint the
neighbour's side of the seam like the virtual extension); seams are then blended by ownership: a
brush-on sample whose paint would land more on other patches than on its own is switched off, so
the overlap band is painted once by the edge tails of both sides rather than twice. Patches are
ordered greedily from the one whose centroid is nearest to `start_point` (the robot), each next
the nearest to the last pass's end.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
from scipy.sparse.csgraph import connected_components

from paintcell.core.errors import PlanError
from paintcell.coverage.plan import CoveragePlan, PassPlan
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate
from paintcell.surface.surface_data import Surface, surface_from_triangles

if TYPE_CHECKING:
    from paintcell.coverage.coverage_settings import PlannerSettings


@dataclass(frozen=True, eq=False)
class Patch:
    """One patch: faces (F_k,) indices into the part's faces; surface: its own `Surface`
    (vertices renumbered; `vertex_ids` maps them back); cone_rad: largest angle of a face
    normal from the patch's mean normal; extrusion_residual: see `extrusion_residual`."""

    faces: np.ndarray
    surface: Surface
    vertex_ids: np.ndarray
    cone_rad: float
    extrusion_residual: float


def face_normals_areas(surface: Surface) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) on the painted side and face areas (F,) [m²]."""
    t = surface.vertices[surface.faces]
    cr = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    a = 0.5 * np.linalg.norm(cr, axis=1)
    return cr / np.maximum(2 * a, 1e-30)[:, None], a


def extrusion_residual(normals: np.ndarray, areas: np.ndarray) -> float:
    """Area-weighted RMS of n·d for the best direction d (smallest singular vector of the
    weighted normals) [-]: 0 when every normal is perpendicular to one direction (extruded)."""
    w = np.sqrt(areas / areas.sum())[:, None]
    s = np.linalg.svd(normals * w, compute_uv=False)
    return float(s[-1])


def _cone(normals: np.ndarray, areas: np.ndarray) -> float:
    m = (normals * areas[:, None]).sum(axis=0)
    m /= max(np.linalg.norm(m), 1e-30)
    return float(np.arccos(np.clip(normals @ m, -1.0, 1.0)).max())


def _face_adjacency(surface: Surface) -> sp.csr_matrix:
    adj = surface.mesh.face_adjacency
    n = len(surface.faces)
    g = sp.coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(n, n))
    return (g + g.T).tocsr()


#: largest extrusion residual of a merged patch [-] (RMS sine of the normals' tilt out of the
#: plane perpendicular to the extrusion direction: 0.1 ≈ 6°); a scanned arch measures 0.05–0.07.
MAX_EXTRUSION_RESIDUAL = 0.1
#: largest median dihedral angle [rad] across the seam of two patches merged (a smooth seam:
#: k-means cut a smooth surface there, ~1°; a fold or crease is tens of degrees).
MAX_SEAM_RAD = np.radians(10.0)


def merge_extruded(piece: np.ndarray, nf: np.ndarray, af: np.ndarray, adj: sp.csr_matrix,
                   max_seam_rad: float = MAX_SEAM_RAD,
                   max_residual: float = MAX_EXTRUSION_RESIDUAL) -> np.ndarray:
    """Face labels with neighbouring pieces merged, greedily (the union with the smallest
    extrusion residual first), while their seam is smooth (median dihedral angle across its
    edges ≤ max_seam_rad) and the union is pseudo-extruded (residual ≤ max_residual): one pass
    family along the extrusion covers it, as it covers a cylinder, so the normal cone's cuts
    through a smooth arch leave no seams to blend."""
    piece = piece.copy()
    rows, cols = sp.triu(adj).nonzero()
    ang = np.arccos(np.clip(np.sum(nf[rows] * nf[cols], axis=1), -1.0, 1.0))
    while True:                              # at most P − 1 merges of a few patches
        a, b = piece[rows], piece[cols]
        cut = a != b
        if not cut.any():
            return piece
        lo, hi = np.minimum(a[cut], b[cut]), np.maximum(a[cut], b[cut])
        pairs, inv = np.unique(np.column_stack([lo, hi]), axis=0, return_inverse=True)
        best, best_r = None, max_residual
        for k, (i, j) in enumerate(pairs):   # neighbouring pairs of a few patches
            if np.median(ang[cut][inv.ravel() == k]) > max_seam_rad:
                continue
            u = (piece == i) | (piece == j)
            r = extrusion_residual(nf[u], af[u])
            if r <= best_r:
                best, best_r = (i, j), r
        if best is None:
            return piece
        piece[piece == best[1]] = best[0]


def segment(surface: Surface, max_cone_rad: float = np.radians(30.0),
            min_area_fraction: float = 0.05, max_k: int = 12,
            max_seam_rad: float = MAX_SEAM_RAD,
            max_residual: float = MAX_EXTRUSION_RESIDUAL) -> np.ndarray:
    """(F,) patch label of every face (0..P−1, largest patch first); see the module docstring."""
    nf, af = face_normals_areas(surface)
    adj = _face_adjacency(surface)
    labels = np.zeros(len(nf), int)
    for k in range(1, max_k + 1):
        if k > 1:
            # deterministic seeds: the normals farthest apart, greedily (k rows)
            seeds = [int(np.argmax(af))]
            for _ in range(k - 1):
                d = np.min(nf @ nf[seeds].T, axis=1)
                seeds.append(int(np.argmin(d)))
            with warnings.catch_warnings():
                # an emptied cluster only means fewer patches; the cone test below judges them
                warnings.filterwarnings("ignore", "One of the clusters is empty", UserWarning)
                _, labels = kmeans2(nf, nf[seeds], minit="matrix", iter=20)
        if all(_cone(nf[labels == c], af[labels == c]) <= max_cone_rad
               for c in np.unique(labels)):
            break
    # connected pieces of each cluster
    rows, cols = adj.nonzero()
    keep = labels[rows] == labels[cols]
    g = sp.coo_matrix((np.ones(keep.sum()), (rows[keep], cols[keep])), shape=adj.shape)
    _, piece = connected_components(g, directed=False)
    # merge small pieces into the neighbour sharing most edges
    total = af.sum()
    for _ in range(len(np.unique(piece))):
        area = np.bincount(piece, weights=af)
        small = [p for p in np.unique(piece) if area[p] < min_area_fraction * total]
        if not small:
            break
        p = min(small, key=lambda q: area[q])
        nb = piece[cols[(piece[rows] == p) & (piece[cols] != p)]]
        if len(nb) == 0:
            break
        piece[piece == p] = np.bincount(nb).argmax()
    piece = merge_extruded(piece, nf, af, adj, max_seam_rad, max_residual)
    # relabel, largest first
    uniq = np.unique(piece)
    area = np.array([af[piece == u].sum() for u in uniq])
    order = uniq[np.argsort(-area)]
    out = np.empty_like(piece)
    for i, u in enumerate(order):
        out[piece == u] = i
    return out


def patches_of(surface: Surface, labels: np.ndarray) -> list[Patch]:
    """The patches of a segmentation as their own surfaces."""
    nf, af = face_normals_areas(surface)
    out = []
    for c in range(int(labels.max()) + 1):
        fi = np.flatnonzero(labels == c)
        f = surface.faces[fi]
        vid = np.unique(f)
        remap = np.full(len(surface.vertices), -1)
        remap[vid] = np.arange(len(vid))
        s = surface_from_triangles(f"{surface.name}#{c}", surface.vertices[vid], remap[f])
        out.append(Patch(fi, s, vid, _cone(nf[fi], af[fi]), extrusion_residual(nf[fi], af[fi])))
    return out


def seam_volumes(app: Applicator, passes: list[PassPlan], own: np.ndarray,
                 surface: Surface) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per pass, the film volume rates [m³/s] each sample puts on its own patch and on the
    others (own: (N,) bool, the surface vertices of the passes' patch)."""
    w_own = np.where(own, surface.vertex_areas, 0.0)
    w_other = np.where(own, 0.0, surface.vertex_areas)
    out = []
    for p in passes:                        # tens of passes
        rate = deposition_rate(app, p.positions, p.spray_axes, p.travel_dirs,
                               surface.vertices, surface.normals)
        out.append((rate @ w_own, rate @ w_other))
    return out


def ownership_brush_off(passes: list[PassPlan], volumes: list[tuple[np.ndarray, np.ndarray]],
                        share: float) -> tuple[list[PassPlan], int]:
    """Switch off brush-on samples whose paint lands on other patches more than `share` × on
    their own (`volumes` from `seam_volumes`)."""
    out, n_off = [], 0
    for p, (v_own, v_other) in zip(passes, volumes, strict=True):
        off = p.paint_on & (v_other > share * v_own)
        n_off += int(off.sum())
        out.append(dataclasses.replace(p, paint_on=p.paint_on & ~off) if off.any() else p)
    return out, n_off


#: seam shares tried by `plan_patches` (the blend whose film is most uniform is kept).
SEAM_SHARES = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.5, 2.0)


def plan_patches(surface: Surface, app: Applicator, settings: object = None,
                 labels: np.ndarray | None = None,
                 start_point: np.ndarray | None = None,
                 speed_caps_m_s: dict[int, np.ndarray] | None = None,
                 tool_x: dict[int, np.ndarray] | None = None) -> CoveragePlan:
    """Plan every patch with Algorithm 1, blend the seams, order the patches; one `CoveragePlan`
    of the whole part (passes' `side` renumbered in execution order; `settings["report"]`
    lists the patches: faces, area, cone, extrusion residual, passes, samples switched off, and
    the seam share chosen).

    Blending: the seam share (`ownership_brush_off`) is chosen among `SEAM_SHARES` as the one
    whose film over the whole part (deposition model on the real mesh) has the smallest σ/μ.
    speed_caps_m_s / tool_x: as `plan_coverage`'s, keyed by the pass's index in this plan's
    execution order (its `side`); each patch with some is planned again under its own (the
    patches' passes and order come from their plans without them, which they do not move)."""
    from paintcell.coverage.coverage_family import plan_family
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.paint.deposition import thickness
    from paintcell.paint.metrics import uniformity

    st = settings if settings is not None else PlannerSettings()
    if not isinstance(st, PlannerSettings):
        raise PlanError("plan_patches settings must be PlannerSettings or None")
    labels = segment(surface) if labels is None else np.asarray(labels, int)
    pts = patches_of(surface, labels)
    # several patches: each planned without the film refinement, which then re-times every pass
    # together against the film of the whole part, seams included (one patch: refined as one)
    refine_whole = len(pts) > 1 and st.optimize_speed and st.film_refine
    st_patch = dataclasses.replace(st, film_refine=False) if refine_whole else st
    raw = _uncapped_plans(pts, app, st_patch)
    # order: nearest patch first, then nearest to where the last pass ended
    here = (np.zeros(3) if start_point is None else np.asarray(start_point, float))
    todo = list(range(len(raw)))
    order: list[int] = []
    while todo:                            # a few patches
        cent = [np.mean([p.positions.mean(axis=0) for p in raw[i]], axis=0) for i in todo]
        i = todo[int(np.argmin([np.linalg.norm(c - here) for c in cent]))]
        order.append(i)
        todo.remove(i)
        here = raw[i][-1].positions[-1]
    first = {i: int(sum(len(raw[k]) for k in order[:order.index(i)])) for i in order}
    caps_exec: list[np.ndarray | None] = []
    if speed_caps_m_s or tool_x:
        for i, pt in enumerate(pts):        # a few patches
            loc_caps = _local(speed_caps_m_s, raw[i], first[i])
            loc_x = _local(tool_x, raw[i], first[i])
            if loc_caps or loc_x:
                again = list(plan_family(pt.surface, app, st_patch, loc_caps, loc_x).passes)
                if [len(p.positions) for p in again] != [len(p.positions) for p in raw[i]]:
                    raise PlanError(f"patch {i} planned under speed caps / bell axes has other "
                                    "passes; they must come from a plan of the same part and "
                                    "settings")
                raw[i] = again
        n_all = sum(len(r) for r in raw)
        for n in range(n_all):
            c = None if speed_caps_m_s is None else speed_caps_m_s.get(n)
            caps_exec.append(None if c is None else (np.asarray(c, float)[::-1] if n % 2 == 1
                                                     else np.asarray(c, float)))
    vols = []
    for pt, r in zip(pts, raw, strict=True):
        own = np.zeros(len(surface.vertices), bool)
        own[pt.vertex_ids] = True
        vols.append(seam_volumes(app, r, own, surface))

    def blended(share: float) -> tuple[list[list[PassPlan]], list[int]]:
        res = [ownership_brush_off(r, v, share) for r, v in zip(raw, vols, strict=True)]
        return [x[0] for x in res], [x[1] for x in res]

    def nsd(share: float) -> float:
        plans, _ = blended(share)
        gun = CoveragePlan(surface_name=surface.name, applicator=app,
                           passes=tuple(p for ps in plans for p in ps)).gun_samples()
        film = thickness(app, gun, surface.vertices, surface.normals)
        return uniformity(film, surface.vertex_areas).nsd_pct

    share = SEAM_SHARES[int(np.argmin([nsd(x) for x in SEAM_SHARES]))] if len(pts) > 1 else 1.0
    plans, n_offs = blended(share)
    report = [{"patch": k, "faces": len(pt.faces), "area_m2": pt.surface.area,
               "cone_deg": float(np.degrees(pt.cone_rad)),
               "extrusion_residual": pt.extrusion_residual, "passes": len(plans[k]),
               "samples_switched_off_at_seams": n_offs[k]} for k, pt in enumerate(pts)]
    passes = [dataclasses.replace(p, side=n) for n, p in
              enumerate(p for i in order for p in plans[i])]
    refine: dict[str, Any] = {}
    if refine_whole:      # the whole part within the robot's caps, as one family is refined
        from paintcell.coverage.coverage_family import jsonable
        from paintcell.coverage.film_refine import refine_plan

        passes, refine = refine_plan(app, surface, passes, st, caps_exec or None)
        refine = jsonable(refine)
    sd = dict(st.to_dict(), patches=True)
    sd["report"] = {"patches": report, "order": order, "seam_share": share,
                    "film_refine": refine}
    return CoveragePlan(surface_name=surface.name, applicator=app, passes=tuple(passes),
                        start_rule="patches", settings=sd)


def _uncapped_plans(pts: list[Patch], app: Applicator, st: PlannerSettings
                    ) -> list[list[PassPlan]]:
    """Each patch's plan without caps: a robot-aware re-plan of the same part and settings
    (`paintcell.motion.speed_feedback`, for one robot or N) needs their passes and order,
    which caps do not move; `plan_family` re-times the pass geometry kept from the first plan
    (`paintcell.coverage.family_geometry`), so asking again is cheap."""
    from paintcell.coverage.coverage_family import plan_family

    return [list(plan_family(pt.surface, app, st).passes) for pt in pts]


def _local(by_pass: dict[int, np.ndarray] | None, patch_passes: list[PassPlan],
           first: int) -> dict[int, np.ndarray]:
    """The per-pass arrays of a whole patch plan (keyed by execution index n, in generation
    order: reversed when n is odd) that belong to one patch whose passes run from `first`, keyed
    by that patch's own sides in its own generation order (`plan_family`'s convention)."""
    out: dict[int, np.ndarray] = {}
    for j, p in enumerate(patch_passes):    # tens of passes
        a = None if by_pass is None else by_pass.get(first + j)
        if a is None:
            continue
        a = np.asarray(a, float)
        out[int(p.side)] = a[::-1] if (first + j) % 2 != j % 2 else a
    return out
