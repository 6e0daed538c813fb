"""What a robustness sweep samples: named disturbances, their distributions, the design.

A factor is a field of `paintcell.execution.execute.Disturbances` given a distribution, written
as the user types
it: ``part_offset_m=normal(0, 0.005)``. Distributions (parameters in the factor's unit):

    normal(mean, sd)            Gaussian
    uniform(low, high)          flat on [low, high]
    triangular(low, mode, high) triangle
    truncnormal(mean, sd, low, high)  Gaussian cut to [low, high]
    a plain number              a constant

Designs: "lhs" (Latin hypercube, scipy.stats.qmc: every factor's marginal stratified into n equal
-probability bins, so quantiles converge faster than Monte Carlo) or "mc" (plain Monte Carlo).
Both draw u ∈ (0, 1)^d from the sweep seed and map it through each distribution's inverse CDF.
Each sample also gets its own integer seed (the random directions of a placement or TCP error)
from `numpy.random.SeedSequence(seed).spawn(n)`: sample i's seed depends on (seed, i) only, never
on which worker runs it or in which order.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.validation.sweep_names import (
    BOOTH_METRICS,
    FACTORS,
    MAGNITUDE_FACTORS,
    METHODS,
    NOT_MODELLED,
    SAMPLE_METRICS,
)

#: a sweep limit key: max_pNN_<figure> or min_pNN_<figure>
LIMIT_RE = re.compile(r"^(max|min)_p(\d{1,2})_(.+)$")


class SweepError(PaintcellError):
    """A sweep specification (factors, distributions, design) or its results folder is invalid."""


_DIST_RE = re.compile(r"^\s*([a-z]+)\s*\(([^()]*)\)\s*$")
_ARITY = {"normal": 2, "uniform": 2, "triangular": 3, "truncnormal": 4}


@dataclass(frozen=True)
class Distribution:
    """One factor's distribution: kind (normal, uniform, triangular, truncnormal, const) and its
    parameters in the factor's unit."""

    kind: str
    params: tuple[float, ...]

    @classmethod
    def parse(cls, text: str | float | int, name: str = "factor") -> Distribution:
        """From ``normal(0, 0.005)`` or a number; a one-line SweepError names the fix."""
        if isinstance(text, bool):
            raise SweepError(f"{name}: {text!r} is not a distribution; write e.g. normal(0, 0.01)")
        if isinstance(text, int | float):
            if not math.isfinite(text):
                raise SweepError(f"{name}: {text!r} must be finite")
            return cls("const", (float(text),))
        m = _DIST_RE.match(str(text))
        if m is None:
            try:
                return cls.parse(float(str(text)), name)
            except ValueError:
                pass
            raise SweepError(f"{name}={text!r} is not a distribution; write normal(mean, sd), "
                             "uniform(low, high), triangular(low, mode, high), "
                             "truncnormal(mean, sd, low, high) or a number")
        kind, args = m.group(1), [a for a in m.group(2).split(",") if a.strip()]
        if kind not in _ARITY:
            raise SweepError(f"{name}: unknown distribution {kind!r}; use one of "
                             f"{', '.join(_ARITY)}")
        try:
            p = tuple(float(a) for a in args)
        except ValueError:
            raise SweepError(f"{name}={text!r}: parameters must be numbers") from None
        if len(p) != _ARITY[kind] or not all(map(math.isfinite, p)):
            raise SweepError(f"{name}: {kind} takes {_ARITY[kind]} finite numbers, got {text!r}")
        bad = ((kind in ("normal", "truncnormal") and p[1] <= 0)
               or (kind == "uniform" and not p[0] < p[1])
               or (kind == "triangular" and not (p[0] <= p[1] <= p[2] and p[0] < p[2]))
               or (kind == "truncnormal" and not p[2] < p[3]))
        if bad:
            raise SweepError(f"{name}={text!r}: need sd > 0, low < high, low <= mode <= high")
        return cls(kind, p)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        """Inverse CDF at u (n,) in (0, 1)."""
        from scipy import stats  # imported here: `paintcell --help` must stay light

        p = self.params
        if self.kind == "const":
            return np.full(len(u), p[0])
        if self.kind == "normal":
            return np.asarray(stats.norm.ppf(u, loc=p[0], scale=p[1]))
        if self.kind == "uniform":
            return p[0] + u * (p[1] - p[0])
        if self.kind == "triangular":
            c = (p[1] - p[0]) / (p[2] - p[0])
            return np.asarray(stats.triang.ppf(u, c, loc=p[0], scale=p[2] - p[0]))
        a, b = (p[2] - p[0]) / p[1], (p[3] - p[0]) / p[1]
        return np.asarray(stats.truncnorm.ppf(u, a, b, loc=p[0], scale=p[1]))

    def __str__(self) -> str:
        if self.kind == "const":
            return f"{self.params[0]:g}"
        return f"{self.kind}({', '.join(f'{v:g}' for v in self.params)})"


