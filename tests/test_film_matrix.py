"""The film refinement's film matrix (paintcell.coverage.film_refine): each column is the film
one knot's slowness lays; with every knot at slowness 1 the columns sum to the plan's own film,
summed here sample by sample with the deposition model. Its blocks are kept between fits by the
passes' content: a fit built again from kept blocks gets the same matrix bit for bit, and a pass
whose brush-on changed gets its own block, equal to the film it now lays."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from paintcell.coverage import film_refine
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.offset_polyline import arc_length
from paintcell.paint.applicator import Applicator
from paintcell.surface import parts
from tests.helpers import sampled_film


@pytest.fixture(scope="module")
def plan_on_panel() -> tuple:
    part = parts.get_part("panel", resolution_m=0.05)
    app = Applicator.default()
    plan = plan_coverage(part, app, PlannerSettings(film_refine=False))
    return part, app, list(plan.passes)


def _matrix(app: Applicator, passes: list, pts: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    basis = [film_refine._knot_basis(arc_length(p.positions),
                                     film_refine.KNOT_SPACING_M)[0] for p in passes]
    return film_refine._film_matrix([app] * len(passes), passes, basis, pts, nrm)


def test_film_matrix_at_unit_slowness_is_the_plans_film(plan_on_panel: tuple,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    part, app, passes = plan_on_panel
    V, N = part.vertices, part.normals
    monkeypatch.setattr(film_refine, "_BLOCKS", film_refine._Blocks(10**9))
    M = _matrix(app, passes, V, N)
    truth = sampled_film(app, passes, V, N)
    assert truth.max() > 0
    np.testing.assert_allclose(M.sum(axis=1), truth, rtol=1e-9, atol=1e-12 * truth.max())
    # built again from the kept blocks: the same matrix, bit for bit
    assert film_refine._BLOCKS.used > 0
    assert np.array_equal(_matrix(app, passes, V, N), M)
    # one pass painted on half its samples: its own block, the film it now lays
    k = len(passes) // 2
    half = passes[k].paint_on.copy()
    half[: len(half) // 2] = False
    changed = [*passes[:k], replace(passes[k], paint_on=half), *passes[k + 1:]]
    M2 = _matrix(app, changed, V, N)
    np.testing.assert_allclose(M2.sum(axis=1), sampled_film(app, changed, V, N), rtol=1e-9,
                               atol=1e-12 * truth.max())
    assert not np.array_equal(M2, M)
    # with no block kept, the same matrix bit for bit
    monkeypatch.setattr(film_refine, "_BLOCKS", film_refine._Blocks(0))
    assert np.array_equal(_matrix(app, changed, V, N), M2)
    assert film_refine._BLOCKS.used == 0
