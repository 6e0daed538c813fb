"""A body's panel files written again from the body generator (`paintcell generate body`,
`paintcell.surface.car_body`), so a paint line laid out for a generated body
(`paintcell init BODY --line`) names its seed instead of carrying megabytes of meshes.

- `generated_origin(path, panels)`: the seed and the way `path` was read ("mesh": the body's
  one mesh, its panels found from the gaps; "panels": its `body.json` folder) when `path` is
  the generator's output — the seed its truth file (`<stem>.truth.json`) or manifest records,
  and that seed's body, read the same way, gives the same panels (names, and areas within
  `AREA_RTOL`); else None.
- `generated_panels(seed, read)`: those panels, from the generator (deterministic).
- `ensure_panel_files(table, files, where)`: the booth file's `[generated_body]` table
  (`seed`, `read`, `areas_m2`: each panel's area in the order of its `[[parts]]`) and its parts'
  files: every file there with its area is kept, the missing ones are written again (binary STL
  in metres, body frame, as `init --line` writes them); a file there that is not its panel, or
  a body the generator no longer makes, is refused in one line, nothing replaced.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError

__all__ = ["AREA_RTOL", "ensure_panel_files", "file_area_m2", "generated_origin",
           "generated_panels"]

#: Relative tolerance on a panel's area for "the same panel" [-] (a float32 STL round trip
#: moves a 0.3 m² panel's area by ~1e-8 relative).
AREA_RTOL = 1e-6
_READS = ("mesh", "panels")


def generated_panels(seed: int, read: str) -> list[Any]:
    """The generator's body for `seed`, written as `paintcell generate body` writes it (binary
    STL) and read back by `paintcell.surface.body_panels.load_body` as `read` says."""
    from paintcell.surface.body_panels import MANIFEST_NAME, load_body
    from paintcell.surface.car_body import generate_body

    if read not in _READS:
        raise PaintcellError(f"read = {read!r} must be one of {', '.join(_READS)}")
    body = generate_body(int(seed))
    with tempfile.TemporaryDirectory(prefix="paintcell-body-") as d:
        if read == "mesh":
            f = Path(d) / "body.stl"
            body.mesh().export(f, file_type="stl")
            return load_body(f)
        for name, m in body.panels.items():
            m.export(Path(d) / f"{name}.stl", file_type="stl")
        (Path(d) / MANIFEST_NAME).write_text(json.dumps(body.manifest("stl")))
        return load_body(Path(d))


def _recorded_seed(path: Path) -> tuple[int, str] | None:
    """(seed, read) a generated body's truth file or manifest records, else None."""
    if path.is_dir() or path.suffix.lower() == ".json":
        doc_path, read = (path / "body.json" if path.is_dir() else path), "panels"
    else:
        doc_path, read = path.with_name(f"{path.stem}.truth.json"), "mesh"
    try:
        doc = json.loads(doc_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    seed = doc.get("seed") if isinstance(doc, dict) else None
    if isinstance(seed, bool) or not isinstance(seed, int) or "kind" not in doc:
        return None
    return seed, read


def _same(a: Sequence[Any], b: Sequence[Any]) -> bool:
    return (len(a) == len(b) and all(x.name == y.name for x, y in zip(a, b, strict=True))
            and bool(np.allclose([x.area_m2 for x in a], [y.area_m2 for y in b], rtol=AREA_RTOL,
                                 atol=0.0)))


def generated_origin(path: str | Path, panels: Sequence[Any]) -> dict[str, Any] | None:
    """{"seed", "read"} when `path` (read into `panels`) is the generator's body (module doc),
    else None."""
    rec = _recorded_seed(Path(path))
    if rec is None:
        return None
    try:
        fresh = generated_panels(*rec)
    except PaintcellError:
        return None
    return {"seed": rec[0], "read": rec[1]} if _same(panels, fresh) else None


def file_area_m2(path: str | Path) -> float:
    """Area of a mesh file's triangles [file units²] (a panel file: m²)."""
    import trimesh

    m = trimesh.load(str(path), force="mesh")
    assert isinstance(m, trimesh.Trimesh)
    return float(m.area)


def _areas(files: Sequence[Path]) -> list[float | None]:
    """Each file's area [m²]; None where it is missing or not a readable mesh."""
    out: list[float | None] = []
    for f in files:
        try:
            out.append(file_area_m2(f) if f.is_file() and not f.is_symlink() else None)
        except Exception:   # noqa: BLE001 — any unreadable file is one to write again
            out.append(None)
    return out


def ensure_panel_files(table: Any, files: Sequence[Path], where: str) -> None:
    """The panel files of a booth's `[generated_body]` table (module doc): kept when each has
    its area, else written again from the generator; PaintcellError (one line) when the table
    is malformed or the generator's body is not the one the booth was laid out for."""
    from paintcell.core.atomic_io import atomic_path

    if not isinstance(table, dict) or set(table) != {"seed", "read", "areas_m2"}:
        raise PaintcellError(f"{where} [generated_body] needs exactly seed, read and areas_m2 "
                             "(as `paintcell init BODY --line` writes it)")
    seed, read, areas = table["seed"], table["read"], table["areas_m2"]
    if isinstance(seed, bool) or not isinstance(seed, int) or read not in _READS \
            or not isinstance(areas, list) or len(areas) != len(files) \
            or not all(isinstance(a, int | float) and a > 0 for a in areas):
        raise PaintcellError(f"{where} [generated_body]: seed must be an integer, read one of "
                             f"{', '.join(_READS)}, areas_m2 one area [m²] per [[parts]] "
                             f"({len(files)})")
    have = _areas(files)
    if all(a is not None for a in have) and np.allclose(np.asarray(have, float), areas,
                                                          rtol=AREA_RTOL, atol=0.0):
        return
    panels = generated_panels(seed, read)
    fresh = [p.area_m2 for p in panels]
    if len(panels) != len(files) or not np.allclose(fresh, areas, rtol=AREA_RTOL, atol=0.0):
        raise PaintcellError(f"{where}: `paintcell generate body --seed {seed}` no longer makes "
                             f"the body this line was laid out for ({len(panels)} panels, "
                             f"{sum(fresh):.4f} m² against {len(files)}, {sum(areas):.4f} m²); "
                             "lay the line out again with `paintcell init BODY --line`")
    for f, a, want in zip(files, have, areas, strict=True):
        if f.exists() or f.is_symlink():
            if a is None or not np.isclose(a, want, rtol=AREA_RTOL, atol=0.0):
                raise PaintcellError(f"{where}: {f} is not the panel of `paintcell generate "
                                     f"body --seed {seed}` this line was laid out for; delete "
                                     "it to have it written again, or lay the line out again")
    for f, a, p in zip(files, have, panels, strict=True):
        if a is not None:
            continue                                     # kept: the panel it should be
        f.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(f) as dst:
            p.mesh.export(str(dst), file_type="stl")
