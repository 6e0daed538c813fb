"""Write the site's scenario and command-line references from the code that reads them.

    python docs/tools/gen_reference.py scenario|cli      # print one page (Markdown)

`mkdocs build` calls `scenario_reference` and `cli_reference` through docs/tools/hooks.py, so
the pages are made at build time and never copied by hand: the scenario keys, their TOML types,
defaults and ranges come from `paintcell.app.scenario_keys` (the table the loader checks files
against), each key's meaning from the docstring of the settings class that holds it, and the
command-line options from the argparse parsers `paintcell.cli.main.build_parser` builds.
"""

from __future__ import annotations

import argparse
import ast
import inspect
import json
import math
import re
import sys
import textwrap
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:   # run as a script from a checkout
    sys.path.insert(0, str(ROOT))

#: The scenario file the reference shows as its example (read when the page is made).
EXAMPLE = ROOT / "scenarios" / "panel.toml"

#: The title of each table's section and what it is for (the key table holds the keys).
TABLE_TITLES = {
    "": ("Top level", "The scalar keys at the top of the file."),
    "part": ("[part]", "A part read from a mesh or CAD file, given as a table instead of "
             "`part = \"…\"` (`paintcell.surface.part_spec.MeshPart`)."),
    "part_placement": ("[part_placement]", "Where the part frame sits in the world. The "
                       "table is required; a key it leaves out is zero."),
    "base": ("[base]", "Where the robot base sits in the world."),
    "planner": ("[planner]", "Settings of the coverage planner, Algorithm 1 "
                "(`paintcell.coverage.coverage_settings.PlannerSettings`); give only what "
                "differs from the default."),
    "fast_planner": ("[fast_planner]", "Planner settings applied over `[planner]` in `--fast` "
                     "runs."),
    "trajectory": ("[trajectory]", "Settings of the time law and the moves between passes "
                   "(`paintcell.motion.trajectory.TrajectorySettings`)."),
    "servo": ("[servo]", "The joint servo of the execution "
              "(`paintcell.execution.execute.ServoSettings`)."),
    "disturbances": ("[disturbances]", "Seeded errors between the planned cell and the "
                     "executed one (`paintcell.execution.execute.Disturbances`); "
                     "empty: the nominal cell."),
    "thresholds": ("[thresholds]", "The limits `paintcell run` and `paintcell check` hold the "
                   "run to (`paintcell.validation.validate_report.Thresholds`)."),
    "spec": ("[spec]", "The paint spec the executed film is judged against "
             "(`paintcell.validation.paint_spec.PaintSpec`); absent: these defaults. "
             "`[thresholds] max_executed_nsd_pct` only tightens its σ/μ."),
    "sweep": ("[sweep]", "The robustness sweep of `paintcell sweep` "
              "(`paintcell.validation.sweep_spec`), with its sub-tables `[sweep.factors]` and "
              "`[sweep.limits]`."),
}


# --- key descriptions from the settings classes' docstrings ----------------------------------

_ENTRY = re.compile(r"^(?P<names>[a-z_][a-z0-9_]*(?:\s*(?:,|/)\s*[a-z_][a-z0-9_]*)*):\s+"
                    r"(?P<text>.*)$")


def field_docs(cls: type) -> dict[str, str]:
    """Each field's description in `cls`'s docstring: `name: text` entries of the class
    docstring (`a / b: text` and `a, b: text` describe both) and attribute docstrings (a string
    right after the field), joined into one line."""
    out: dict[str, str] = {}
    doc = inspect.getdoc(cls) or ""
    names: list[str] = []
    for line in doc.splitlines():
        m = _ENTRY.match(line)
        if m is not None:
            names = [n.strip() for n in re.split(r"[,/]", m["names"])]
            for n in names:
                out[n] = m["text"].strip()
        elif line.startswith(" ") and names:
            for n in names:
                out[n] += " " + line.strip()
        else:
            names = []
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body  # type: ignore[attr-defined]
    for stmt, nxt in zip(body, body[1:], strict=False):
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) \
                and isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) \
                and isinstance(nxt.value.value, str):
            out[stmt.target.id] = " ".join(nxt.value.value.split())
    return out