@dataclass(frozen=True)
class SweepSpec:
    """A sweep: factors (name → distribution), samples n, design method, seed."""

    factors: dict[str, Distribution]
    samples: int
    method: str = "lhs"
    seed: int = 0
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        if not self.factors:
            raise SweepError("a sweep needs at least one factor; give --vary NAME=DIST, e.g. "
                             "--vary part_offset_m=normal(0,0.005)")
        for name in self.factors:
            if name in NOT_MODELLED:
                raise SweepError(f"factor {name} is not modelled: {NOT_MODELLED[name]}")
            if name not in FACTORS:
                raise SweepError(f"unknown factor {name!r}; valid: {', '.join(FACTORS)}")
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) \
                or self.samples < 1:
            raise SweepError(f"samples = {self.samples!r} must be an int >= 1 (--samples N)")
        _check_budget(self.samples, "samples (--samples)")
        if self.method not in METHODS:
            raise SweepError(f"method {self.method!r} must be one of {', '.join(METHODS)}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SweepError(f"seed = {self.seed!r} must be an int >= 0 (--seed N)")
        object.__setattr__(self, "names", tuple(sorted(self.factors)))

    @classmethod
    def from_strings(cls, items: dict[str, Any] | list[str], samples: int, method: str = "lhs",
                     seed: int = 0) -> SweepSpec:
        """From {"part_offset_m": "normal(0, 0.005)"} or ["part_offset_m=normal(0, 0.005)"]."""
        pairs: dict[str, Any] = {}
        if isinstance(items, dict):
            pairs = dict(items)
        else:
            for it in items:
                key, sep, val = it.partition("=")
                if not sep or not key.strip():
                    raise SweepError(f"--vary {it!r} is not NAME=DIST (e.g. "
                                     "part_offset_m=normal(0,0.005))")
                pairs[key.strip()] = val
        return cls({k: Distribution.parse(v, k) for k, v in pairs.items()}, samples, method, seed)

    def design(self) -> np.ndarray:
        """(samples, d) factor values, columns in `names` order (deterministic in the seed)."""
        from scipy.stats import qmc

        d = len(self.names)
        ss = np.random.SeedSequence(self.seed)
        design_seed = np.random.default_rng(ss.spawn(2)[0])
        if self.method == "lhs":
            u = qmc.LatinHypercube(d=d, rng=design_seed).random(self.samples)
        else:
            u = design_seed.random((self.samples, d))
        u = np.clip(u, 1e-12, 1 - 1e-12)
        cols = [self.factors[n].ppf(u[:, j]) for j, n in enumerate(self.names)]
        x = np.column_stack(cols) if cols else np.zeros((self.samples, 0))
        for j, n in enumerate(self.names):
            if n in MAGNITUDE_FACTORS:
                x[:, j] = np.abs(x[:, j])
        return x

    def sample_seeds(self) -> np.ndarray:
        """(samples,) per-sample integer seeds from SeedSequence(seed).spawn: sample i's seed
        depends on (seed, i) only."""
        children = np.random.SeedSequence(self.seed).spawn(2)[1].spawn(self.samples)
        return np.array([int(c.generate_state(1, np.uint32)[0]) for c in children], np.int64)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description (factors as the strings the user wrote, normalized)."""
        return {"factors": {n: str(self.factors[n]) for n in self.names},
                "units": {n: FACTORS[n][0] for n in self.names},
                "samples": self.samples, "method": self.method, "seed": self.seed}

    def digest(self, scenario: dict[str, Any]) -> str:
        """Identity of (this spec, the scenario run): a results folder resumes only the same."""
        blob = json.dumps({"spec": self.to_dict(), "scenario": scenario}, sort_keys=True,
                          default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


#: keys of a scenario's sweep table and their defaults (fast_samples None: `samples`; workers:
#: local Dask processes, 0 runs the samples in this process).
SCENARIO_DEFAULTS: dict[str, Any] = {"factors": {}, "samples": 100, "fast_samples": None,
                                     "method": "lhs", "seed": 0, "limits": {}, "workers": 2}
#: keys of a scenario's sweep table.
SCENARIO_KEYS = tuple(SCENARIO_DEFAULTS)


def spec_from_scenario(sweep: dict[str, Any], *, fast: bool = False,
                       vary: list[str] | None = None, samples: int | None = None,
                       method: str | None = None, seed: int | None = None) -> SweepSpec:
    """The sweep of a scenario's `sweep` table, with command-line overrides (--vary adds or
    replaces factors; --samples, --method, --seed replace). `fast`: `fast_samples` if given."""
    unknown = sorted(set(sweep) - set(SCENARIO_KEYS))
    if unknown:
        raise SweepError(f"unknown sweep setting(s) {unknown}; valid: {list(SCENARIO_KEYS)}")
    factors = sweep.get("factors", {})
    if not isinstance(factors, dict):
        raise SweepError("sweep factors must be a table of NAME = \"DIST\" entries")
    factors = dict(factors)
    if vary:
        factors.update(SweepSpec.from_strings(vary, 1).factors)
    d = {**SCENARIO_DEFAULTS, **{k: v for k, v in sweep.items() if v is not None}}
    n = samples if samples is not None else (
        d["fast_samples"] if fast and d["fast_samples"] is not None else d["samples"])
    return SweepSpec({k: v if isinstance(v, Distribution) else Distribution.parse(v, k)
                      for k, v in factors.items()}, n,
                     method if method is not None else d["method"],
                     seed if seed is not None else d["seed"])


def check_sweep_table(sweep: dict[str, Any]) -> None:
    """Validate a scenario's sweep table on load (one-line SweepError): known keys, factors and
    distributions, positive sample counts, a known method, a non-negative seed and workers, and
    well-formed limits. A table without factors is valid (factors may come from --vary)."""
    if not isinstance(sweep, dict):
        raise SweepError("sweep must be a table [sweep]")
    unknown = sorted(set(sweep) - set(SCENARIO_KEYS))
    if unknown:
        raise SweepError(f"unknown sweep setting(s) {unknown}; valid: {list(SCENARIO_KEYS)}")
    for key in ("samples", "fast_samples", "seed", "workers"):
        v = sweep.get(key, 1)
        low = 1 if "samples" in key else 0
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise SweepError(f"sweep {key} = {v!r} must be an int >= {low}")
        if "samples" in key:
            _check_budget(v, f"sweep {key}")
        if key == "workers" and v > MAX_WORKERS:
            raise SweepError(f"sweep workers = {v} is more than {MAX_WORKERS} local processes; "
                             "use a Dask cluster (--scheduler) for more")
    if sweep.get("factors"):
        spec_from_scenario({k: v for k, v in sweep.items() if k not in ("limits", "workers")})
    elif "factors" in sweep and not isinstance(sweep["factors"], dict):
        raise SweepError("sweep factors must be a table [sweep.factors] of NAME = \"DIST\"")
    if sweep.get("method", "lhs") not in METHODS:
        raise SweepError(f"sweep method {sweep['method']!r} must be one of {', '.join(METHODS)}")
    limits = sweep.get("limits", {})
    if not isinstance(limits, dict):
        raise SweepError("sweep limits must be a table [sweep.limits]")
    check_limits(limits)


#: Most local worker processes a sweep starts (each holds a robot model and a MuJoCo cell).
MAX_WORKERS = 256


def _check_budget(samples: int, setting: str) -> None:
    """A sample count the sweep's memory budget holds (`paintcell.core.budget`), as SweepError."""
    from paintcell.core.budget import check_sweep_budget
    from paintcell.core.memory import BudgetError

    try:
        check_sweep_budget(samples, setting)
    except BudgetError as exc:
        raise SweepError(str(exc)) from None


def check_limits(limits: dict[str, Any] | None) -> dict[str, float]:
    """Validated limits (one-line SweepError naming the bad key and the valid forms)."""
    out: dict[str, float] = {}
    for key, val in (limits or {}).items():
        if isinstance(val, bool) or not isinstance(val, int | float) or not math.isfinite(val):
            raise SweepError(f"sweep limit {key} = {val!r} must be a finite number")
        m = LIMIT_RE.match(key)
        if key in ("min_yield_pct", "min_yield_lower_pct"):
            pass
        elif m is None or m.group(3) not in {**SAMPLE_METRICS, **BOOTH_METRICS}:
            raise SweepError(f"unknown sweep limit {key!r}; use max_pNN_<figure>, "
                             f"min_pNN_<figure> (figures: {', '.join(SAMPLE_METRICS)}; a "
                             f"booth's also {', '.join(BOOTH_METRICS)}), "
                             "min_yield_pct or min_yield_lower_pct")
        out[key] = float(val)
    return out
