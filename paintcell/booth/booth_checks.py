"""The checks a booth file passes when it is loaded, before any work.

A booth that cannot run must be refused at once, in one line naming the file, the table, the key
and the fix — not after seconds of planning with a message about something else (an unknown
robot model found when the robots are built, a reversed rail found as "the conveyor tracking
needs 3.12 m of its rail", a part listed twice found by the allocation). Checked here: at least
one `[[robots]]` and one `[[parts]]`; each robot's name (unique), model (known, and able to
stand on a rail when it has one), rail (two numbers, lower < upper, inside ±`RAIL_LIMIT_M`) and
home (one number per joint, the carriage inside the rail); each part once (the same part at the
same place twice is a copy); `[allocation]` (a table of known robots to [part, first pass, end
pass] triples, parts in range); numbers where numbers belong, with the key named.
"""

from __future__ import annotations

import math
from typing import Any

from paintcell.core.errors import PaintcellError

__all__ = ["ARM_JOINTS", "RAIL_ARMS", "RAIL_LIMIT_M", "BoothDataError", "check_allocation",
           "check_parts_once", "check_robot", "check_structure", "number", "numbers"]

#: Joints of each arm model (`paintcell.robots.catalog`); a rail model has one more (the rail).
ARM_JOINTS = {"abb_paint": 6, "irb5500": 6, "ur10": 6}
#: Arms that have a rail model ("<arm>_rail", `paintcell.robots.rail`).
RAIL_ARMS = ("abb_paint", "irb5500")
#: Largest carriage position a rail may reach, either way [m] (paint-booth rails run up to
#: ~15 m; a value past this is a unit slip, e.g. millimetres).
RAIL_LIMIT_M = 20.0


class BoothDataError(PaintcellError):
    """A booth file holds an unknown key or an invalid value."""


def _models() -> list[str]:
    return [*ARM_JOINTS, *(f"{a}_rail" for a in RAIL_ARMS)]


def number(v: Any, where: str, lo: float = -math.inf, hi: float = math.inf,
           unit: str = "") -> float:
    """`v` as a float when it is a finite number in [lo, hi]; else a BoothDataError naming
    `where` (file, table and key) and the valid range."""
    rng = f"[{lo:g}, {hi:g}]" + (f" {unit}" if unit else "")
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise BoothDataError(f"{where} = {v!r} must be a number {rng} (no quotes)")
    if not math.isfinite(v) or not lo <= v <= hi:
        raise BoothDataError(f"{where} = {v!r} is out of range; valid: {rng}")
    return float(v)


def numbers(v: Any, n: int | None, where: str, lo: float = -math.inf, hi: float = math.inf,
            unit: str = "", example: str = "") -> tuple[float, ...]:
    """A list of `n` finite numbers in [lo, hi] (any length when n is None) as floats."""
    if not isinstance(v, list | tuple) or (n is not None and len(v) != n):
        what = "a list" if n is None else f"a list of {n} numbers"
        raise BoothDataError(f"{where} = {v!r} must be {what}" +
                             (f", e.g. {example}" if example else ""))
    return tuple(number(x, f"{where}[{i}]", lo, hi, unit) for i, x in enumerate(v))


def check_structure(d: dict[str, Any], where: str) -> None:
    """At least one robot and one part, each a table of an array (`[[robots]]`, `[[parts]]`)."""
    for key, example in (("robots", 'name = "side_a", model = "irb5500"'),
                         ("parts", 'part = "door", xyz_m = [0, 0, 0]')):
        v = d.get(key)
        if v is None or (isinstance(v, list) and not v):
            raise BoothDataError(f"{where}: a booth needs at least one [[{key}]] table; add "
                                 f"[[{key}]] with {example}")
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            raise BoothDataError(f"{where}: {key} must be [[{key}]] tables (an array of tables, "
                                 f"each with {example}), got {type(v).__name__}")


