"""Reading a results folder: its files, each checked, and the scenario from its snapshot.

Nothing here imports or runs a file named in the folder: the scenario comes from the data in
`scenario.json` (`paintcell.app.scenario_data.scenario_from_snapshot`). Every unreadable file is
named in a one-line error with the fix (re-run `paintcell run`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import read_regular_bytes

__all__ = ["load_run_dir", "read_json"]

_ZIP_MAGIC = b"PK\x03\x04"


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object file; a missing, corrupt or non-object file is named in the error."""
    path = Path(path)
    try:
        d = json.loads(read_regular_bytes(path).decode("utf-8"))
    except FileNotFoundError:
        raise PaintcellError(f"{path} is missing; re-run `paintcell run`") from None
    except (ValueError, UnicodeDecodeError) as exc:
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
    files = {
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
    return files


def check_folder_files(d: Path) -> None:
    """Check every data file a report reads (JSON objects, npz archives) before it reads them,
    so a corrupt one is named in one line instead of failing deep inside the report."""
    d = Path(d)
    for name in ("metrics.json", "scenario.json", "figures.json", "plan.json"):
        if (d / name).exists() or name == "metrics.json":
            read_json(d / name)
    for name in ("plan.npz", "trajectory.npz", "trace.npz"):
        path = d / name
        if path.exists() or path.is_symlink():
            if read_regular_bytes(path, head_bytes=4) != _ZIP_MAGIC:
                raise PaintcellError(f"{path} is not an .npz archive (no zip header; "
                                     "corrupt or replaced); re-run `paintcell run`")
