"""The film of a run as data (`film.npz`) and the spec-window numbers the report leads with.

`paintcell run` (and `paintcell validate`) write `film.npz` into the results folder: the film per
surface vertex, planned and executed [m], the vertex areas [m²], which vertices are judged (a real
part's skin; every vertex of a library part) and the spec window: ±`tolerance` around the planned
area-weighted mean film of the judged area (`paintcell.validation.validate`'s window, the one
behind `executed_within_tolerance_pct`). The report reads it to draw the thickness histogram against
the window and to state the share of area inside it; anyone can recompute that share from the
arrays alone.
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


class FilmFileError(PaintcellError):
    """`film.npz` is unreadable or inconsistent."""


@dataclass(frozen=True)
class FilmData:
    """Per-vertex film of one run and its spec window.

    planned_m / executed_m: (N,) film thickness per surface vertex [m]; areas_m2: (N,) vertex
    areas [m²]; judged: (N,) bool, the vertices the uniformity is judged on; target_m: centre of
    the spec window [m] (planned area-weighted mean over the judged area); tolerance: half-width
    of the window as a fraction of the target [-].
    """

    planned_m: np.ndarray
    executed_m: np.ndarray
    areas_m2: np.ndarray
    judged: np.ndarray
    target_m: float
    tolerance: float

    @property
    def window_m(self) -> tuple[float, float]:
        """(low, high) film thickness limits of the spec window [m]."""
        return (self.target_m * (1.0 - self.tolerance), self.target_m * (1.0 + self.tolerance))

    def inside_pct(self, which: str = "executed") -> float:
        """Share of the judged area whose film lies inside the spec window [%].

        which: "executed" or "planned"."""
        t = self.executed_m if which == "executed" else self.planned_m
        w = self.areas_m2 * self.judged
        lo, hi = self.window_m
        inside = (t >= lo) & (t <= hi)
        return 100.0 * float(w[inside].sum() / w.sum())

    def below_above_pct(self, which: str = "executed") -> tuple[float, float]:
        """Shares of the judged area below and above the spec window [%]."""
        t = self.executed_m if which == "executed" else self.planned_m
        w = self.areas_m2 * self.judged
        lo, hi = self.window_m
        return (100.0 * float(w[t < lo].sum() / w.sum()),
                100.0 * float(w[t > hi].sum() / w.sum()))


def film_data(surface: Any, report: Any) -> FilmData:
    """`FilmData` of a `Surface` and its `ValidationReport`.

    The window's centre is the report's planned mean film (`planned_mean_um`) and its half-width
    the report's `tolerance_fraction`, so the data agree with metrics.json.
    """
    m = report.metrics
    judged = surface.judged_vertex_mask()  # None: every vertex is judged
    return FilmData(np.asarray(report.planned_thickness_m, float).reshape(-1),
                    np.asarray(report.executed_thickness_m, float).reshape(-1),
                    np.asarray(surface.vertex_areas, float).reshape(-1),
                    (np.ones(len(surface.vertices), bool) if judged is None
                     else np.asarray(judged, bool).reshape(-1)),
                    1e-6 * float(m["planned_mean_um"]), float(m["tolerance_fraction"]))


def save_film_data(path: str | os.PathLike[str], film: FilmData) -> Path:
    """Write `film` as `film.npz` (atomically); return the path."""
    arrays = {
        "planned_thickness_m": film.planned_m, "executed_thickness_m": film.executed_m,
        "vertex_areas_m2": film.areas_m2, "judged": film.judged,
        "target_m": np.asarray(film.target_m), "tolerance": np.asarray(film.tolerance),
    }
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
    except (OSError, ValueError, KeyError) as e:
        raise FilmFileError(f"{path} is not a paintcell film file ({e}); re-run "
                            "`paintcell validate` on the folder") from e
    film = FilmData(np.asarray(a["planned_thickness_m"], float).reshape(-1),
                    np.asarray(a["executed_thickness_m"], float).reshape(-1),
                    np.asarray(a["vertex_areas_m2"], float).reshape(-1),
                    np.asarray(a["judged"], bool).reshape(-1), float(a["target_m"]),
                    float(a["tolerance"]))
    n = len(film.executed_m)
    if not (len(film.planned_m) == len(film.areas_m2) == len(film.judged) == n) or n == 0:
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
