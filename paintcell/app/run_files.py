"""Reading a results folder back — of a one-robot scenario or of a booth of several robots —
and what `validate`, `export` and `report` make of it: its files, each checked, the scenario
from its snapshot, the validation recomputed, the robot programs (the report of either kind:
`paintcell.output.report.write_report`).

Nothing here imports or runs a file named in the folder: the scenario comes from the data in
`scenario.json` (`paintcell.app.scenario_data.scenario_from_snapshot`, a booth's
`paintcell.booth.booth_data.booth_from_snapshot`). Every unreadable file is named in a one-line
error with the fix (re-run `paintcell run`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from paintcell.core.data_text import DataTextError, parse_json
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import read_regular_bytes

__all__ = ["check_folder_files", "load_run_dir", "plans_digest", "program_modules",
           "read_json", "rederive", "revalidate_run_dir"]

_ZIP_MAGIC = b"PK\x03\x04"


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object file; a missing, corrupt or non-object file is named in the error."""
    path = Path(path)
    try:
        d = parse_json(read_regular_bytes(path).decode("utf-8"), str(path))
    except FileNotFoundError:
        raise PaintcellError(f"{path} is missing; re-run `paintcell run`") from None
    except (DataTextError, UnicodeDecodeError) as exc:
        raise PaintcellError(f"{path} is not readable JSON ({_first(exc)}); re-run "
                             "`paintcell run`") from exc
    if not isinstance(d, dict):
        raise PaintcellError(f"{path} must hold a JSON object; re-run `paintcell run`")
    return d


