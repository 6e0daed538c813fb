"""What an exported RAPID module may say besides its moves: names and comments as RAPID takes
them, and the claim its header makes about validation.

An identifier is letters, digits and `_`, starting with a letter, at most 32 characters and no
reserved word (`rapid_ident`); a comment line is printable ASCII (`comment_text`). A module
exported from a results folder starts with `validation_header`: VALIDATED only when every
threshold re-derived from the folder's data passed and its metrics.json states what the data
give (`recorded_mismatches`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

#: RAPID's reserved words (ABB, Technical reference manual RAPID kernel, "Reserved words"), and
#: the predefined names and data types the module uses: an identifier may be none of them.
RESERVED = frozenset("""
    ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF
    ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF
    INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN
    STEP SYSMODULE TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR TASK
    NUM BOOL STRING ROBTARGET JOINTTARGET SPEEDDATA ZONEDATA TOOLDATA WOBJDATA TRIGGDATA
    LOADDATA CONFDATA POSE POS ORIENT EXTJOINT FINE V1000 TOOL0 WOBJ0 LOAD0 MAIN TBELL JHOME
    TBRUSHON TBRUSHOFF MOVEL MOVEABSJ TRIGGL TRIGGIO PAINTL SETBRUSH SETDO
""".split())
IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
#: Characters a comment may carry beyond printable ASCII, spelt out (RAPID files are ISO 8859-1,
#: and a controller's editor shows nothing else reliably).
_SPELT = {"σ": "sigma", "μ": "mu", "µ": "u", "≤": "<=", "≥": ">=", "→": "->", "—": "-",
          "–": "-", "×": "x", "²": "2", "³": "3", "°": "deg"}


def rapid_ident(name: str, what: str = "module") -> str:
    """A valid RAPID identifier for `name`: letters, digits and `_`, starting with a letter, at
    most 32 characters, and none of `RESERVED` (case-insensitive, as RAPID is); a name that is
    one gets the prefix `m_`/`m`."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not s or not s[0].isalpha():
        s = "m" + s
    s = s[:32]
    if s.upper() in RESERVED:
        s = ("m_" + s)[:32]
    if not IDENT.match(s):  # cannot happen for the rules above; never write an invalid name
        raise ValueError(f"cannot make a RAPID identifier of {what} name {name!r}")
    return s


def comment_text(text: object) -> str:
    """`text` made safe for one RAPID comment line: printable ASCII only (a few symbols spelt
    out, others `?`), no control character, newline or line separator, at most 200 characters."""
    s = "".join(_SPELT.get(c, c) for c in str(text))
    s = "".join(c if " " <= c <= "~" else ("?" if c.isprintable() else " ") for c in s)
    s = re.sub(r" {2,}", " ", s).strip()
    return s if len(s) <= 200 else s[:197] + "..."


def validation_header(checks: Sequence[Any], plan_digest: str,
                      mismatches: Sequence[str] = ()) -> list[str]:
    """Header lines for a module exported from a results folder.

    checks: the thresholds' `Check`s re-derived from the folder's data (`paintcell validate`'s
    computation with the thresholds of its scenario.json), never the verdict metrics.json states;
    mismatches: where metrics.json disagrees with them (a hand-edited or stale file).
    VALIDATED needs at least one check, every check passed with a finite value, and no mismatch;
    it names the digest of the plan (which the folder's plan.json, trajectory and trace carry; a
    digest, not the run id, so reruns export byte-identical modules). Otherwise the header says,
    first, that the run is NOT VALIDATED and why, so nobody loads it on a robot thinking it was
    proven.
    """
    bad = [c for c in checks if not (c.passed and math.isfinite(float(c.value)))]
    if checks and not bad and not mismatches:
        return [f"VALIDATED in MuJoCo simulation: PASS, all {len(checks)} thresholds met "
                f"(plan {plan_digest[:16]})."]
    why = "; ".join([f"{c.name} {c.value:.6g} vs limit {c.limit:.6g}" for c in bad]
                    + [f"metrics.json does not match its data: {m}" for m in mismatches]) \
        or "no threshold checked"
    return ["!!! NOT VALIDATED: THIS RUN FAILED VALIDATION - DO NOT RUN ON A ROBOT AS IS !!!",
            f"Failed: {why}.",
            f"Exported with --allow-failed (plan {plan_digest[:16]})."]


def recorded_mismatches(metrics: dict[str, Any], checks: Sequence[Any], passed: bool,
                        rel_tol: float = 1e-6) -> list[str]:
    """Where a results folder's `metrics.json` disagrees with the checks re-derived from its data:
    its verdict, a check missing or extra, a value off by more than `rel_tol` (NaN, null or text
    included) or a check's verdict. Empty when metrics.json states what the data give."""
    out: list[str] = []
    if metrics.get("passed") is not passed:
        out.append(f"passed = {metrics.get('passed')!r}, the data give {passed}")
    rec = {c.get("name"): c for c in metrics.get("checks") or [] if isinstance(c, dict)}
    for c in checks:
        r = rec.pop(c.name, None)
        if r is None:
            out.append(f"check {c.name!r} is missing")
            continue
        v = r.get("value")
        same = isinstance(v, int | float) and not isinstance(v, bool) and (
            math.isclose(float(v), c.value, rel_tol=rel_tol, abs_tol=1e-12)
            if math.isfinite(c.value) else False)
        if not same and not (v is None and not math.isfinite(c.value)):
            out.append(f"{c.name} = {v!r}, the data give {c.value:.6g}")
        elif r.get("passed") is not c.passed:
            out.append(f"{c.name} passed = {r.get('passed')!r}, the data give {c.passed}")
    out.extend(f"check {n!r} is not one the scenario sets" for n in rec)
    return out
