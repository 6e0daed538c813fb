"""A griffe extension (mkdocs.yml, mkdocstrings `extensions`): `name: text` entries as lists.

paintcell's docstrings describe fields and arguments as paragraphs of `name: text` lines, the
text's continuation indented or starting in lower case (`a / b: text` and `a, b: text` describe
several). Markdown would run such a paragraph together into one; this turns each run of entries
into a bulleted list with the names in code, leaving every other line as it is.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ENTRY = re.compile(r"^(?P<names>[A-Za-z_][A-Za-z0-9_]*(?:\s*(?:,|/)\s*[A-Za-z_][A-Za-z0-9_]*)*):"
                    r"\s+(?P<text>\S.*)$")
#: A line that carries on the sentence of the line before (a wrap at the margin), not a new one.
_CARRIES_ON = re.compile(r"^[a-z(`\[{'\"]")


def as_lists(doc: str) -> str:
    """`doc` with each paragraph-starting run of `name: text` entries as a Markdown list."""
    out: list[str] = []
    in_list = False
    fence = False
    for line in doc.splitlines():
        if line.lstrip().startswith("```"):
            fence = not fence
        m = None if fence else _ENTRY.match(line)
        starts_paragraph = not out or not out[-1].strip() or in_list
        if m is not None and starts_paragraph:
            if not in_list and out and out[-1].strip():
                out.append("")
            names = ", ".join(f"`{n.strip()}`" for n in re.split(r"[,/]", m["names"]))
            out.append(f"- {names}: {m['text']}")
            in_list = True
        elif in_list and line.strip() and (line.startswith(" ") or _CARRIES_ON.match(line)):
            out.append("  " + line.strip())      # the entry's continuation
        else:
            if in_list and line.strip():
                out.append("")                     # the list ends before this paragraph
            in_list = False
            out.append(line)
    return "\n".join(out)


class FieldLists(griffe.Extension):
    """Rewrites every docstring griffe loads with `as_lists`."""

    def on_instance(self, *, node: Any, obj: griffe.Object, agent: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = as_lists(obj.docstring.value)