# --- Markdown helpers ------------------------------------------------------------------------

def cell(text: str) -> str:
    """`text` safe in a Markdown table cell: pipes escaped, `<`, `>` and `&` escaped outside
    code spans, on one line."""
    parts = " ".join(str(text).split()).split("`")
    for i in range(0, len(parts), 2):      # outside code spans
        parts[i] = parts[i].replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return "`".join(parts).replace("|", "\\|")


def toml_literal(v: Any) -> str:
    """`v` as a TOML value literal (what a scenario file writes)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if isinstance(v, int | float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(toml_literal(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_literal(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"no TOML literal for {v!r}")


def interval(lo: float, hi: float, lo_closed: bool, hi_closed: bool) -> str:
    """`[lo, hi]` / `(lo, hi)` with TOML numbers (`inf`)."""
    return (("[" if lo_closed else "(") + f"{toml_literal(float(lo))}, "
            f"{toml_literal(float(hi))}" + ("]" if hi_closed else ")"))


# --- the scenario reference -------------------------------------------------------------------

def _default_cell(key: Any) -> str:
    if key.required:
        return "*required*"
    if key.default_text:
        return f"*{key.default_text}*"
    if key.default is None:
        return "*unset*"
    return f"`{toml_literal(key.default)}`"


def _valid_cell(key: Any) -> str:
    words = []
    if key.low is not None:
        words.append(f"`{interval(key.low, key.high, key.low_closed, key.high_closed)}`")
    if key.valid:
        words.append(cell(key.valid))
    return "; ".join(words)


def scenario_reference() -> str:
    """The scenario reference page (Markdown)."""
    from paintcell.app.scenario_keys import TABLES, scenario_keys

    keys = scenario_keys()
    lines = [
        "# Scenario file reference", "",
        "A scenario is a TOML file: the top-level keys below, then tables. Every key is checked "
        "when the file is read: an unknown key, a value of the wrong type, a number out of its "
        "range or a non-finite number is refused with one line naming the file, the table, the "
        "key and what is valid. Relative paths are relative to the scenario file. "
        "`paintcell init` writes a commented scenario for a part file; `scenarios/` holds one "
        "per library part.", "",
        "Columns: the key's TOML type; its default (*unset*: the key has no value unless "
        "given, with the meaning the description says); the values the loader accepts "
        "(`[a, b]` includes its bounds, `(a, b)` excludes them; `inf` is TOML's infinity); "
        "and the description from the class that holds the setting.", "",
        "This page is generated from `paintcell.app.scenario_keys`, the table the loader "
        "checks files against.", "",
        f"An example, `{EXAMPLE.relative_to(ROOT)}` as shipped:", "", "```toml",
        EXAMPLE.read_text(encoding="utf-8").strip(), "```", "",
    ]
    for table in ("", *TABLES):
        title, what = TABLE_TITLES[table]
        rows = [k for k in keys if k.table == table]
        lines += [f"## `{title}`" if table else f"## {title}", "", what, ""]
        if table == "fast_planner":
            lines += ["It accepts every `[planner]` key, with the same types and ranges; a key "
                      "it does not set takes the scenario's `[planner]` value (and that, the "
                      "default of the `[planner]` table below).", "",
                      "Keys: " + ", ".join(f"`{k.name}`" for k in rows) + ".", ""]
            continue
        docs = field_docs(rows[0].owner) if rows and rows[0].owner is not None else {}
        lines += ["| Key | Type | Default | Valid | Description |",
                  "|---|---|---|---|---|"]
        for k in rows:
            text = k.doc or docs.get(k.name, "")
            lines.append(f"| `{k.name}` | {k.kind} | {_default_cell(k)} | {_valid_cell(k)} | "
                         f"{cell(text)} |")
        lines.append("")
        if table == "sweep":
            lines += _sweep_notes()
    return "\n".join(lines)


def _sweep_notes() -> list[str]:
    from paintcell.validation.sweep_names import FACTORS, SAMPLE_METRICS

    lines = ["### `[sweep.factors]`", "",
             "One `NAME = \"DIST\"` per disturbance to vary; DIST is `normal(mean, sd)`, "
             "`uniform(low, high)`, `triangular(low, mode, high)`, "
             "`truncnormal(mean, sd, low, high)` or a plain number, in the factor's unit.", "",
             "| Factor | Unit | Meaning |", "|---|---|---|"]
    lines += [f"| `{n}` | {cell(u)} | {cell(m)} |" for n, (u, m) in FACTORS.items()]
    lines += ["", "### `[sweep.limits]`", "",
              "`max_pNN_<figure>` / `min_pNN_<figure>` bound the NN-th percentile of a figure "
              "over the samples; `min_yield_pct` and `min_yield_lower_pct` bound the share of "
              "samples that pass (and its lower confidence bound) [%]. Figures:", "",
              "| Figure | Unit |", "|---|---|"]
    lines += [f"| `{n}` | {cell(u)} |" for n, u in SAMPLE_METRICS.items()]
    return [*lines, ""]


# --- the command-line reference ---------------------------------------------------------------

def _value(action: argparse.Action) -> str:
    """The argument's value as `--help` shows it: its metavar, else its choices, else its name."""
    if action.nargs == 0:
        return ""
    if action.metavar is None and action.choices is not None:
        return "{" + ",".join(map(str, action.choices)) + "}"
    meta = action.metavar or (action.dest.upper() if action.option_strings else action.dest)
    return str(meta) + (" …" if action.nargs in ("*", "+") else "")


