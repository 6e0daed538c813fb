"""The film of a run as data (`film.npz`) and the spec-window numbers the report leads with.

`paintcell run` (and `paintcell validate`) write `film.npz` into the results folder: the film per
surface vertex, planned and executed [m], the vertex areas [m²], which vertices are judged (a real
part's skin; every vertex of a library part), the surface's vertices [m] and faces with the
judged faces, and the paint spec's window: ±`tolerance` around `target_m` (the scenario's
`[spec]`, `paintcell.validation.paint_spec`; the window behind `executed_inside_spec_pct`). The
report reads it to draw the thickness histogram against the window and to state the share of
the judged area inside it; anyone can recompute that share from the arrays alone (over the
judged faces, the film linear on each: `paintcell.validation.paint_spec.share_in_window`).
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.atomic_io import atomic_write_npz
from paintcell.core.errors import PaintcellError

FILM_NAME = "film.npz"
#: matplotlib colormap of the spec map: blues below the window, greens inside, reds above.
SPEC_CMAP = "paintcell_spec"
_KEYS = ("planned_thickness_m", "executed_thickness_m", "vertex_areas_m2", "judged",
         "target_m", "tolerance")
#: The surface, so the share inside the window is exact over the judged faces (files written
#: without them: the share is lumped on the vertex areas).
_MESH_KEYS = ("vertices_m", "faces", "judged_faces")


class FilmFileError(PaintcellError):
    """`film.npz` is unreadable or inconsistent."""


@dataclass(frozen=True)
class FilmData:
    """Per-vertex film of one run and its spec window.

    planned_m / executed_m: (N,) film thickness per surface vertex [m]; areas_m2: (N,) vertex
    areas [m²]; judged: (N,) bool, the vertices the uniformity is judged on; target_m: centre of
    the spec window [m] (the paint spec's target: by default the planned area-weighted mean over
    the judged area); tolerance: half-width of the window as a fraction of the target [-];
    vertices_m (N, 3) [m], faces (F, 3), judged_faces (F,) bool: the surface (None in files
    written without it).
    """

    planned_m: np.ndarray
    executed_m: np.ndarray
    areas_m2: np.ndarray
    judged: np.ndarray
    target_m: float
    tolerance: float
    vertices_m: np.ndarray | None = None
    faces: np.ndarray | None = None
    judged_faces: np.ndarray | None = None

    @property
    def window_m(self) -> tuple[float, float]:
        """(low, high) film thickness limits of the spec window [m]."""
        return (self.target_m * (1.0 - self.tolerance), self.target_m * (1.0 + self.tolerance))

    def inside_pct(self, which: str = "executed") -> float:
        """Share of the judged area whose film lies inside the spec window [%].

        which: "executed" or "planned"."""
        return self._shares(which)[1]

    def below_above_pct(self, which: str = "executed") -> tuple[float, float]:
        """Shares of the judged area below and above the spec window [%]."""
        below, _, above = self._shares(which)
        return below, above

    def _shares(self, which: str) -> tuple[float, float, float]:
        """(below, inside, above) the window [%] of the judged area: exact over the judged faces
        when the file has the surface, else lumped on the judged vertices' areas."""
        t = self.executed_m if which == "executed" else self.planned_m
        lo, hi = self.window_m
        if self.faces is not None and self.vertices_m is not None:
            from paintcell.validation.paint_spec import share_in_window

            s = share_in_window(t, self.vertices_m, self.faces, lo, hi, self.judged_faces)
            return 100.0 * s[0], 100.0 * s[1], 100.0 * s[2]
        w = self.areas_m2 * self.judged
        total = float(w.sum())
        below, above = float(w[t < lo].sum()) / total, float(w[t > hi].sum()) / total
        return 100.0 * below, 100.0 * (1.0 - below - above), 100.0 * above


