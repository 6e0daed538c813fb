"""The paint spec a part's executed film is judged against: a scenario's `[spec]` table.

```toml
[spec]
target_film_um = 30.0   # centre of the window [µm] (default: the plan's own target film)
window_pct = 20.0       # the window: target ± 20 %
min_inside_pct = 90.0   # at least 90 % of the judged area inside the window
max_nsd_pct = 10.0      # executed σ/μ at most 10 %
```

A scenario without the table is judged against these defaults: a run that writes nothing still
meets a paint spec. The share inside the window is area-weighted over the judged region, exactly
for the film as the surface carries it (linear over each triangle, `share_in_window`), so a film
that is a linear ramp gives the closed-form share. `[thresholds] max_executed_nsd_pct` can only
tighten the spec's σ/μ: the check holds the smaller of the two (`nsd_limit`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PaintcellError
from paintcell.validation.validate_report import Check

__all__ = ["PaintSpec", "SPEC_RANGES", "SpecError", "nsd_limit", "share_in_window", "spec_checks",
           "spec_metrics"]


class SpecError(PaintcellError):
    """A `[spec]` table holds an unknown key or a value out of range."""


#: (low, high, what) of each `[spec]` key; low and high exclusive (`min_inside_pct` may be
#: 100: every point in the window).
SPEC_RANGES: dict[str, tuple[float, float, str]] = {
    "target_film_um": (0.0, 1000.0, "a film thickness [µm]"),
    "window_pct": (0.0, 100.0, "a half-width in % of the target"),
    "min_inside_pct": (0.0, 100.0, "a share of the judged area [%]"),
    "max_nsd_pct": (0.0, 100.0, "σ/μ [%]"),
}


@dataclass(frozen=True)
class PaintSpec:
    """A paint shop's film spec.

    target_film_um: centre of the window [µm]; None: the plan's own target film (a one-robot
        run: the planned area-weighted mean film of the judged area; a booth: the booth's
        `film_target_um`, else the whole body's planned mean film over the judged area).
    window_pct: half-width of the window [% of the target] (inclusive at both ends).
    min_inside_pct: least share of the judged area whose executed film lies in the window [%]
        (`min_inside_pct = 100` is allowed: every point in the window).
    max_nsd_pct: largest executed film σ/μ over the judged area [%].
    """

    target_film_um: float | None = None
    window_pct: float = 20.0
    min_inside_pct: float = 90.0
    max_nsd_pct: float = 10.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None and f.name == "target_film_um":
                continue
            lo, hi, what = SPEC_RANGES[f.name]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise SpecError(f"{f.name} = {v!r} must be a number ({what})")
            top_ok = f.name == "min_inside_pct" and v == hi
            if not (lo < v < hi or top_ok):
                raise SpecError(f"{f.name} = {v!r} is out of range; valid: {lo:g} < {f.name} "
                                f"{'≤' if f.name == 'min_inside_pct' else '<'} {hi:g} ({what})")

    @classmethod
    def from_table(cls, table: Any, where: str) -> PaintSpec:
        """The spec of a `[spec]` table; `where` (the file) is named in every error."""
        if table is None:
            return cls()
        if not isinstance(table, dict):
            raise SpecError(f"{where}: spec must be a table [spec]")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(table) - set(names))
        if unknown:
            raise SpecError(f"{where}: unknown [spec] key(s) {unknown}; valid: {', '.join(names)}")
        try:
            return cls(**table)
        except SpecError as exc:
            raise SpecError(f"{where} [spec]: {exc}") from exc

    def target_m(self, planned_target_m: float) -> float:
        """The window's centre [m]: `target_film_um`, else the plan's own `planned_target_m`."""
        return planned_target_m if self.target_film_um is None else 1e-6 * self.target_film_um

    def window_m(self, target_m: float) -> tuple[float, float]:
        """(low, high) film limits [m] of the window around `target_m` [m]."""
        h = 0.01 * self.window_pct
        return target_m * (1.0 - h), target_m * (1.0 + h)

    def to_dict(self) -> dict[str, Any]:
        """The `[spec]` table (None target left out: TOML has no null)."""
        return {k: v for k, v in asdict(self).items() if v is not None}


def share_in_window(film_m: npt.ArrayLike, vertices_m: npt.ArrayLike, faces: npt.ArrayLike,
                    lo_m: float, hi_m: float, face_mask: npt.ArrayLike | None = None
                    ) -> tuple[float, float, float]:
    """(below, inside, above): shares [0, 1] of the area of the faces in `face_mask` (default
    all) whose film lies below `lo_m`, in [lo_m, hi_m], above `hi_m`.

    film_m: (N,) film per vertex [m], linear over each triangle (as the surface carries it);
    vertices_m (N, 3) [m]; faces (F, 3). Exact for that film: over a triangle whose corner
    values sort to a ≤ b ≤ c, the area share with film ≤ x is (x−a)²/((b−a)(c−a)) up to b and
    1 − (c−x)²/((c−a)(c−b)) above it.
    """
    t = np.asarray(film_m, float).reshape(-1)
    v = np.asarray(vertices_m, float).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if face_mask is not None:
        f = f[np.asarray(face_mask, bool).reshape(-1)]
    if len(t) != len(v):
        raise SpecError(f"film has {len(t)} values, the surface {len(v)} vertices")
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1)
    total = float(area.sum())
    if not total > 0:
        raise SpecError("the judged region has no area; judge a region the part has")
    abc = np.sort(t[f], axis=1)
    below = float(area @ _cdf(abc, lo_m, strict=True)) / total
    up_to_hi = float(area @ _cdf(abc, hi_m, strict=False)) / total
    return below, up_to_hi - below, 1.0 - up_to_hi


def _cdf(abc: np.ndarray, x: float, strict: bool) -> np.ndarray:
    """(F,) area share of each triangle whose linear film is ≤ x (strict: < x); corner values
    sorted a ≤ b ≤ c per row. A triangle of one value (a == c) is all on one side of x."""
    a, b, c = abc[:, 0], abc[:, 1], abc[:, 2]
    flat = c - a <= 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = np.where(b > a, (x - a) ** 2 / ((b - a) * (c - a)), 0.0)
        upper = np.where(c > b, 1.0 - (c - x) ** 2 / ((c - a) * (c - b)), 1.0)
    out = np.where(x <= a, 0.0, np.where(x >= c, 1.0, np.where(x <= b, lower, upper)))
    at = (a < x) if strict else (a <= x)
    out = np.where(flat, at.astype(float), out)
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0)


def nsd_limit(spec: PaintSpec, max_executed_nsd_pct: float | None) -> tuple[float, str]:
    """(σ/μ limit [%], where it comes from): the spec's `max_nsd_pct`, or `[thresholds]
    max_executed_nsd_pct` where that is tighter (a threshold never loosens the spec)."""
    th = math.inf if max_executed_nsd_pct is None else float(max_executed_nsd_pct)
    if th < spec.max_nsd_pct:
        return th, "[thresholds] max_executed_nsd_pct"
    return spec.max_nsd_pct, "[spec] max_nsd_pct"


def spec_checks(m: dict[str, Any], spec: PaintSpec, max_executed_nsd_pct: float | None,
                nsd_key: str = "executed_nsd_pct", inside_key: str = "executed_inside_spec_pct",
                what: str = "") -> list[Check]:
    """The spec's two checks on metrics `m`: "executed σ/μ" + `what` (`m[nsd_key]` against
    `nsd_limit`) and "film in spec window" + `what` (`m[inside_key]` against `min_inside_pct`).
    A failed one says by how much it missed (the window's detail reads `spec_*_um` and the
    `*_below_spec_pct` / `*_above_spec_pct` of the same stem as `inside_key`)."""
    out = []
    limit, source = nsd_limit(spec, max_executed_nsd_pct)
    v = float(m[nsd_key])
    ok = math.isfinite(v) and v <= limit
    out.append(Check(name=f"executed σ/μ{what}", value=v, limit=limit, unit="%", passed=ok,
                     kind="max", detail="" if ok else
                     f"{v - limit:.2f} points over {source} = {limit:g} %"))
    inside = float(m[inside_key])
    stem = inside_key.removesuffix("_inside_spec_pct")
    ok = math.isfinite(inside) and inside >= spec.min_inside_pct
    detail = ""
    if not ok:
        detail = (f"{spec.min_inside_pct - inside:.1f} points short: {inside:.1f} % of the judged "
                  f"area in {m['spec_low_um']:.1f}–{m['spec_high_um']:.1f} µm (target "
                  f"{m['spec_target_um']:.1f} µm ± {spec.window_pct:g} %), "
                  f"{m[f'{stem}_below_spec_pct']:.1f} % below, "
                  f"{m[f'{stem}_above_spec_pct']:.1f} % above")
    out.append(Check(name=f"film in spec window{what}", value=inside,
                     limit=spec.min_inside_pct, unit="%", passed=ok, kind="min", detail=detail))
    return out


def spec_metrics(film_m: np.ndarray, vertices_m: np.ndarray, faces: np.ndarray,
                 face_mask: np.ndarray | None, target_m: float, spec: PaintSpec,
                 stem: str = "executed") -> dict[str, float]:
    """Metrics of `film_m` against the spec window around `target_m` [m]: `spec_target_um`,
    `spec_low_um`, `spec_high_um`, `{stem}_inside_spec_pct`, `{stem}_below_spec_pct`,
    `{stem}_above_spec_pct` (shares of the judged area, `share_in_window`)."""
    lo, hi = spec.window_m(target_m)
    below, inside, above = share_in_window(film_m, vertices_m, faces, lo, hi, face_mask)
    return {"spec_target_um": 1e6 * target_m, "spec_low_um": 1e6 * lo, "spec_high_um": 1e6 * hi,
            f"{stem}_inside_spec_pct": 100.0 * inside, f"{stem}_below_spec_pct": 100.0 * below,
            f"{stem}_above_spec_pct": 100.0 * above}
