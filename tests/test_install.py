"""The wheel installs one import name, `paintcell`, with its data, and works from outside the
repository: built with pip, installed into an empty target folder, imported by a fresh interpreter
whose working directory and path hold no repository folder."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel of the tracked files (copied out, so a developer's stale build/ cannot leak in
    and the build writes nothing into the repository)."""
    import shutil

    out = tmp_path_factory.mktemp("wheel")
    src = tmp_path_factory.mktemp("src")
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                           check=True).stdout.decode().split("\0")
    for f in filter(None, files):
        if (ROOT / f).is_file():
            (src / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / f, src / f)
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
           "-w", str(out), str(src)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    wheels = list(out.glob("paintcell-*.whl"))
    assert len(wheels) == 1
    return wheels[0]


@pytest.mark.slow
def test_the_wheel_holds_one_top_level_name_and_the_data(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"paintcell"}
    dist_info = next(n for n in names if n.endswith(".dist-info/RECORD")).rsplit("/", 1)[0]
    top_level = f"{dist_info}/top_level.txt"
    if top_level in names:
        assert zipfile.ZipFile(wheel).read(top_level).decode().split() == ["paintcell"]
    # the wheel's modules are exactly the tracked ones (nothing missing, no stale build/ files)
    tracked = subprocess.run(["git", "ls-files", "paintcell/*.py"], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split()
    assert tracked, "git ls-files found no modules"
    assert sorted(n for n in names if n.endswith(".py")) == sorted(tracked)
    for data in ("paintcell/paint/data/default_bell.toml",
                 "paintcell/robots/abb_paint/abb_paint.xml",
                 "paintcell/robots/abb_irb5500/abb_irb5500.xml",
                 # the report's 3-D film view
                 "paintcell/output/viewer/three-film.min.js",
                 "paintcell/output/viewer/film_view.js",
                 "paintcell/output/viewer/LICENSE-three.txt"):
        assert data in names, data


@pytest.mark.slow
def test_installed_paintcell_imports_and_runs_outside_the_repository(wheel: Path,
                                                                       tmp_path: Path) -> None:
    target = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target",
                           str(target), str(wheel)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    installed = sorted(p.name for p in target.iterdir()
                       if not p.name.endswith(".dist-info") and p.name != "bin")
    assert installed == ["paintcell"]
    # A fresh interpreter: the repository is neither the working directory nor on the path;
    # dependencies come from this environment's site-packages.
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(target)
    # Every module is imported and must come from the installed folder: a module missing from
    # the wheel must not be found in the repository through this environment's editable install.
    code = ("import importlib, pkgutil, sys, paintcell\n"
            "from paintcell.robots import load_robot\n"
            "from paintcell.paint.applicator import Applicator\n"
            "for m in pkgutil.walk_packages(paintcell.__path__, 'paintcell.'):\n"
            "    if m.name != 'paintcell.__main__':\n"
            "        importlib.import_module(m.name)\n"
            "print(paintcell.__file__)\n"
            "print(load_robot('abb_paint').nq, Applicator.default().name)\n"
            "print(' '.join(sorted(f'{k}={v.__file__}' for k, v in sys.modules.items()\n"
            "                      if k.startswith('paintcell'))))\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.split("\n")
    assert Path(lines[0]).resolve().is_relative_to(target.resolve())
    assert lines[1].split()[0] == "6"
    loaded = dict(kv.split("=", 1) for kv in lines[2].split())
    assert len(loaded) > 50   # the whole package was imported
    outside = sorted(k for k, f in loaded.items() if not Path(f).resolve().is_relative_to(
        target.resolve()))
    assert not outside, f"modules loaded from outside the installed wheel: {outside}"
    # the command line of the installed package
    cli = subprocess.run([sys.executable, "-m", "paintcell", "--help"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert cli.returncode == 0, cli.stderr[-2000:]
    assert "check" in cli.stdout and "run" in cli.stdout
