"""Fuzz of the part-file import: corrupt, extreme and mislabelled meshes, and meshes far finer than
the run needs.

Each case asserts what `tests/fuzz/fuzz_cases.py` states: `import_part` returns a surface or
refuses in one line naming the file (never another exception), and through the real `paintcell
inspect` the refusal exits 2 with exactly one stderr line (no library warning). Files are
written here by hand (binary STL records with numpy, OBJ/PLY as text), so what each case holds
is known independently of the readers under test; seeded generators corrupt them at random.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest

from paintcell.surface.part_import import import_part
from paintcell.surface.part_spec import MeshPart
from tests.fuzz.fuzz_cases import cli_refusal, loader_outcome


def grid(nx: int, ny: int, size_m: tuple[float, float] = (1.0, 0.8), bump_m: float = 0.0
         ) -> np.ndarray:
    """(2·nx·ny, 3, 3) triangles of a size_m rectangle [m] split into nx × ny cells, raised by a
    sine bump of bump_m."""
    x, y = np.meshgrid(np.linspace(0, size_m[0], nx + 1), np.linspace(0, size_m[1], ny + 1),
                       indexing="ij")
    z = bump_m * np.sin(np.pi * x / size_m[0]) * np.sin(np.pi * y / size_m[1])
    p = np.stack([x, y, z], axis=-1)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], axis=2).reshape(-1, 3, 3),
                           np.stack([a, c, d], axis=2).reshape(-1, 3, 3)])


def stl_bytes(tri: np.ndarray, count: int | None = None) -> bytes:
    """A binary STL of triangles (F, 3, 3) (float32 records; header count `count` if given)."""
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    n = len(tri) if count is None else count
    return b"fuzz".ljust(80, b" ") + np.uint32(n).tobytes() + rec.tobytes()


def obj_bytes(v: np.ndarray, f: np.ndarray) -> bytes:
    lines = [f"v {a} {b} {c}" for a, b, c in v] + [f"f {a} {b} {c}" for a, b, c in f + 1]
    return ("\n".join(lines) + "\n").encode()


GOOD = grid(20, 16, bump_m=0.03)
GOOD_MM = GOOD * 1000.0
_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
_F = np.array([[0, 1, 2], [0, 2, 3]])

CORRUPT: dict[str, tuple[str, bytes]] = {
    "empty": (".stl", b""),
    "header_only": (".stl", stl_bytes(GOOD)[:84]),
    "truncated": (".stl", stl_bytes(GOOD)[:5000]),
    "count_too_high": (".stl", stl_bytes(GOOD, count=10**6)),
    "count_too_low": (".stl", stl_bytes(GOOD, count=3)),
    "count_zero": (".stl", stl_bytes(GOOD[:0])),
    "garbage": (".stl", bytes(range(256)) * 40),
    "ascii_bad_numbers": (".stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex a b c\n"
                                  b"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid x\n"),
    "ascii_no_facets": (".stl", b"solid x\nendsolid x\n"),
    "inf_vertices": (".stl", stl_bytes(np.where(np.arange(GOOD.size).reshape(GOOD.shape) % 7 == 0,
                                                np.inf, GOOD))),
    "nan_vertices": (".stl", stl_bytes(np.full_like(GOOD, np.nan))),
    "one_nan_vertex": (".stl", stl_bytes(np.concatenate([GOOD, [[[np.nan, 0, 0]] * 3]]))),
    "degenerate_collinear": (".stl", stl_bytes(np.stack([np.linspace(0, 1, 30)[:, None]
                                                         * [1, 0, 0]] * 3, axis=1)
                                               + np.array([0, 0.1, 0.2])[None, :, None]
                                               * [1, 0, 0])),
    "degenerate_points": (".stl", stl_bytes(np.zeros((50, 3, 3)))),
    "one_triangle": (".stl", stl_bytes(GOOD[:1])),
    "huge_coordinates": (".stl", stl_bytes(GOOD * 1e30)),
    "microscopic": (".stl", stl_bytes(GOOD * 1e-9)),
    "obj_bad_index": (".obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\nf 1 2 3\n"),
    "obj_zero_index": (".obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
    "obj_no_faces": (".obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
    "obj_text": (".obj", b"hello world\n"),
    "obj_binary": (".obj", bytes(range(256)) * 8),
    "obj_inf": (".obj", obj_bytes(np.where(_V > 0, np.inf, 0.0), _F)),
    "ply_no_magic": (".ply", b"PLY\nformat ascii 1.0\nend_header\n"),
    "ply_header_lies": (".ply", b"ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\n"
                                b"property float y\nproperty float z\nelement face 1\nproperty "
                                b"list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n"),
    "ply_binary_garbage": (".ply", b"ply\n" + bytes(range(256)) * 8),
    "stl_named_obj": (".obj", stl_bytes(GOOD)),
    "stl_named_ply": (".ply", stl_bytes(GOOD)),
    "obj_named_stl": (".stl", obj_bytes(_V, _F)),
    "unknown_suffix": (".xyz", stl_bytes(GOOD)),
    "no_suffix": ("", stl_bytes(GOOD)),
}


@pytest.mark.parametrize("kind", sorted(CORRUPT))
def test_a_corrupt_mesh_is_refused_in_one_line_naming_the_file(tmp_path: Path,
                                                               kind: str) -> None:
    suffix, data = CORRUPT[kind]
    p = tmp_path / f"part{suffix}"
    p.write_bytes(data)
    msg = loader_outcome(lambda: import_part(MeshPart(file=str(p)), 0.05), str(p))
    assert msg is not None, f"{kind} was imported"


@pytest.mark.parametrize("scale,units,given", [(1.0, "m", "auto"), (1000.0, "mm", "auto"),
                                              (100.0, "cm", "cm"), (1 / 0.0254, "in", "in")])
def test_units_are_inferred_and_the_part_keeps_its_size(tmp_path: Path, scale: float,
                                                        units: str, given: str) -> None:
    p = tmp_path / "part.stl"
    p.write_bytes(stl_bytes(grid(20, 16) * scale))
    surf, rep = import_part(MeshPart(file=str(p), units=given), 0.05)
    assert rep.units.units == units
    ext = np.ptp(surf.vertices, axis=0)
    assert abs(ext[0] - 1.0) < 1e-4 and abs(ext[1] - 0.8) < 1e-4, ext


def test_a_part_far_from_the_origin_keeps_its_size(tmp_path: Path) -> None:
    tri = grid(20, 16).reshape(-1, 3) * 1000.0 + [5.0e5, -2.0e5, 1.0e4]   # CAD world mm
    p = tmp_path / "part.obj"
    p.write_bytes(obj_bytes(tri, np.arange(len(tri)).reshape(-1, 3)))
    surf, rep = import_part(MeshPart(file=str(p)), 0.05)
    assert rep.units.units == "mm"
    ext = np.ptp(surf.vertices, axis=0)
    assert abs(ext[0] - 1.0) < 1e-4 and abs(ext[1] - 0.8) < 1e-4, ext


# --- seeded corruptions of a good file ----------------------------------------------------

@pytest.mark.parametrize("seed", range(30))
def test_random_byte_corruption_imports_or_is_refused(tmp_path: Path, seed: int) -> None:
    rng = random.Random(seed)
    data = bytearray(stl_bytes(GOOD_MM))
    for _ in range(rng.randint(1, 40)):
        i = rng.randrange(84, len(data))
        data[i] = rng.randrange(256)
    if rng.random() < 0.3:
        data = data[: rng.randrange(84, len(data))]
    p = tmp_path / "part.stl"
    p.write_bytes(bytes(data))
    loader_outcome(lambda: import_part(MeshPart(file=str(p)), 0.05), str(p))


@pytest.mark.parametrize("seed", range(15))
def test_random_triangle_soups_import_or_are_refused(tmp_path: Path, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    scale = 10.0 ** rng.uniform(-6, 8)
    tri = rng.normal(size=(n, 3, 3)) * scale
    if seed % 3 == 0:
        tri[rng.integers(0, n)] = 0.0          # a collapsed triangle among them
    p = tmp_path / "part.stl"
    p.write_bytes(stl_bytes(tri))
    loader_outcome(lambda: import_part(MeshPart(file=str(p)), 0.05), str(p))


@pytest.mark.fuzz_full
@pytest.mark.parametrize("seed", range(30, 150))
def test_random_byte_corruption_long_run(tmp_path: Path, seed: int) -> None:
    test_random_byte_corruption_imports_or_is_refused(tmp_path, seed)


# --- a mesh far finer than the resolution: thinned on the way in ----------------------------

def test_a_fine_mesh_is_thinned_and_keeps_its_outline_and_area(tmp_path: Path) -> None:
    p = tmp_path / "fine.stl"
    p.write_bytes(stl_bytes(grid(250, 200) * 1000.0))     # 100,000 faces, a flat 1.0 × 0.8 m
    surf, rep = import_part(MeshPart(file=str(p)), 0.05)
    assert rep.repair.thinned_from == 100_000 and rep.repair.faces_in < 100_000 / 4
    assert "thinned" in rep.repair.summary()
    ext = np.ptp(surf.vertices, axis=0)
    assert abs(ext[0] - 1.0) < 1e-6 and abs(ext[1] - 0.8) < 1e-6, ext   # the outline stays
    assert abs(rep.area_after_remesh_m2 - 0.8) < 0.8 * 1e-3        # the plane's area, 0.1 %


def test_a_mesh_near_the_resolution_is_not_thinned(tmp_path: Path) -> None:
    p = tmp_path / "coarse.stl"
    p.write_bytes(stl_bytes(grid(40, 32) * 1000.0))
    _, rep = import_part(MeshPart(file=str(p)), 0.05)
    assert rep.repair.thinned_from == 0 and rep.repair.faces_in == 2 * 40 * 32


# --- through the real command -------------------------------------------------------------

_CLI = ["inf_vertices", "degenerate_collinear", "truncated", "empty", "obj_named_stl",
        "ply_header_lies"]


@pytest.mark.parametrize("kind", [k if k == "inf_vertices" else
                                  pytest.param(k, marks=pytest.mark.fuzz_full) for k in _CLI])
def test_inspect_refuses_in_one_line_without_warnings(tmp_path: Path, kind: str) -> None:
    suffix, data = CORRUPT[kind]
    p = tmp_path / f"part{suffix}"
    p.write_bytes(data)
    cli_refusal(["inspect", str(p), "--resolution", "0.05"], tmp_path, str(p))


def test_inspect_at_a_micrometre_is_refused_by_the_budget(tmp_path: Path) -> None:
    p = tmp_path / "part.stl"
    p.write_bytes(stl_bytes(GOOD_MM))
    line = cli_refusal(["inspect", str(p), "--resolution", "1e-6"], tmp_path, str(p))
    assert "--resolution = 1e-06 m" in line and "available" in line
