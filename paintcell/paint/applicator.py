"""The electrostatic rotating bell (ESRB) deposition model: one bivariate + two revolved Gaussians.

Paper §2.2 (after Conner et al. 2002) and `shared/DESIGN.md`. The model is the film-thickness rate
on a flat reference plane perpendicular to the spray axis at standoff `h`, in tool-frame plane
coordinates (x along travel, y = z × x):

    f(x, y) = A0 · exp(-(x²/(2σx²) + y²/(2σy²))) + Σ_k Ak · exp(-(r - μk)² / (2σk²)),
    r = √(x² + y²)

`paintcell.paint.deposition` projects it onto curved surfaces.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import tomli_w

from paintcell.core.atomic_io import atomic_write_text
from paintcell.core.data_text import DataTextError, read_toml
from paintcell.core.errors import ApplicatorError

#: f < FOOTPRINT_REL · peak outside `footprint_radius_m` (the culling radius of the kernel). For an
#: isotropic Gaussian the paint mass outside that radius is exactly this fraction.
FOOTPRINT_REL = 1e-4

_SCALARS = ("standoff_m", "a0_m_s", "sigma_x_m", "sigma_y_m")
_RINGS = ("ring_amplitudes_m_s", "ring_radii_m", "ring_sigmas_m")


@dataclass(frozen=True, eq=False)
class Applicator:
    """ESRB bell deposition model (film-thickness rate on the reference plane).

    standoff_m: h, distance from the spray point to the reference plane along the spray axis [m].
    a0_m_s: A0, peak film-thickness rate of the central bivariate Gaussian [m/s].
    sigma_x_m: σx of the central Gaussian along the travel direction [m].
    sigma_y_m: σy of the central Gaussian across the travel direction [m].
    ring_amplitudes_m_s: (K,) Ak, peak rate of each revolved Gaussian (ring) [m/s] (K = 2).
    ring_radii_m: (K,) μk, ring radius [m].
    ring_sigmas_m: (K,) σk, ring width [m].
    name: a label for reports.
    """

    standoff_m: float
    a0_m_s: float
    sigma_x_m: float
    sigma_y_m: float
    ring_amplitudes_m_s: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ring_radii_m: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.2]))
    ring_sigmas_m: np.ndarray = field(default_factory=lambda: np.array([0.02, 0.02]))
    name: str = "custom"

    def __post_init__(self) -> None:
        valid = ("valid: standoff_m > 0, sigma_x_m > 0, sigma_y_m > 0, a0_m_s >= 0, ring arrays of "
                 "equal length with amplitudes >= 0, radii >= 0, sigmas > 0, all finite, and at "
                 "least one positive amplitude")
        for name in _SCALARS:
            try:
                v = float(getattr(self, name))
            except (TypeError, ValueError) as e:
                raise ApplicatorError(f"{name} must be a number; {valid}") from e
            if not math.isfinite(v):
                raise ApplicatorError(f"{name} = {v} is not finite; {valid}")
            object.__setattr__(self, name, v)
        rings = []
        for name in _RINGS:
            try:
                arr = np.array(getattr(self, name), dtype=float).reshape(-1)
            except (TypeError, ValueError) as e:
                raise ApplicatorError(f"{name} must be a sequence of numbers; {valid}") from e
            if not np.all(np.isfinite(arr)):
                raise ApplicatorError(f"{name} = {arr.tolist()} is not finite; {valid}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
            rings.append(arr)
        if not (len(rings[0]) == len(rings[1]) == len(rings[2])):
            raise ApplicatorError(
                f"ring arrays have lengths {[len(r) for r in rings]}; {valid}")
        if not isinstance(self.name, str):
            raise ApplicatorError(f"name must be a string, got {type(self.name).__name__}")
        checks = [
            (self.standoff_m > 0, f"standoff_m = {self.standoff_m} must be > 0"),
            (self.sigma_x_m > 0, f"sigma_x_m = {self.sigma_x_m} must be > 0"),
            (self.sigma_y_m > 0, f"sigma_y_m = {self.sigma_y_m} must be > 0"),
            (self.a0_m_s >= 0, f"a0_m_s = {self.a0_m_s} must be >= 0"),
            (bool(np.all(rings[0] >= 0)),
             f"ring_amplitudes_m_s = {rings[0].tolist()} must be >= 0"),
            (bool(np.all(rings[1] >= 0)), f"ring_radii_m = {rings[1].tolist()} must be >= 0"),
            (bool(np.all(rings[2] > 0)), f"ring_sigmas_m = {rings[2].tolist()} must be > 0"),
            (self.a0_m_s > 0 or bool(np.any(rings[0] > 0)), "all amplitudes are zero"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ApplicatorError(f"{msg}; {valid}")

    # --- the model ----------------------------------------------------------------------------
    def scaled(self, factor: float) -> Applicator:
        """This bell with its flow (every film-thickness rate [m/s]) multiplied by `factor`
        (> 0): the same spray pattern, `factor` × the film at the same motion."""
        return replace(self, a0_m_s=self.a0_m_s * factor,
                       ring_amplitudes_m_s=np.asarray(self.ring_amplitudes_m_s) * factor,
                       name=f"{self.name} ×{factor:.3f} flow")

    def flux(self, x: npt.ArrayLike, y: npt.ArrayLike) -> np.ndarray:
        """Film-thickness rate f(x, y) on the reference plane [m/s] (broadcasting).

        x: tool-frame coordinate along travel [m]; y: across travel [m].
        """
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        # exponents clamped at -700: numpy's exp is 10-20x slower where it underflows, and
        # e^-700 ≈ 1e-304 is zero for any film
        out = self.a0_m_s * np.exp(np.maximum(-(x * x / (2 * self.sigma_x_m**2)
                                                + y * y / (2 * self.sigma_y_m**2)), -700.0))
        r = np.hypot(x, y)
        for a, mu, s in zip(self.ring_amplitudes_m_s, self.ring_radii_m, self.ring_sigmas_m,
                            strict=True):
            if a > 0:
                out = out + a * np.exp(np.maximum(-((r - mu) ** 2) / (2 * s * s), -700.0))
        return out

    def radial_envelope(self, r: npt.ArrayLike) -> np.ndarray:
        """Upper bound of f at radius r [m] over all directions [m/s] (equal to f on the axis of
        the wider central σ)."""
        r = np.asarray(r, float)
        if self.sigma_y_m >= self.sigma_x_m:
            return self.flux(np.zeros_like(r), r)
        return self.flux(r, np.zeros_like(r))

    @cached_property
    def emitted_flow_m3_s(self) -> float:
        """Closed-form ∫∫ f dx dy over the reference plane: film volume per second [m³/s].

        Central Gaussian: 2π A0 σx σy. Revolved Gaussian: 2π A ∫₀^∞ r e^{-(r-μ)²/2σ²} dr
        = 2π A [σ² e^{-μ²/2σ²} + μ σ √(π/2) (1 + erf(μ / (σ√2)))].
        """
        q = 2 * math.pi * self.a0_m_s * self.sigma_x_m * self.sigma_y_m
        for a, mu, s in zip(self.ring_amplitudes_m_s, self.ring_radii_m, self.ring_sigmas_m,
                            strict=True):
            a, mu, s = float(a), float(mu), float(s)
            q += 2 * math.pi * a * (s * s * math.exp(-mu * mu / (2 * s * s))
                                    + mu * s * math.sqrt(math.pi / 2)
                                    * (1 + math.erf(mu / (s * math.sqrt(2)))))
        return q

    @cached_property
    def peak_rate_m_s(self) -> float:
        """max f over the plane [m/s] (reached on the axis of the wider central σ)."""
        r = np.linspace(0.0, self._r_search_m, 20001)
        return float(self.radial_envelope(r).max())

    @cached_property
    def footprint_radius_m(self) -> float:
        """Radius beyond which f < 1e-4 · peak in every direction [m] (the culling radius)."""
        thr = FOOTPRINT_REL * self.peak_rate_m_s
        r = np.linspace(0.0, self._r_search_m, 20001)
        env = self.radial_envelope(r)
        above = np.flatnonzero(env >= thr)
        if len(above) == 0:
            return 0.0
        i = int(above[-1])
        if i + 1 >= len(r):
            return float(r[-1])
        lo, hi = float(r[i]), float(r[i + 1])
        for _ in range(60):  # bisection on the last crossing (env decreasing there)
            mid = 0.5 * (lo + hi)
            if float(self.radial_envelope(mid)) >= thr:
                lo = mid
            else:
                hi = mid
        return hi

    @property
    def _r_search_m(self) -> float:
        s = max(self.sigma_x_m, self.sigma_y_m)
        far = [12.0 * s] + [float(m + 12.0 * sg) for m, sg in zip(self.ring_radii_m,
                                                                   self.ring_sigmas_m,
                                                                   strict=True)]
        return max(far)

    # --- (de)serialization --------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON/TOML-safe dict of plain floats and lists (exact round trip via `from_dict`)."""
        d: dict[str, Any] = {"name": self.name}
        for name in _SCALARS:
            d[name] = float(getattr(self, name))
        for name in _RINGS:
            d[name] = [float(v) for v in getattr(self, name)]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Applicator:
        """Inverse of `to_dict`; unknown or missing keys raise `ApplicatorError`."""
        known = set(_SCALARS) | set(_RINGS) | {"name"}
        extra = set(d) - known
        if extra:
            raise ApplicatorError(f"unknown applicator keys {sorted(extra)}; valid keys: "
                                  f"{sorted(known)}")
        missing = (set(_SCALARS) | set(_RINGS)) - set(d)
        if missing:
            raise ApplicatorError(f"missing applicator keys {sorted(missing)}; give all of "
                                  f"{sorted(known - {'name'})}")
        return cls(**{k: d[k] for k in d})

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> Applicator:
        """Load from a TOML file with the keys of `to_dict` (see
        `paintcell/paint/data/default_bell.toml`).
        """
        path = Path(path)
        if not path.exists():
            raise ApplicatorError(f"applicator file {path} does not exist; give a TOML path")
        try:
            d = read_toml(path)
        except DataTextError as e:
            raise ApplicatorError(f"applicator {e}") from e
        return cls.from_dict(d)

    def to_toml(self, path: str | os.PathLike[str]) -> None:
        """Write the parameters as TOML (atomically)."""
        atomic_write_text(path, tomli_w.dumps(self.to_dict()))

    @classmethod
    def default(cls) -> Applicator:
        """The shipped default bell (`paintcell/paint/data/default_bell.toml`): defaults to
        calibrate."""
        data = resources.files("paintcell.paint").joinpath("data/default_bell.toml")
        text = data.read_text()
        return cls.from_dict(tomllib.loads(text))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Applicator) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(repr(sorted(self.to_dict().items())))
