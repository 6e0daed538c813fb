"""The film refinement's bounded fit (`paintcell.coverage.film_refine.bounded_minimum`): the
minimiser of a strictly convex quadratic in a box, checked against scipy's bounded-variable
least squares (another algorithm on the same problem written as least squares) and against the
optimality conditions re-measured on the answer."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from paintcell.coverage import film_refine
from paintcell.coverage.film_refine import bounded_minimum


def _problem(seed: int, k: int = 80, held: float = 0.0) -> tuple[np.ndarray, ...]:
    """A least-squares problem ‖A s − b‖² with a pull toward 1 (as the fit's), as (A, b, H, g,
    lo, hi): H = AᵀA, g = Aᵀb, bounds that cut the free minimiser in several places; held > 0
    adds a few heavy rows (the fit's held pass durations), which raise H's condition to ~1e5."""
    rng = np.random.default_rng(seed)
    A = np.vstack([rng.normal(size=(3 * k, k)), 0.1 * np.eye(k)])
    b = np.concatenate([rng.normal(size=3 * k) + A[:3 * k].sum(axis=1), 0.1 * np.ones(k)])
    if held:
        rows = np.sqrt(held) * rng.uniform(0.0, 1.0, size=(4, k))
        A, b = np.vstack([A, rows]), np.concatenate([b, rows.sum(axis=1)])
    free = np.linalg.lstsq(A, b, rcond=None)[0]
    lo = np.where(np.arange(k) % 5 == 0, free + 0.3, free - 1.0)   # every fifth held at lo
    hi = np.where(np.arange(k) % 7 == 3, free - 0.3, free + 1.0)   # some at hi
    lo, hi = np.minimum(lo, hi - 0.1), np.maximum(hi, lo + 0.1)
    return A, b, A.T @ A, A.T @ b, lo, hi


def _kkt_residual(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  s: np.ndarray) -> float:
    """The largest violation of the box QP's optimality conditions at s, re-measured: the
    gradient's component that still points into the box (zero at the minimiser)."""
    grad = H @ s - g
    at_lo, at_hi = s <= lo, s >= hi
    inside = ~(at_lo | at_hi)
    worst = [np.abs(grad[inside]).max(initial=0.0), (-grad[at_lo]).max(initial=0.0),
             grad[at_hi].max(initial=0.0)]
    return max(worst) / np.abs(g).max()


@pytest.mark.parametrize("held", [0.0, 1000.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bounded_minimum_equals_bounded_least_squares(seed: int, held: float) -> None:
    A, b, H, g, lo, hi = _problem(seed, held=held)
    s, how = bounded_minimum(H, g, lo, hi)
    ref = np.clip(lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-14).x, lo, hi)
    assert how == "osqp"
    assert np.all((s >= lo) & (s <= hi))
    n_held = int(np.sum((s == lo) | (s == hi)))
    assert 10 <= n_held <= 70                               # the bounds are exercised
    assert np.abs(s - ref).max() <= 1e-8 * np.abs(ref).max()
    assert _kkt_residual(H, g, lo, hi, s) < 1e-9


@pytest.mark.parametrize("cond", [1e2, 1e5])
def test_bounded_minimum_of_a_problem_built_around_its_answer(cond: float) -> None:
    # H, the answer s* and the multipliers chosen, g made so that s* meets the optimality
    # conditions (sufficient: H positive definite): a quarter of the knots at lo, a tenth at hi,
    # half of those held with zero multiplier (degenerate: at the bound, no pull against it)
    rng = np.random.default_rng(5)
    k = 120
    Q = np.linalg.qr(rng.normal(size=(k, k)))[0]
    H = (Q * np.geomspace(1.0, cond, k)) @ Q.T
    H = 0.5 * (H + H.T)
    s_true = rng.uniform(1.0, 3.0, size=k)
    at_lo, at_hi = np.arange(k) % 4 == 0, np.arange(k) % 10 == 1
    lo = np.where(at_lo, s_true, s_true - rng.uniform(0.1, 1.0, size=k))
    hi = np.where(at_hi, s_true, s_true + rng.uniform(0.1, 1.0, size=k))
    mult = rng.uniform(0.01, 1.0, size=k) * (np.arange(k) % 8 < 4)   # zero on half of them
    grad = np.where(at_lo, mult, np.where(at_hi, -mult, 0.0))
    g = H @ s_true - grad
    s, how = bounded_minimum(H, g, lo, hi)
    assert how == "osqp"                     # the degenerate bounds do not defeat the check
    assert np.abs(s - s_true).max() <= 1e-9
    assert _kkt_residual(H, g, lo, hi, s) < 1e-8


def test_bounded_minimum_inside_the_box_is_the_free_minimiser() -> None:
    A, b, H, g, _, _ = _problem(3)
    free = np.linalg.lstsq(A, b, rcond=None)[0]
    s, how = bounded_minimum(H, g, free - 1.0, free + 1.0)
    assert how == "unbounded"
    assert np.abs(s - free).max() <= 1e-10 * np.abs(free).max()


def test_a_wrong_active_set_falls_back_to_bounded_least_squares(monkeypatch: Any) -> None:
    # OSQP answering the middle of the box with no bound active: the check refuses it
    A, b, H, g, lo, hi = _problem(4)

    class Wrong:
        def setup(self, *args: Any, **kwargs: Any) -> None:
            pass

        def solve(self, **kwargs: Any) -> Any:
            return SimpleNamespace(x=0.5 * (lo + hi), y=np.zeros(len(g)))

    monkeypatch.setattr(film_refine.osqp, "OSQP", Wrong)
    s, how = bounded_minimum(H, g, lo, hi)
    ref = np.clip(lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-14).x, lo, hi)
    assert how == "bvls"
    assert np.abs(s - ref).max() <= 1e-8 * np.abs(ref).max()
    assert _kkt_residual(H, g, lo, hi, s) < 1e-9
