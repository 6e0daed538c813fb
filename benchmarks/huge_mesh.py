"""What a mesh far finer than the run's resolution costs: `paintcell inspect` and `paintcell
init` on a generated binary STL of ~2 million faces (a 1.0 × 0.8 m gently curved panel in mm,
triangle soup as CAD exports write it), wall time and peak resident memory of each command
(the child's ru_maxrss), one labelled figure a line.

Run: PYTHONPATH=$PWD .venv/bin/python benchmarks/huge_mesh.py [--faces 2000000] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_panel_stl(path: Path, n_faces: int) -> int:
    """A curved 1.0 × 0.8 m panel [mm] as a binary STL of about `n_faces` triangles (an
    nx × ny grid, two triangles a cell); returns the face count written."""
    ny = max(2, int(np.sqrt(n_faces / 2 / 1.25)))
    nx = max(2, int(round(1.25 * ny)))
    x, y = np.meshgrid(np.linspace(0.0, 1000.0, nx + 1), np.linspace(0.0, 800.0, ny + 1),
                       indexing="ij")
    z = 60.0 * np.sin(np.pi * x / 1000.0) * np.sin(np.pi * y / 800.0)
    p = np.stack([x, y, z], axis=-1).astype(np.float32)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    tri = np.concatenate([np.stack([a, b, c], axis=2).reshape(-1, 3, 3),
                          np.stack([a, c, d], axis=2).reshape(-1, 3, 3)])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tri
    with open(path, "wb") as fh:
        fh.write(b"paintcell benchmark panel".ljust(80, b" "))
        fh.write(np.uint32(len(tri)).tobytes())
        fh.write(rec.tobytes())
    return len(tri)


def measure(cmd: list[str]) -> tuple[int, float, float, str]:
    """(exit code, wall [s], peak RSS of the child [GiB], its last stderr line)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    tail = (r.stderr.strip().splitlines() or [""])[-1]
    return r.returncode, wall, max(peak, before) / 2**20, tail


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--faces", type=int, default=2_000_000)
    ap.add_argument("--keep", type=Path, default=None, help="write the STL here and keep it")
    ap.add_argument("--only", choices=("inspect", "init"), default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = args.keep or Path(tmp)
        d.mkdir(parents=True, exist_ok=True)
        stl = d / "huge_panel.stl"
        n = write_panel_stl(stl, args.faces)
        print(f"mesh: {n} faces, {stl.stat().st_size / 1e6:.1f} MB binary STL (mm)")
        exe = [sys.executable, "-m", "paintcell"]
        runs = {"inspect": [*exe, "inspect", str(stl), "--png", str(Path(tmp) / "i.png")],
                "init": [*exe, "init", str(stl), "--out", str(Path(tmp) / "s.toml")]}
        for name, cmd in runs.items():
            if args.only and name != args.only:
                continue
            rc, wall, peak, tail = measure(cmd)
            # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: run one per process
            # (--only) for a clean peak of the second command.
            print(f"{name}: exit {rc}, {wall:.1f} s wall, peak RSS {peak:.2f} GiB"
                  + (f" ({tail})" if rc else ""))


if __name__ == "__main__":
    main()