def _first(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def load_run_dir(d: Path) -> dict[str, Any]:
    """Scenario (from the snapshot), run settings, plan, trajectory and trace of a results folder.

    The plan, trajectory and trace must come from one run (the trajectory and trace carry the
    plan's digest).
    """
    from paintcell.app.scenario_data import scenario_from_snapshot
    from paintcell.coverage.plan import CoveragePlan
    from paintcell.execution.trace import ExecutedTrace
    from paintcell.motion.joint_trajectory import JointTrajectory

    d = Path(d)
    if not d.is_dir():
        raise PaintcellError(f"results folder {d} does not exist; run `paintcell run` first")

    def read(name: str, loader: Any) -> Any:
        path = d / name
        if not path.exists():
            raise PaintcellError(f"{path} is missing; {d} was not written by `paintcell run` "
                                 "(re-run it)")
        if path.suffix == ".npz":
            if read_regular_bytes(path, head_bytes=4) != _ZIP_MAGIC:
                raise PaintcellError(f"{path} is not an .npz archive (no zip header; "
                                     "corrupt or replaced); re-run `paintcell run`")
        try:
            return loader(path)
        except PaintcellError:
            raise
        except Exception as exc:
            raise PaintcellError(f"cannot read {path} ({type(exc).__name__}: {_first(exc)}); "
                                 "re-run `paintcell run`") from exc

    meta = read_json(d / "scenario.json")
    if meta.get("kind") == "booth":      # several robots: a plan per part, files per robot
        from paintcell.booth.booth_data import booth_from_snapshot
        from paintcell.booth.booth_results import read_booth_results

        booth = booth_from_snapshot(meta, str(d / "scenario.json"))
        return {"kind": "booth", "scenario": booth,
                "run": meta.get("run", {"fast": False, "mode": "servo"}),
                **read_booth_results(d, booth, read)}
    files = {
        "kind": "scenario",
        "scenario": scenario_from_snapshot(meta, str(d / "scenario.json")),
        "run": meta.get("run", {"fast": False, "mode": "servo"}),
        "plan": read("plan.json", CoveragePlan.load),
        "trajectory": read("trajectory.npz", JointTrajectory.load_npz),
        "trace": read("trace.npz", ExecutedTrace.load_npz),
    }
    digest = files["plan"].content_digest()
    for name in ("trajectory", "trace"):
        tagged = files[name].meta.get("plan_digest")
        if tagged is not None and tagged != digest:
            raise PaintcellError(f"{d / (name + '.npz')} was made from another plan than "
                                 f"{d / 'plan.json'}; re-run `paintcell run` on {d}")
    files["plans"], files["trajectories"] = [files["plan"]], [files["trajectory"]]
    return files


def plans_digest(files: dict[str, Any]) -> str:
    """The digest of a run's plans (`CoveragePlan.content_digest`; a booth: of its parts' plans
    together), the one a RAPID module's header names."""
    digests = [p.content_digest() for p in files["plans"]]
    if len(digests) == 1:
        return digests[0]
    import hashlib

    return hashlib.sha256("+".join(digests).encode()).hexdigest()


def rederive(files: dict[str, Any], metrics: dict[str, Any]) -> tuple[Any, Any]:
    """The validation of a loaded results folder (`load_run_dir`) recomputed from its data with
    the thresholds of its snapshot, never the verdict its metrics.json states: (the
    `ValidationReport`, write_films(folder) -> the film files it writes there). `metrics`: the
    folder's metrics.json (a booth's allocation, film build and seam records)."""
    from paintcell.output.gltf_film import write_film_files

    scn = files["scenario"]
    if files["kind"] == "booth":   # the film on the whole body on its conveyor, per robot
        from paintcell.booth.booth_results import booth_film, revalidate_booth

        rep, films = revalidate_booth(scn, files, metrics)
        return rep, lambda out: write_film_files(out, *booth_film(
            scn, files["body"], files["judged"], films, files["plans"]))
    from paintcell.app.pipeline import load_surface, run_film
    from paintcell.validation.validate import validate

    surface = load_surface(scn, bool(files["run"]["fast"]))
    plan, traj, trace = files["plan"], files["trajectory"], files["trace"]
    rep = validate(plan, surface, traj, trace, scn.part_placement.matrix, scn.thresholds,
                   reachability=traj.meta.get("reachability"), spec=scn.spec)
    files["surface"] = surface
    return rep, lambda out: write_film_files(out, *run_film(scn, surface, plan, rep))


def revalidate_run_dir(d: Path) -> tuple[str, Any, list[str]]:
    """Recompute the validation of results folder `d` from its files and snapshot (`rederive`)
    and rewrite its metrics.json and film files: (scenario name, the `ValidationReport`, the
    files written). The stage times of the old metrics.json are kept; a corrupt one is replaced
    with a warning."""
    import sys

    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.json_values import json_default

    d = Path(d)
    f = load_run_dir(d)
    scn, fast, mode = f["scenario"], bool(f["run"]["fast"]), str(f["run"]["mode"])
    old_path = d / "metrics.json"
    old: dict[str, Any] = {}
    if old_path.exists():
        try:
            old = read_json(old_path)
        except PaintcellError as exc:
            # metrics.json is what validate rewrites: a corrupt one is replaced, not fatal.
            sys.stderr.write(f"paintcell: warning: {exc} (replacing it)\n")
    stage_times = dict(old.get("stage_times_s") or {})
    rep, write_films = rederive(f, old)
    if f["kind"] == "booth":
        m = rep.to_dict()
        m["scenario"] = {"name": scn.name, "source": scn.source}
        m["stage_times_s"] = stage_times
    else:
        from paintcell.app.pipeline import RunResult, metrics_dict

        m = metrics_dict(RunResult(scn, d, f["surface"], f["plan"], f["trajectory"], f["trace"],
                                   rep, timings_s=stage_times, fast=fast, mode=mode))
    atomic_write_text(old_path, json.dumps(m, indent=2, default=json_default))
    return scn.name, rep, ["metrics.json", *write_films(d)]


def program_modules(files: dict[str, Any], metrics: dict[str, Any], header: list[str],
                    style: str, spacing_m: float) -> dict[str, str]:
    """{module name: RAPID text} of a results folder's robot programs (`load_run_dir`): one for a
    one-robot run (named for the scenario); one per robot of a booth, each task synchronised
    with the others (MultiMove `WaitSyncTask`) and coordinated with the conveyor. header: the
    validation lines each module starts with; style, spacing_m: `rapid_module`'s style and
    max_spacing_m [m]."""
    scn = files["scenario"]
    options: dict[str, Any] = {"style": style, "max_spacing_m": spacing_m, "validation": header}
    if files["kind"] == "booth":
        from paintcell.booth.booth_programs import load_robots
        from paintcell.output.export_rapid import cell_modules

        return cell_modules(scn, metrics, files["jobs"], files["static"], load_robots(scn),
                            **options)
    from paintcell.app.pipeline import load_robot_for
    from paintcell.output.export_rapid import rapid_module

    return {scn.name: rapid_module(files["trajectory"], load_robot_for(scn),
                                   module_name=scn.name, **options)}


def check_folder_files(d: Path) -> None:
    """Check every data file a report reads (JSON objects, npz archives) before it reads them,
    so a corrupt one is named in one line instead of failing deep inside the report."""
    d = Path(d)
    # a booth's: each part's plan_<i>.json / .npz, each robot's static_ / trace_ / trajectory_
    booth = sorted(p.name for p in d.glob("plan_*.*") if p.name.split(".")[0][5:].isdigit())
    booth += sorted(p.name for pat in ("static_*.npz", "trace_*.npz", "trajectory_*.npz")
                    for p in d.glob(pat))
    for name in ("metrics.json", "scenario.json", "figures.json", "plan.json",
                 *(n for n in booth if n.endswith(".json"))):
        if (d / name).exists() or name == "metrics.json":
            read_json(d / name)
    for name in ("plan.npz", "trajectory.npz", "trace.npz", *(n for n in booth
                                                               if n.endswith(".npz"))):
        path = d / name
        if path.exists() or path.is_symlink():
            if read_regular_bytes(path, head_bytes=4) != _ZIP_MAGIC:
                raise PaintcellError(f"{path} is not an .npz archive (no zip header; "
                                     "corrupt or replaced); re-run `paintcell run`")