def check_robot(r: dict[str, Any], i: int, where: str, seen: set[str]
                ) -> tuple[str, str, tuple[float, float] | None, tuple[float, ...] | None]:
    """(name, model, rail, home) of `[[robots]]` table #i, checked (module doc)."""
    at = f"{where} [[robots]] #{i}"
    name = r.get("name")
    if not isinstance(name, str) or not name or not all(c.isalnum() or c in "_-" for c in name):
        raise BoothDataError(f"{at}: name = {name!r} must be letters, digits, '_' or '-', e.g. "
                             'name = "side_a"')
    if name in seen:
        raise BoothDataError(f"{at}: name = {name!r} is already the name of another robot; "
                             "robot names must be unique")
    seen.add(name)
    at = f"{where} [[robots]] {name}"
    model = r.get("model", "irb5500")
    if not isinstance(model, str) or model not in _models():
        raise BoothDataError(f"{at}: model = {model!r} is not a known robot; valid: "
                             f"{', '.join(_models())}")
    rail = None
    arm = model.removesuffix("_rail")
    if "rail" in r:
        if arm not in RAIL_ARMS:
            raise BoothDataError(f"{at}: model {model!r} has no rail; rail arms: "
                                 f"{', '.join(RAIL_ARMS)} (or drop rail)")
        if not isinstance(r["rail"], list) or len(r["rail"]) != 2:
            raise BoothDataError(f"{at}: rail = {r['rail']!r} must be rail = [lower, upper] "
                                 "carriage travel [m], e.g. [-1.2, 1.2]")
        lo, hi = numbers(r["rail"], 2, f"{at} rail", -RAIL_LIMIT_M, RAIL_LIMIT_M, "m")
        if not lo < hi:
            raise BoothDataError(f"{at}: rail = {list(r['rail'])!r} must be [lower, upper] with "
                                 f"lower < upper [m]; write rail = [{hi:g}, {lo:g}]")
        rail = (lo, hi)
        model = f"{arm}_rail"
    n_joints = ARM_JOINTS[arm] + (1 if model.endswith("_rail") else 0)
    home = None
    if r.get("home") is not None:
        home = numbers(r["home"], n_joints, f"{at} home", -100.0, 100.0, "rad (rail: m)",
                       f"{n_joints} joint values" + (" (the rail's [m] first)"
                                                     if model.endswith("_rail") else ""))
        travel = rail or ((-2.0, 2.0) if model.endswith("_rail") else None)
        if travel is not None and not travel[0] <= home[0] <= travel[1]:
            raise BoothDataError(f"{at}: home[0] = {home[0]:g} m puts the carriage off its "
                                 f"rail [{travel[0]:g}, {travel[1]:g}] m; move it onto the rail")
    return name, model, rail, home


def _part_key(p: dict[str, Any]) -> tuple[Any, ...]:
    part = p.get("part")
    what = repr(sorted(part.items())) if isinstance(part, dict) else repr(part)
    return (what, tuple(p.get("xyz_m", (0.0, 0.0, 0.0))), tuple(p.get("rpy_rad", (0.0, 0.0, 0.0))))


def check_parts_once(parts: list[dict[str, Any]], where: str) -> None:
    """Refuse a part listed twice at the same place (a copied `[[parts]]` table)."""
    first: dict[tuple[Any, ...], int] = {}
    for i, p in enumerate(parts):
        k = _part_key(p)
        if k in first:
            raise BoothDataError(f"{where} [[parts]] #{i}: part = {p.get('part')!r} at the same "
                                 f"xyz_m and rpy_rad as [[parts]] #{first[k]}; each part is "
                                 "listed once, remove the copy")
        first[k] = i


def check_allocation(alloc: Any, robots: list[str], n_parts: int, where: str
                     ) -> dict[str, Any]:
    """The `[allocation]` table: {robot name: [part index, first pass, end pass] or a list of
    them}, robots known, indices whole numbers ≥ 0, parts in range, first < end; returned as
    written, lists as tuples (`paintcell.booth.booth.Booth.allocation`)."""
    at = f"{where} [allocation]"
    if not isinstance(alloc, dict):
        raise BoothDataError(f"{at} must be a table of robot name = [part index, first pass, "
                             f"end pass], e.g. [allocation] {robots[0]} = [0, 0, 4]; got "
                             f"{type(alloc).__name__}")
    out: dict[str, Any] = {}
    for name, v in alloc.items():
        if name not in robots:
            raise BoothDataError(f"{at}: {name!r} is not a robot of the booth; robots: "
                                 f"{', '.join(robots)}")
        triples = v if isinstance(v, list) and v and isinstance(v[0], list) else [v]
        jobs = []
        for t in triples:
            if not isinstance(t, list) or len(t) != 3 or not all(
                    isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in t):
                raise BoothDataError(f"{at}: {name} = {v!r} must be [part index, first pass, "
                                     "end pass] (whole numbers ≥ 0), or a list of them")
            p, a, b = t
            if p >= n_parts:
                raise BoothDataError(f"{at}: {name} = {v!r} names part {p}; the booth has "
                                     f"[[parts]] 0..{n_parts - 1}")
            if not a < b:
                raise BoothDataError(f"{at}: {name} = {v!r}: first pass {a} must be below end "
                                     f"pass {b}")
            jobs.append((p, a, b))
        out[name] = tuple(jobs) if triples is v else jobs[0]
    return out
