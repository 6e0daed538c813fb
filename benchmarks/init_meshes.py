"""`paintcell init` on every shared mesh: wall and CPU time per mesh and what init decided — the
robot it chose (and whether it wrote `fold_moves`) or its one-line refusal.

Each mesh runs as `python -m paintcell init FILE --out DIR/NAME.toml` in its own process, one at a
time, as a user runs it; the first run of a fresh checkout also compiles the numba film kernels
(once per install), so one warm-up init runs first and is not counted.

With `--baseline TREE` (another checkout of paintcell, e.g. `git archive main | tar -x -C
/tmp/base`), each mesh runs there first, then here, one after the other in this run, so that the
load of a shared machine falls on both alike: the table adds the baseline's CPU time, the ratio
(baseline / this tree) and whether the two scenario files are identical (or the refusals the same
line).

    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py                 # every shared mesh
    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py ../shared/meshes/reach_hood_panel.ply
    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py --baseline /tmp/base
    PYTHONPATH=$PWD .venv/bin/python benchmarks/init_meshes.py --keep /tmp/cells   # then run them

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


def run_init(mesh: Path, out: Path, tree: Path = ROOT) -> tuple[float, float, str]:
    """(wall [s], CPU [s], result line) of one `paintcell init` in its own process, with the
    paintcell of `tree` (this checkout by default)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "paintcell", "init", str(mesh), "--out",
                           str(out)], capture_output=True, text=True, cwd=tree,
                          env={**os.environ, "PYTHONPATH": str(tree)}, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode == 0:
        cell = next((ln for ln in proc.stdout.splitlines() if ln.startswith("cell: ")), "cell: ?")
        fold = "fold_moves = true" in out.read_text()
        robot = cell.removeprefix("cell: ").split(":")[0].split(",")[0]     # "robot irb5500"
        result = robot + (" + fold_moves" if fold else "")
    else:
        result = "refused: " + (proc.stderr.strip().splitlines() or ["?"])[-1]
    return wall, cpu, result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("meshes", nargs="*", type=Path,
                    help="mesh files (default: every .ply/.stl in ../shared/meshes)")
    ap.add_argument("--no-warm-up", action="store_true",
                    help="skip the uncounted warm-up init (numba kernels already compiled)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another paintcell checkout, run on each mesh before this one")
    ap.add_argument("--keep", type=Path, default=None,
                    help="copy this tree's scenario files here (to `paintcell run` them)")
    args = ap.parse_args()
    base: Path | None = args.baseline
    if base is not None and not (base / "paintcell" / "__main__.py").is_file():
        sys.exit(f"--baseline {base}: not a paintcell checkout (no paintcell/__main__.py)")
    meshes = args.meshes or sorted(p for p in MESHES.glob("*") if p.suffix in (".ply", ".stl"))
    if not meshes:
        sys.exit(f"no meshes given and none in {MESHES}")
    with tempfile.TemporaryDirectory() as tmp:
        out, out0 = Path(tmp) / "head", Path(tmp) / "base"   # same depth: same relative paths
        out.mkdir()
        out0.mkdir()
        if not args.no_warm_up:
            for tree in (ROOT,) if base is None else (base, ROOT):
                run_init(meshes[0], out / "warm_up.toml", tree)
        extra = "" if base is None else f" {'base CPU':>8s} {'ratio':>6s} {'same':>4s}"
        print(f"{'mesh':32s} {'wall s':>8s} {'CPU s':>8s}{extra}  result")
        for mesh in meshes:
            if base is not None:
                _, cpu0, result0 = run_init(mesh, out0 / f"{mesh.stem}.toml", base)
            wall, cpu, result = run_init(mesh, out / f"{mesh.stem}.toml")
            row = f"{mesh.stem:32s} {wall:8.1f} {cpu:8.1f}"
            if base is not None:
                same = _same(out0 / f"{mesh.stem}.toml", out / f"{mesh.stem}.toml",
                             result0, result)
                row += f" {cpu0:8.1f} {cpu0 / cpu:6.2f} {'yes' if same else 'NO':>4s}"
            print(f"{row}  {result[:160]}", flush=True)
            if args.keep is not None and (out / f"{mesh.stem}.toml").exists():
                args.keep.mkdir(parents=True, exist_ok=True)
                text = (out / f"{mesh.stem}.toml").read_text()   # part path relative to --keep
                (args.keep / f"{mesh.stem}.toml").write_text(text.replace(
                    f'file = "{os.path.relpath(mesh.resolve(), out.resolve())}"',
                    f'file = "{os.path.relpath(mesh.resolve(), args.keep.resolve())}"'))


def _same(toml0: Path, toml1: Path, result0: str, result1: str) -> bool:
    """Both runs wrote byte-identical scenarios, or both refused with the same line."""
    if result0 != result1:
        return False
    if toml0.exists() != toml1.exists():
        return False
    return not toml0.exists() or toml0.read_bytes() == toml1.read_bytes()


if __name__ == "__main__":
    main()