def _help(action: argparse.Action, prog: str) -> str:
    text = action.help or ""
    if "%(" in text:
        text = text % {**vars(action), "prog": prog}
    if action.metavar is not None and action.choices is not None:   # not in the Value column
        text += " (choices: " + ", ".join(f"`{c}`" for c in action.choices) + ")"
    return text


def _default(action: argparse.Action) -> str:
    d = action.default
    if action.required or d in (None, False, [], argparse.SUPPRESS):
        return ""
    if isinstance(d, list):
        return " ".join(f"`{x}`" for x in d)
    return f"`{d}`"


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The sub-command parsers of `parser`, by name, in the order they were added."""
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return dict(a.choices)
    return {}


def cli_reference() -> str:
    """The command-line reference page (Markdown)."""
    from paintcell.cli.main import EXIT_HELP, build_parser

    parser = build_parser()
    lines = ["# Command-line reference", "",
             "This page is generated from the argument parsers of `paintcell` "
             "(`paintcell.cli.main.build_parser`); `paintcell COMMAND --help` prints the same.",
             "", f"{cell(parser.description or '')}", "", "```text",
             parser.format_usage().strip(), "```", "",
             "`--debug` (before or after the command): show the full traceback on errors "
             "instead of one line.", "", "```text", EXIT_HELP.strip(), "```", ""]
    lines += ["| Command | What it does |", "|---|---|"]
    subs = subcommands(parser)
    for name, sp in subs.items():
        first = (sp.description or "").split(". ")[0].rstrip(".")
        lines.append(f"| [`{name}`](#{name}) | {cell(first)} |")
    lines.append("")
    for name, sp in subs.items():
        lines += [f"## {name}", "", cell(sp.description or ""), "", "```text",
                  sp.format_usage().strip(), "```", "",
                  "| Argument | Value | Default | Description |", "|---|---|---|---|"]
        hidden = []
        for a in sp._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            if a.help == argparse.SUPPRESS:
                hidden.append(a)
                continue
            flag = ", ".join(f"`{o}`" for o in a.option_strings) or f"`{a.dest}`"
            if a.required and a.option_strings:
                flag += " (required)"
            value = _value(a)
            lines.append(f"| {flag} | {f'`{value}`' if value else ''} | {_default(a)} | "
                         f"{cell(_help(a, sp.prog))} |")
        lines.append("")
        if hidden:
            lines += ["Internal options, which `--help` does not show (paintcell passes them to "
                      "its own worker processes): "
                      + ", ".join(f"`{a.option_strings[0]} {_value(a)}`" for a in hidden)
                      + ".", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    pages = {"scenario": scenario_reference, "cli": cli_reference}
    if len(sys.argv) != 2 or sys.argv[1] not in pages:
        sys.exit("usage: python docs/tools/gen_reference.py scenario|cli")
    print(pages[sys.argv[1]]())
