"""Pieces a gap apart planned as one surface (paintcell.coverage.stitch) and the openings they
enclose (paintcell.coverage.openings.find_openings).

Independent truths, closed forms of rectangles: a flat 0.8 × 0.3 m panel and, 15 mm above it, an
inverted-U frame (0.8 × 0.4 m with a 0.64 × 0.32 m window cut from its bottom edge) are two
pieces, neither with a hole; stitched, they are one piece with two boundary loops — the outline
of the whole door and the window, whose area is the window's plus the gap strip below it
(0.64 × 0.015 m²: no strip reaches into it along the panel's edge), and every edge is shared by
at most two faces; the stitched area is the two pieces' plus at least half and at most all of
the gap strips under the legs (2 × 0.08 × 0.015 m²; the outer corners, where the panel's edge
turns away from the leg, are left open). Pieces 0.1 m apart are left apart; so are the panel
and frame as patches of one piece of the part file (the import's piece of each face), stitched
when they are its two pieces.
"""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.coverage.openings import boundary_loops, find_openings, vertex_pieces
from paintcell.coverage.stitch import stitched_surface
from paintcell.surface.analytic import grid_faces
from paintcell.surface.surface_data import Surface, surface_from_triangles

STEP = 0.02
WIN_W, WIN_H, GAP = 0.64, 0.32, 0.015


def _grid(x0: float, x1: float, y0: float, y1: float, cut=None) -> tuple[np.ndarray, np.ndarray]:
    x = np.linspace(x0, x1, int(round((x1 - x0) / STEP)) + 1)
    y = np.linspace(y0, y1, int(round((y1 - y0) / STEP)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    F = grid_faces(len(x), len(y))
    if cut is not None:
        F = F[~cut(V[F].mean(axis=1))]
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def door(gap: float) -> Surface:
    """The panel (y ≤ 0) and, `gap` above it, the frame with its window (module docstring)."""
    vp, fp = _grid(-0.4, 0.4, -0.3, 0.0)
    vf, ff = _grid(-0.4, 0.4, gap, gap + 0.4,
                   lambda c: (np.abs(c[:, 0]) < WIN_W / 2) & (c[:, 1] < gap + WIN_H))
    V = np.vstack([vp, vf])
    F = np.vstack([fp, ff + len(vp)])
    s = surface_from_triangles("door", V, F)
    return s if s.normals[:, 2].mean() > 0 else surface_from_triangles("door", V, F[:, ::-1])


def _n_pieces(s: Surface) -> int:
    return len(np.unique(vertex_pieces(s.faces, len(s.vertices))[np.unique(s.faces)]))


def test_pieces_apart_have_outlines_not_holes() -> None:
    s = door(GAP)
    assert _n_pieces(s) == 2
    assert find_openings(s) == []


def test_stitched_pieces_are_one_surface_round_their_window() -> None:
    s = door(GAP)
    st = stitched_surface(s, 0.046)
    assert _n_pieces(st) == 1
    assert len(st.vertices) == len(s.vertices)
    np.testing.assert_array_equal(st.faces[:len(s.faces)], s.faces)
    assert len(boundary_loops(st.faces, len(st.vertices))) == 2
    (o,) = find_openings(st)
    assert o.area_m2 == pytest.approx(WIN_W * WIN_H + WIN_W * GAP, rel=1e-9)
    assert o.centroid[0] == pytest.approx(0.0, abs=1e-9)
    e = np.sort(np.concatenate([st.faces[:, [0, 1]], st.faces[:, [1, 2]], st.faces[:, [2, 0]]]),
                axis=1)
    assert np.unique(e, axis=0, return_counts=True)[1].max() <= 2
    assert np.all(st.normals[:, 2] > 0.999)                    # wound like the pieces
    legs = 2 * 0.08 * GAP
    assert s.area + 0.5 * legs <= st.area <= s.area + legs + 1e-12


def _with_pieces(s: Surface, piece_of_face: np.ndarray) -> Surface:
    import dataclasses

    from paintcell.surface.regions import SKIN, PartRegions

    regs = PartRegions(np.full(len(s.faces), SKIN, np.int8), piece_of_face.astype(np.int32),
                       np.array([0.0, 0.0, 1.0]))
    return dataclasses.replace(s, regions=regs)


def test_patches_of_one_file_piece_are_not_stitched_and_pieces_of_a_file_are() -> None:
    """The import's piece of each face decides: the frame and panel as patches of one file
    piece (a strip of skin cut off by another region) stay apart; as two file pieces they are
    stitched as before."""
    s = door(GAP)
    comp = vertex_pieces(s.faces, len(s.vertices))[s.faces[:, 0]]
    assert _n_pieces(stitched_surface(_with_pieces(s, np.zeros(len(s.faces))), 0.046)) == 2
    assert _n_pieces(stitched_surface(_with_pieces(s, comp), 0.046)) == 1


def test_pieces_far_apart_are_left_apart() -> None:
    s = door(0.1)
    assert _n_pieces(stitched_surface(s, 0.046)) == 2
