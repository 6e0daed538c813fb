"""`paintcell init` on every shared mesh (issue 12 item 6: "seconds, not minutes"): wall and CPU
time per mesh and what init decided — the robot it chose (and whether it wrote `fold_moves`) or
its one-line refusal.

Each mesh runs as `python -m paintcell init FILE --out DIR/NAME.toml` in its own process, one at a
time, as a user runs it; the first run of a fresh checkout also compiles the numba film kernels
(once per install), so one warm-up init runs first and is not counted.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py                 # every shared mesh
    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py ../shared/meshes/reach_hood_panel.ply

Columns: wall time [s]; CPU time of the init process (user + system) [s]; the result.
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

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"


def run_init(mesh: Path, out: Path) -> tuple[float, float, str]:
    """(wall [s], CPU [s], result line) of one `paintcell init` in its own process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "paintcell", "init", str(mesh), "--out",
                           str(out)], capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode == 0:
        cell = next((ln for ln in proc.stdout.splitlines() if ln.startswith("cell: ")), "cell: ?")
        fold = "fold_moves = true" in out.read_text()
        robot = cell.removeprefix("cell: ").split(":")[0].split(",")[0]     # "robot irb5500"
        result = robot + (" + fold_moves" if fold else "")
    else:
        result = "refused: " + (proc.stderr.strip().splitlines() or ["?"])[-1][:160]
    return wall, cpu, result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("meshes", nargs="*", type=Path,
                    help="mesh files (default: every .ply/.stl in ../shared/meshes)")
    ap.add_argument("--no-warm-up", action="store_true",
                    help="skip the uncounted warm-up init (numba kernels already compiled)")
    args = ap.parse_args()
    meshes = args.meshes or sorted(p for p in MESHES.glob("*") if p.suffix in (".ply", ".stl"))
    if not meshes:
        sys.exit(f"no meshes given and none in {MESHES}")
    with tempfile.TemporaryDirectory() as tmp:
        if not args.no_warm_up:
            run_init(meshes[0], Path(tmp) / "warm_up.toml")
        print(f"{'mesh':32s} {'wall s':>8s} {'CPU s':>8s}  result")
        for mesh in meshes:
            wall, cpu, result = run_init(mesh, Path(tmp) / f"{mesh.stem}.toml")
            print(f"{mesh.stem:32s} {wall:8.1f} {cpu:8.1f}  {result}", flush=True)


if __name__ == "__main__":
    main()