def film_data(surface: Any, report: Any) -> FilmData:
    """`FilmData` of a `Surface` and its `ValidationReport`.

    The window is the report's paint spec window (`spec_target_um` ± `spec_window_pct`; a report
    without them: the planned mean ± `tolerance_fraction`), so the data agree with metrics.json;
    the surface's vertices, faces and judged faces come along (the share over the judged faces).
    """
    m = report.metrics
    judged = surface.judged_vertex_mask()  # None: every vertex is judged
    if "spec_target_um" in m:
        target_um, tol = float(m["spec_target_um"]), 0.01 * float(m["spec_window_pct"])
    else:
        target_um, tol = float(m["planned_mean_um"]), float(m["tolerance_fraction"])
    faces = np.asarray(surface.faces, np.int64)
    regions = getattr(surface, "regions", None)
    return FilmData(np.asarray(report.planned_thickness_m, float).reshape(-1),
                    np.asarray(report.executed_thickness_m, float).reshape(-1),
                    np.asarray(surface.vertex_areas, float).reshape(-1),
                    (np.ones(len(surface.vertices), bool) if judged is None
                     else np.asarray(judged, bool).reshape(-1)),
                    1e-6 * target_um, tol, np.asarray(surface.vertices, float), faces,
                    (np.ones(len(faces), bool) if regions is None
                     else np.asarray(regions.face_mask(), bool)))


def save_film_data(path: str | os.PathLike[str], film: FilmData) -> Path:
    """Write `film` as `film.npz` (atomically; the surface's arrays when `film` has them);
    return the path."""
    arrays = {
        "planned_thickness_m": film.planned_m, "executed_thickness_m": film.executed_m,
        "vertex_areas_m2": film.areas_m2, "judged": film.judged,
        "target_m": np.asarray(film.target_m), "tolerance": np.asarray(film.tolerance),
    }
    if film.faces is not None and film.vertices_m is not None and film.judged_faces is not None:
        arrays.update(vertices_m=np.asarray(film.vertices_m, float),
                      faces=np.asarray(film.faces).astype(np.int32),
                      judged_faces=np.asarray(film.judged_faces, bool))
    atomic_write_npz(Path(path), arrays)
    return Path(path)


def save_film(path: str | os.PathLike[str], surface: Any, report: Any) -> Path:
    """Write `film.npz` (atomically) from a `Surface` and its `ValidationReport` (`film_data`);
    return the path."""
    return save_film_data(path, film_data(surface, report))


def load_film(results_dir: str | os.PathLike[str]) -> FilmData | None:
    """The folder's `film.npz` (None when the folder has none: made before this file existed)."""
    path = Path(results_dir) / FILM_NAME
    if not path.exists():
        return None
    try:
        with np.load(path) as z:
            a = {k: z[k] for k in _KEYS}
            mesh = {k: z[k] for k in _MESH_KEYS if k in z}
    except (OSError, ValueError, KeyError) as e:
        raise FilmFileError(f"{path} is not a paintcell film file ({e}); re-run "
                            "`paintcell validate` on the folder") from e
    film = FilmData(np.asarray(a["planned_thickness_m"], float).reshape(-1),
                    np.asarray(a["executed_thickness_m"], float).reshape(-1),
                    np.asarray(a["vertex_areas_m2"], float).reshape(-1),
                    np.asarray(a["judged"], bool).reshape(-1), float(a["target_m"]),
                    float(a["tolerance"]),
                    *((np.asarray(mesh["vertices_m"], float).reshape(-1, 3),
                       np.asarray(mesh["faces"], np.int64).reshape(-1, 3),
                       np.asarray(mesh["judged_faces"], bool).reshape(-1))
                      if len(mesh) == len(_MESH_KEYS) else ()))
    n = len(film.executed_m)
    mesh_ok = film.faces is None or (
        film.vertices_m is not None and len(film.vertices_m) == n
        and film.judged_faces is not None and len(film.judged_faces) == len(film.faces)
        and (len(film.faces) == 0 or (int(film.faces.min()) >= 0 and int(film.faces.max()) < n))
        and bool(film.judged_faces.any()))
    if not (len(film.planned_m) == len(film.areas_m2) == len(film.judged) == n) or n == 0 \
            or not mesh_ok:
        raise FilmFileError(f"{path}: its arrays have different lengths; re-run "
                            "`paintcell validate` on the folder")
    if not (film.areas_m2 * film.judged).sum() > 0:
        raise FilmFileError(f"{path}: the judged area is zero; re-run `paintcell validate`")
    return film


