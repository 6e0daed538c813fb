"""The generated CAD-like meshes the real-part scenarios paint (scenarios/parts/cad_*.ply) are the
generator's output for seed 0 (`paintcell generate KIND --out scenarios/parts/cad_KIND.ply`):
re-generated here and compared face by face, so a change to paintcell/surface/cad_like.py
cannot leave
the scenarios painting a stale file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from paintcell.surface.cad_like import PART_KINDS, make_part

PARTS = Path(__file__).resolve().parents[1] / "scenarios" / "parts"


@pytest.mark.parametrize("kind", PART_KINDS)
def test_committed_mesh_is_the_generator_output(kind: str) -> None:
    stored = trimesh.load(PARTS / f"cad_{kind}.ply", process=False, force="mesh")
    fresh = make_part(kind, 0).mesh
    assert stored.faces.shape == fresh.faces.shape
    # the same triangles, corner by corner [mm] (PLY keeps float32 or float64 coordinates)
    np.testing.assert_allclose(stored.vertices[stored.faces], fresh.vertices[fresh.faces],
                               atol=1e-3)
    assert f'"parts/cad_{kind}.ply"' in (PARTS.parent / f"cad_{kind}.toml").read_text()
