"""Settings dataclasses built from a scenario's tables (`[planner]`, `[servo]`, …): a misspelt
key or a value of the wrong type is refused in one line naming the table and what to write.

TOML keeps types, so `moving_vias = "false"` is a string — truthy, the opposite of what was
meant; a typo'd key would run with its default.
"""

from __future__ import annotations

import functools
import numbers
import types
import typing
from dataclasses import fields
from typing import Any

import numpy as np

from paintcell.core.errors import ScenarioDataError, ScenarioError

__all__ = ["check_types", "settings_from"]


def settings_from(cls: type, values: dict[str, Any], what: str) -> Any:
    """An instance of the settings dataclass `cls` from a scenario's dict, with a clear error
    naming the valid keys when one is misspelt or a value is not of its field's type."""
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ScenarioError(f"unknown {what} setting(s) {unknown}; valid: {sorted(names)}")
    check_types(cls, values, f"[{what}]")
    return cls(**values)


def _toml(v: Any) -> str:
    """`v` as the user wrote it, for an error line ("the string 'false'", "true", "2.5")."""
    if isinstance(v, str):
        return f"the string {v!r}"
    if isinstance(v, bool | np.bool_):
        return "true" if v else "false"
    if isinstance(v, list | tuple | np.ndarray):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(v)


def _is_real(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool | np.bool_)


def _fits(v: Any, t: Any) -> bool:
    if t is type(None):
        return v is None
    if t is bool:
        return isinstance(v, bool | np.bool_)
    if t is int:
        return isinstance(v, numbers.Integral) and not isinstance(v, bool | np.bool_)
    if t is float:
        return _is_real(v)
    if t is str:
        return isinstance(v, str)
    if typing.get_origin(t) in (tuple, list):
        return isinstance(v, list | tuple | np.ndarray) and all(_is_real(x) for x in v)
    return True  # a type these tables do not use: the class checks it


_WHAT = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def _fix(key: str, v: Any, alts: tuple[Any, ...]) -> str:
    """What the user can write instead of `v`."""
    s = v.strip().lower() if isinstance(v, str) else None
    if bool in alts:
        if s in ("false", "no", "off", "0"):
            return f"write {key} = false"
        if s in ("true", "yes", "on", "1"):
            return f"write {key} = true"
        return f"write {key} = true or {key} = false"
    if int in alts and _is_real(v) and float(v).is_integer():
        return f"write {key} = {int(v)}"
    if (float in alts or int in alts) and s is not None:
        try:
            x = float(s)
        except ValueError:
            pass
        else:
            return f"write {key} = {int(x) if int in alts and x.is_integer() else x!r} " \
                   "(no quotes)"
    if any(typing.get_origin(t) in (tuple, list) for t in alts):
        return f"write {key} = [0.0, 1.5, …] (numbers, no quotes)"
    what = " or ".join(_WHAT.get(t, "a value of its type") for t in alts if t is not type(None))
    return f"write {key} as {what}"


@functools.cache
def _field_types(cls: type) -> dict[str, tuple[Any, ...]]:
    """Each field's annotated type as its union alternatives."""
    hints = typing.get_type_hints(cls)
    return {f.name: (typing.get_args(hints[f.name])
                     if isinstance(hints[f.name], types.UnionType)
                     or typing.get_origin(hints[f.name]) is typing.Union else (hints[f.name],))
            for f in fields(cls)}


def check_types(cls: type, values: dict[str, Any], where: str) -> None:
    """Refuse a settings value that is not of its dataclass field's annotated type, in one line.

    TOML keeps types, so `moving_vias = "false"` is a string — truthy, the opposite of what was
    meant. A bool must be a TOML boolean; a float any number but a boolean; an int a whole
    number; a tuple a list of numbers. `where` names the table, e.g. "door.toml [trajectory]".
    """
    types_ = _field_types(cls)
    for key, v in values.items():
        alts = types_.get(key)
        if alts is None or any(_fits(v, t) for t in alts):
            continue
        what = " or ".join(dict.fromkeys(
            "a list of numbers" if typing.get_origin(t) in (tuple, list) else _WHAT.get(t, str(t))
            for t in alts if t is not type(None)))
        raise ScenarioDataError(f"{where} {key} must be {what} (got {_toml(v)}); "
                                f"{_fix(key, v, alts)}")