def histogram_png(film: FilmData, size_px: tuple[int, int] = (480, 330)) -> bytes:
    """PNG of the area-weighted film histogram of the judged area against the spec window.

    Executed film as filled bars, planned film as an outline [µm on x, % of judged area on y];
    the window shaded, with the executed share of area inside it in the title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    j = film.judged
    w = film.areas_m2[j]
    w = 100.0 * w / w.sum()
    ex, pl = 1e6 * film.executed_m[j], 1e6 * film.planned_m[j]
    lo, hi = (1e6 * x for x in film.window_m)
    both = np.r_[ex, pl]
    # the window and the bulk of the film; the far tails clipped into the end bins
    x0 = min(float(np.percentile(both, 0.5)), lo * 0.8)
    x1 = max(float(np.percentile(both, 99.5)), hi * 1.2)
    bins = np.linspace(max(x0, 0.0) if both.min() >= 0 else x0, x1, 41).tolist()
    dpi = 80
    fig, ax = plt.subplots(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
    try:
        ax.axvspan(lo, hi, color="#2e9d4f", alpha=0.15, label=f"spec window {lo:.1f}–{hi:.1f} µm")
        ax.hist(np.clip(ex, bins[0], bins[-1]), bins=bins, weights=w, color="#3b6fb6",
                label="executed")
        ax.hist(np.clip(pl, bins[0], bins[-1]), bins=bins, weights=w, histtype="step",
                color="#222222", linewidth=1.2, label="planned")
        for x in (lo, hi):
            ax.axvline(x, color="#2e9d4f", linewidth=1.2)
        ax.set_xlabel("film thickness [µm]")
        ax.set_ylabel("share of judged area [%]")
        ax.set_title(f"{film.inside_pct():.1f} % of the area inside the spec window "
                     f"(±{100 * film.tolerance:g} %)", fontsize=10)
        ax.legend(fontsize=8, loc="best")
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    return buf.getvalue()


def spec_range_um(target_um: float, tolerance: float) -> tuple[float, float]:
    """Colour range [µm] of the spec map: the window (low, high) is its middle third, so one
    window width below and above it shade from light to dark before clamping."""
    lo, hi = target_um * (1.0 - tolerance), target_um * (1.0 + tolerance)
    return lo - (hi - lo), hi + (hi - lo)


def register_spec_cmap() -> str:
    """Register `SPEC_CMAP` with matplotlib (once) and return its name.

    Thirds of equal length: below the window dark → light blue, inside light → mid green, above
    light → dark red; used with `spec_range_um` the window is exactly the green third."""
    from matplotlib import colormaps
    from matplotlib.colors import LinearSegmentedColormap, ListedColormap

    if SPEC_CMAP not in colormaps:
        n = 86
        thirds = [LinearSegmentedColormap.from_list("b", a, n)(np.linspace(0, 1, n))
                  for a in (("#08306b", "#9ecae1"), ("#c7e9c0", "#238b45"),
                            ("#fcbba1", "#67000d"))]
        colormaps.register(ListedColormap(np.vstack(thirds), name=SPEC_CMAP))
    return SPEC_CMAP


def spec_rgb(thickness_m: npt.ArrayLike, target_um: float, tolerance: float) -> np.ndarray:
    """(N, 3) sRGB colours in [0, 1] of film thickness_m (N,) [m] on the spec map: `SPEC_CMAP`
    over `spec_range_um(target_um, tolerance)`, clamped at both ends (the scale of the report's
    spec render and its colour bar). NaN is drawn as the low end."""
    from matplotlib import colormaps

    lo, hi = spec_range_um(target_um, tolerance)
    t_um = np.nan_to_num(1e6 * np.asarray(thickness_m, float).reshape(-1), nan=lo)
    s = np.clip((t_um - lo) / (hi - lo), 0.0, 1.0)
    return np.asarray(colormaps[register_spec_cmap()](s), float)[:, :3]
