"""Part import speed: read + repair + remesh of the largest shared mesh (179k faces) at 10 and
5 mm, and the remesher choice (pymeshlab's isotropic explicit remeshing against gpytoolbox's
Botsch–Kobbelt `remesh_botsch`, when installed) on the same repaired piece.

Run: PYTHONPATH=$PWD .venv/bin/python benchmarks/import.py   (one labelled figure per line)
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from paintcell.surface.mesh_io import read_part_file
from paintcell.surface.mesh_repair import remesh, repair
from paintcell.surface.part_import import split_pieces
from paintcell.surface.regions import face_areas

MESH = Path(__file__).resolve().parents[1] / ".." / "shared" / "meshes" / \
    "bezier_part_scan_12_pieces.ply"


def timed(fn):  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def main() -> None:
    if not MESH.is_file():
        print(f"skipped: {MESH} is absent")
        return
    raw, t_read = timed(lambda: read_part_file(MESH))
    print(f"read {MESH.name}: {t_read:.2f} s ({len(raw.faces)} faces)")
    (v, f, rep), t_rep = timed(lambda: repair(raw.vertices, raw.faces))
    print(f"repair: {t_rep:.2f} s ({rep.summary()})")
    piece = split_pieces(v, f)[0]
    used, inv = np.unique(f[piece], return_inverse=True)
    pv, pf = v[used], inv.reshape(-1, 3)
    a0 = float(face_areas(pv, pf).sum())
    for res in (0.010, 0.005):
        (rv, rf), t_rm = timed(lambda r=res: remesh(pv, pf, r))
        a = float(face_areas(rv, rf).sum())
        print(f"pymeshlab remesh @ {res * 1e3:.0f} mm: {t_rm:.2f} s, {len(rf)} faces, area "
              f"{100 * (a / a0 - 1):+.3f} %; read + repair + remesh {t_read + t_rep + t_rm:.2f} s "
              f"({(t_read + t_rep + t_rm) / t_read:.1f}× the read alone)")
        try:
            import gpytoolbox
        except ImportError:
            print("gpytoolbox not installed: remesher comparison skipped")
            continue
        (gv, gf), t_g = timed(lambda r=res: gpytoolbox.remesh_botsch(
            pv.astype(np.float64), pf.astype(np.int32), i=6, h=r, project=True))
        ag = float(face_areas(gv, gf).sum())
        print(f"gpytoolbox remesh_botsch @ {res * 1e3:.0f} mm: {t_g:.2f} s, {len(gf)} faces, "
              f"area {100 * (ag / a0 - 1):+.3f} % ({t_g / t_rm:.2f}× pymeshlab's time)")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
