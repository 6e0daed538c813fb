"""Hem and flange film reported apart (paintcell.validation.region_film): closed-form films on a
plate whose
strips are labelled hem and edge."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from paintcell.surface.analytic import plane
from paintcell.surface.regions import REGION_NAMES, PartRegions
from paintcell.validation.region_film import region_film


def test_region_means_are_the_closed_form_averages() -> None:
    s = plane(1.0, 0.4, 0.01)                 # x ∈ [−0.5, 0.5], y ∈ [−0.2, 0.2]
    c = s.vertices[s.faces].mean(axis=1)
    labels = np.full(len(s.faces), REGION_NAMES.index("skin"), np.int8)
    labels[c[:, 0] > 0.4] = REGION_NAMES.index("hem")      # a 0.1 m strip at the +x end
    labels[c[:, 0] < -0.45] = REGION_NAMES.index("edge")   # a 0.05 m strip at the −x end
    regs = PartRegions(face_labels=labels, face_piece=np.zeros(len(s.faces), np.int32),
                       painted_direction=np.array([0.0, 0.0, 1.0]))
    s = dataclasses.replace(s, regions=regs)
    x = s.vertices[:, 0]
    film = 40e-6 + 20e-6 * x                   # linear: a strip's mean is its value mid-strip
    out = region_film(s, film, 2 * film, judged_mean_m=80e-6)
    # area-weighted over each strip (x ∈ [0.4, 0.5] and [−0.5, −0.45]): the mid-strip value
    assert out["hem_planned_mean_um"] == pytest.approx(40 + 20 * 0.45, rel=1e-3)
    assert out["hem_executed_mean_um"] == pytest.approx(2 * (40 + 20 * 0.45), rel=1e-3)
    assert out["edge_executed_mean_um"] == pytest.approx(2 * (40 - 20 * 0.475), rel=1e-3)
    assert out["hem_executed_vs_skin_pct"] == pytest.approx(100 * 98 / 80, rel=1e-3)
    assert "inner_executed_mean_um" not in out          # no inner faces: nothing reported
    assert region_film(dataclasses.replace(s, regions=None), film, film, 1.0) == {}
