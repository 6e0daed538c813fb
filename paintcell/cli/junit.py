"""The JUnit XML file of `paintcell check`: one test case per scenario (failures list the failing
thresholds, errors say what happened), and an error case of its own when the check itself did not
complete — so a CI that reads the file sees a pass only when every scenario passed. Every text is
stripped of terminal escapes and of the characters XML 1.0 forbids."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from paintcell.cli.common import fmt_value

__all__ = ["clean_text", "write_junit"]

_ANSI = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b[@-_]")
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def clean_text(text: str) -> str:
    """Text without terminal escape sequences and without the characters XML 1.0 forbids
    (NUL, BEL, ESC and the other control characters; lone surrogates)."""
    return _NOT_XML.sub("", _ANSI.sub("", text))


def write_junit(path: Path, cases: list[tuple[str, float, list[dict[str, Any]], str | None]],
                *, suite_error: tuple[str, str] | None = None) -> None:
    """JUnit XML with one test case per scenario; failures list the failing thresholds.
    `suite_error` (name, message): the check itself did not complete (interrupted, usage error,
    still running) — an error case of class `paintcell.check`, so the suite is never green.
    Every text is stripped of control characters (and XML-escaped by the writer)."""
    import xml.etree.ElementTree as ET

    from paintcell.core.atomic_io import atomic_write_text

    c, f = clean_text, fmt_value
    n_fail = sum(1 for _, _, checks, err in cases
                 if err is None and not all(ch["passed"] for ch in checks))
    n_err = sum(1 for case in cases if case[3] is not None) + (suite_error is not None)
    suite = ET.Element("testsuite", name="paintcell-check",
                       tests=str(len(cases) + (suite_error is not None)),
                       failures=str(n_fail), errors=str(n_err),
                       time=f"{sum(case[1] for case in cases):.3f}")
    for name, dt, checks, err in cases:
        case = ET.SubElement(suite, "testcase", classname="paintcell.scenarios", name=c(name),
                             time=f"{dt:.3f}")
        if err is not None:
            ET.SubElement(case, "error", message=c(err)).text = c(err)
            continue
        bad = [ch for ch in checks if not ch["passed"]]
        if bad:
            msg = "; ".join(f"{ch['name']}={f(ch['value'])} (limit {f(ch['limit'])})"
                            for ch in bad)
            ET.SubElement(case, "failure", message=c(msg)).text = c(msg)
        ET.SubElement(case, "system-out").text = c("\n".join(
            f"{ch['name']}: {f(ch['value'])} (limit {f(ch['limit'])} {ch.get('unit', '')})"
            for ch in checks))
    if suite_error is not None:
        case = ET.SubElement(suite, "testcase", classname="paintcell.check",
                             name=suite_error[0], time="0.000")
        ET.SubElement(case, "error", type=suite_error[0],
                      message=c(suite_error[1])).text = c(suite_error[1])
    atomic_write_text(path, ET.tostring(suite, encoding="unicode", xml_declaration=True))
