"""The site's generated references say what the loader and the parsers accept.

The scenario and command-line reference pages (docs/tools/gen_reference.py) are read back as a
user reads them — Markdown tables — and checked against the real code by other routes than the
one that wrote them: each documented key is written into a TOML scenario with its documented
default and loaded; each documented range is probed at and just beyond its bounds; the keys the
loader's own error lines name as valid are the documented ones; each documented option is
parsed by the real parser and `--help` lists the documented options, no more. The hook that
fails `mkdocs build --strict` on a blank docstring is checked on a module that lacks one.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path
from typing import Any

import pytest

from paintcell.app.scenario_data import load_toml_scenario
from paintcell.cli.main import build_parser
from paintcell.core.errors import PaintcellError, ScenarioDataError

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "tools" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)
    spec.loader.exec_module(module)
    return module


gen = _load("gen_reference")

# --- the scenario reference, read back --------------------------------------------------------

_ROW = re.compile(r"^\| `(?P<key>[^`]+)` \| (?P<kind>[^|]*) \| (?P<default>[^|]*) \| "
                  r"(?P<valid>(?:[^|\\]|\\.)*) \| (?P<doc>.*) \|$")


def _scenario_doc() -> dict[str, dict[str, dict[str, str]]]:
    """{table: {key: row}} of the scenario reference ("" is the top level; the section title
    `[t]` names table t)."""
    out: dict[str, dict[str, dict[str, str]]] = {}
    table = None
    for line in gen.scenario_reference().splitlines():
        m = re.match(r"^## (?:`\[(\w+)\]`|(Top level))$", line)
        if m:
            table = m.group(1) or ""
            out[table] = {}
            continue
        if line.startswith("### "):
            table = None
        if table is None:
            continue
        row = _ROW.match(line)
        if row:
            out[table][row["key"]] = row.groupdict()
        elif line.startswith("Keys: "):   # [fast_planner]: the [planner] keys, listed
            out[table] = {k: {"key": k, "default": "*[planner]*", "valid": "", "doc": "x"}
                          for k in re.findall(r"`(\w+)`", line)}
    return out


DOC = _scenario_doc()
_BASE = {"part": '"panel"', "part_placement": {"xyz_m": "[1.4, 0.0, 1.0]",
                                               "rpy_rad": "[0.0, 0.0, 0.0]"}}


def _toml(table: str, key: str, literal: str | None) -> str:
    """A minimal scenario file with `key = literal` in `table` (None: the key left out)."""
    top = {"part": _BASE["part"]}
    tables: dict[str, dict[str, str]] = {"part_placement": dict(_BASE["part_placement"])}
    if table == "part":
        top.pop("part")
        tables["part"] = {"file": '"part.stl"'}
    if literal is None:                          # left out, also of the minimal file
        (top if table == "" else tables.get(table, {})).pop(key, None)
    elif table == "":
        top[key] = literal
    else:
        tables.setdefault(table, {})[key] = literal
    lines = [f"{k} = {v}" for k, v in top.items()]
    for t, kv in tables.items():
        lines += [f"[{t}]", *(f"{k} = {v}" for k, v in kv.items())]
    return "\n".join(lines) + "\n"


def _write_and_load(tmp_path: Path, text: str) -> Any:
    f = tmp_path / "scn.toml"
    f.write_text(text, encoding="utf-8")
    return load_toml_scenario(f)


def _literal(cell: str) -> str | None:
    """The TOML literal of a Default cell (`0.04`), None for a default in words."""
    m = re.fullmatch(r"`(.*)`", cell.strip())
    return m.group(1) if m else None


def _documented(with_literal: bool) -> list[tuple[str, str, str]]:
    return [(t, k, row["default"]) for t, rows in DOC.items() for k, row in rows.items()
            if (_literal(row["default"]) is not None) == with_literal]


def test_the_reference_documents_every_table_and_describes_every_key() -> None:
    assert set(DOC) == {"", "part", "part_placement", "base", "planner", "fast_planner",
                        "trajectory", "servo", "disturbances", "thresholds", "spec", "sweep"}
    assert len(DOC["planner"]) > 30 and len(DOC["thresholds"]) > 8
    blank = [(t, k) for t, rows in DOC.items() for k, r in rows.items() if not r["doc"].strip()]
    assert not blank, f"keys without a description: {blank}"


@pytest.mark.parametrize(("table", "key", "default"), _documented(with_literal=True),
                         ids=lambda v: str(v))
def test_each_documented_default_is_accepted_and_is_the_default(
        tmp_path: Path, table: str, key: str, default: str) -> None:
    literal = _literal(default)
    assert literal is not None
    value = tomllib.loads(f"v = {literal}")["v"]
    _write_and_load(tmp_path, _toml(table, key, literal))      # accepted as written
    # ... and it is what the scenario gets without the key
    scn = _write_and_load(tmp_path, _toml(table, key, None))
    assert _effective(scn, table, key) == pytest.approx(value)


def _effective(scn: Any, table: str, key: str) -> Any:
    """What a scenario loaded without `key` runs with (tuples as lists)."""
    from paintcell.validation.settings_tables import settings_classes
    from paintcell.validation.sweep_spec import spec_from_scenario

    if table == "":
        v = getattr(scn, key)
    elif table in ("part_placement", "base"):
        v = getattr(getattr(scn, table), key)
    elif table == "part":
        v = getattr(scn.part, key)
    elif table in ("thresholds", "spec"):
        v = getattr(getattr(scn, table), key)
    elif table == "sweep":
        if key in ("factors", "limits", "workers"):   # none unless given; 2 local workers
            return scn.sweep.get(key, 2 if key == "workers" else {})
        spec = spec_from_scenario(scn.sweep, vary=["part_offset_m=0.001"])
        v = getattr(spec, key)
    else:
        v = getattr(settings_classes()[table](**getattr(scn, table)), key)
    return list(v) if isinstance(v, tuple) else v


def test_documented_words_for_defaults_are_true(tmp_path: Path) -> None:
    unset = [(t, k) for t, k, d in _documented(with_literal=False) if d == "*unset*"]
    assert ("thresholds", "max_abs_loss_pp") in unset and ("", "applicator") in unset
    scn = _write_and_load(tmp_path, _toml("", "name", None))
    assert DOC[""]["name"]["default"] == "*the file's stem*" and scn.name == "scn"
    for t, k in unset:                           # unset: the key has no value (None)
        scn = _write_and_load(tmp_path, _toml(t, k, None))
        if t == "sweep":
            assert k not in scn.sweep
            continue
        assert _effective(scn, t, k) is None, (t, k)


def test_required_keys_are_refused_when_missing(tmp_path: Path) -> None:
    required = [(t, k) for t, rows in DOC.items() for k, r in rows.items()
                if r["default"] == "*required*"]
    assert set(required) == {("", "part"), ("part", "file")}
    no_part = "[part_placement]\nxyz_m = [1.4, 0.0, 1.0]\nrpy_rad = [0.0, 0.0, 0.0]\n"
    no_file = '[part]\nunits = "m"\n' + no_part
    no_placement = 'part = "panel"\n'           # the section says the table is required
    assert "The table is required" in gen.scenario_reference()
    for text in (no_part, no_file, no_placement):
        with pytest.raises(ScenarioDataError):
            _write_and_load(tmp_path, text)


def _valid_keys(tmp_path: Path, table: str) -> set[str]:
    """The keys the loader's own error line names as valid for `table`."""
    with pytest.raises(ScenarioDataError) as exc:
        _write_and_load(tmp_path, _toml(table, "zz_not_a_key", "1"))
    m = re.search(r"valid(?: keys)?: (.*)$", str(exc.value))
    assert m, str(exc.value)
    return set(re.findall(r"[a-z_][a-z0-9_]*", m.group(1)))


@pytest.mark.parametrize("table", sorted(DOC))
def test_the_loader_accepts_exactly_the_documented_keys(tmp_path: Path, table: str) -> None:
    documented = set(DOC[table])
    if table == "":   # the top level also takes the tables
        documented |= set(DOC) - {""}
    assert _valid_keys(tmp_path, table) == documented


_INTERVAL = re.compile(r"`([\[(])(-?[\d.e+-]+|inf), (-?[\d.e+-]+|inf)([\])])`")


def _ranges() -> list[tuple[str, str, float, float, bool, bool]]:
    out = []
    for t, rows in DOC.items():
        for k, r in rows.items():
            m = _INTERVAL.search(r["valid"])
            if m:
                out.append((t, k, float(m[2]), float(m[3]), m[1] == "[", m[4] == "]"))
    return out


def test_ranges_are_documented() -> None:
    keys = {(t, k) for t, k, *_ in _ranges()}
    assert {("", "resolution_m"), ("planner", "u_max"), ("thresholds", "tolerance"),
            ("thresholds", "reachability_pct"), ("part", "fill_holes_m")} <= keys


def _accepted(tmp_path: Path, table: str, key: str, v: float) -> bool:
    literal = "inf" if v == math.inf else repr(v)
    if DOC[table][key]["kind"] == "integer" and math.isfinite(v) and v == int(v):
        literal = str(int(v))
    try:
        _write_and_load(tmp_path, _toml(table, key, literal))
    except PaintcellError:
        return False
    return True


@pytest.mark.parametrize(("table", "key", "lo", "hi", "lo_closed", "hi_closed"), _ranges(),
                         ids=lambda v: str(v))
def test_each_documented_range_is_the_loaders(tmp_path: Path, table: str, key: str, lo: float,
                                              hi: float, lo_closed: bool,
                                              hi_closed: bool) -> None:
    eps = 1e-9
    assert _accepted(tmp_path, table, key, lo) == lo_closed
    assert not _accepted(tmp_path, table, key, lo - max(eps, abs(lo) * 1e-6))
    step = 1.0 if DOC[table][key]["kind"] == "integer" else eps   # a count takes whole numbers
    inside = lo + step if math.isinf(hi) else lo + (hi - lo) * 0.5
    assert _accepted(tmp_path, table, key, inside)
    assert _accepted(tmp_path, table, key, hi) == hi_closed
    if math.isfinite(hi):
        assert not _accepted(tmp_path, table, key, hi + max(eps, abs(hi) * 1e-6))


@pytest.mark.parametrize(("table", "key"), [("part", "units"), ("sweep", "method"),
                                            ("", "robot")])
def test_documented_choices_are_accepted(tmp_path: Path, table: str, key: str) -> None:
    choices = [c.strip() for c in DOC[table][key]["valid"].split("\\|")]
    assert len(choices) >= 2
    for c in choices:
        _write_and_load(tmp_path, _toml(table, key, f'"{c}"'))
    if table != "":   # the loader leaves an unknown robot name to the robot catalog
        with pytest.raises(ScenarioDataError):
            _write_and_load(tmp_path, _toml(table, key, '"zz_not_a_choice"'))


# --- the command-line reference, read back ----------------------------------------------------

def _cli_doc() -> dict[str, dict[str, dict[str, str]]]:
    """{command: {first option or positional: row}}; internal options have value "internal"."""
    out: dict[str, dict[str, dict[str, str]]] = {}
    cmd = None
    row = re.compile(r"^\| (?P<flags>`[^|]*?)(?: \(required\))? \| (?P<value>[^|]*) \| "
                     r"(?P<default>[^|]*) \| (?P<help>.*) \|$")
    for line in gen.cli_reference().splitlines():
        m = re.match(r"^## (\w+)$", line)
        if m:
            cmd = m.group(1)
            out[cmd] = {}
        elif cmd and (r := row.match(line)):
            flags = re.findall(r"`([^`]+)`", r["flags"])
            out[cmd][flags[0]] = {**r.groupdict(), "flags": " ".join(flags),
                                  "required": str("(required)" in line)}
        elif cmd and line.startswith("Internal options"):
            for flag, value in re.findall(r"`(--[\w-]+) (\w+)`", line):
                out[cmd][flag] = {"flags": flag, "value": f"`{value}`", "default": "",
                                  "help": "internal", "required": "False"}
    return out


CLI = _cli_doc()


def _parse(argv: list[str]) -> Any:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            return build_parser().parse_args(argv)
        except SystemExit as exc:
            raise AssertionError(f"{argv} refused: {err.getvalue().strip()}") from exc


def _argv(cmd: str, skip: str = "") -> list[str]:
    """A command line of `cmd` with every positional and required option documented."""
    argv = [cmd]
    for name, r in CLI[cmd].items():
        if name == skip:
            continue
        value = _a_value(r)
        if not name.startswith("-"):
            if "…" not in r["value"]:
                argv.append(value or "x")
        elif r["required"] == "True":
            argv += [name, *([value] if value else [])]
    return argv


def _a_value(r: dict[str, str]) -> str:
    """A value for a documented argument other than its default ("" for a flag)."""
    value = r["value"].strip("` ")
    if not value:
        return ""
    default = r["default"].strip("` ")
    if value.startswith("{"):
        choices = value.strip("{}").split(",")
        return next(c for c in choices if c != default)
    m = re.search(r"\(choices: (.*)\)$", r["help"])
    if m:
        return next(c for c in re.findall(r"`([^`]+)`", m.group(1)) if c != default)
    said = re.search(r"\(default ([-+\d.e]+)\)", r["help"])   # a default the help states
    if said and default in ("", "None"):
        default = said.group(1)
    try:                 # a number other than the default, inside any range it documents
        d = float(default)
    except ValueError:
        return "3"
    if default.lstrip("-").isdigit():
        return str(int(d) + 1)
    return repr(d / 2) if d else "0.5"


def test_the_commands_are_the_documented_ones() -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    m = re.search(r"\{([\w,]+)\}", out.getvalue())
    assert m and m.group(1).split(",") == list(CLI)
    assert {"run", "check", "init", "inspect", "sweep"} <= set(CLI)


@pytest.mark.parametrize(("cmd", "option"),
                         [(c, o) for c, rows in CLI.items() for o in rows if o.startswith("-")])
def test_each_documented_option_parses_with_the_real_parser(cmd: str, option: str) -> None:
    r = CLI[cmd][option]
    value = _a_value(r)
    base = _argv(cmd, skip=option)
    with_it = vars(_parse([*base, option, *([value] if value else [])]))
    if r["required"] == "True":   # the command cannot be parsed without it
        with pytest.raises(AssertionError):
            _parse(base)
        changed = {k for k, v in with_it.items() if v is not None and v is not False}
        assert changed
        return
    without = vars(_parse(base))
    changed = {k for k in with_it if with_it[k] != without.get(k)}
    assert len(changed) == 1, (option, changed)
    default = r["default"].strip("` ")
    if default:   # the documented default is the parser's
        assert str(without[changed.pop()]) == default


def _help_options(cmd: str) -> set[str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        build_parser().parse_args([cmd, "--help"])
    found = set()
    section = ""
    for line in out.getvalue().splitlines():
        if line and not line.startswith(" "):
            section = line
        elif section.startswith(("options", "positional")) and re.match(r"^  \S", line):
            invocation = re.split(r"\s{2,}", line.strip())[0]   # the help text follows
            for part in invocation.split(", "):
                name = part.split()[0]
                found.add(name)
    return found - {"-h", "--help"}


@pytest.mark.parametrize("cmd", list(CLI))
def test_help_lists_exactly_the_documented_arguments(cmd: str) -> None:
    shown = _help_options(cmd)
    # a positional shows as its value: its metavar, its choices {a,b} or its name
    documented = {r["value"].strip("`").removesuffix(" …") if not f.startswith("-") else f
                  for r in CLI[cmd].values() if r["help"] != "internal"
                  for f in r["flags"].split()}
    assert shown == documented
    assert "--debug" in shown


# --- the strict build's own checks -------------------------------------------------------------

def test_a_blank_public_docstring_is_found(tmp_path: Path, monkeypatch: Any) -> None:
    hooks = _load("hooks")
    pkg = tmp_path / "paintcell_doc_probe"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""Probe package."""\n')
    (pkg / "m.py").write_text(textwrap.dedent('''\
        """A module."""


        def documented() -> None:
            """Has one."""


        def bare() -> None:
            pass


        def _private() -> None:
            pass


        class Thing:
            """A thing."""

            def method(self) -> None:
                pass

            @property
            def size_m(self) -> float:
                return 1.0
        '''))
    (pkg / "reexport.py").write_text(textwrap.dedent('''\
        """Names of m, one exported."""

        from paintcell_doc_probe.m import Thing, bare

        __all__ = ["Thing"]
        '''))
    monkeypatch.setattr(hooks, "ROOT", tmp_path)
    assert hooks.missing_docstrings("paintcell_doc_probe.m") == [
        "paintcell_doc_probe.m.Thing.method", "paintcell_doc_probe.m.Thing.size_m",
        "paintcell_doc_probe.m.bare"]
    # a page of the re-exporting module renders Thing (exported), not bare (only imported)
    assert hooks.missing_docstrings("paintcell_doc_probe.reexport") == [
        "paintcell_doc_probe.m.Thing.method", "paintcell_doc_probe.m.Thing.size_m"]


def test_the_api_pages_and_the_scenario_keys_are_documented() -> None:
    hooks = _load("hooks")
    modules = hooks.api_modules()
    assert "paintcell.app.pipeline" in modules and len(modules) >= 15
    blank = [p for m in modules for p in hooks.missing_docstrings(m)]
    assert not blank, f"public objects without a docstring: {blank}"
    assert hooks.undescribed_keys() == []


# --- the strict build itself (`make docs`, .ci/run) -----------------------------------------

def _mkdocs(config_dir: Path, out: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                          cwd=config_dir, env=env, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_the_site_builds_strictly_with_the_generated_pages(tmp_path: Path) -> None:
    r = _mkdocs(ROOT, tmp_path / "site")
    assert r.returncode == 0, r.stderr[-3000:]
    scenario = (tmp_path / "site" / "reference" / "scenario" / "index.html").read_text()
    assert "max_axis_turn_rad_m" in scenario and "max_abs_loss_pp" in scenario
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "--disturb" in cli and "--scheduler" in cli
    api = (tmp_path / "site" / "api" / "coverage" / "index.html").read_text()
    assert "plan_coverage" in api and "PlannerSettings" in api


@pytest.mark.slow
def test_a_broken_link_and_a_blank_docstring_fail_the_strict_build(tmp_path: Path) -> None:
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    shutil.copytree(ROOT / "docs", tmp_path / "docs",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for tree in ("paintcell", "scenarios"):     # the code and the example the pages read
        (tmp_path / tree).symlink_to(ROOT / tree)
    index = tmp_path / "docs" / "index.md"
    index.write_text(index.read_text() + "\nSee [the results](no_such_page.md).\n")
    api = tmp_path / "docs" / "api" / "app.md"      # a module whose function has no docstring
    (tmp_path / "paintcell_blank.py").write_text('"""A module."""\n\n\ndef bare() -> None:\n'
                                                 '    pass\n')
    api.write_text(api.read_text() + "\n::: paintcell_blank\n")
    r = _mkdocs(tmp_path, tmp_path / "site")
    assert r.returncode != 0
    said = r.stdout + r.stderr
    assert "contains a link 'no_such_page.md'" in said and "in strict mode" in said
    assert "paintcell_blank.bare has no docstring" in said


def test_docstring_entries_render_as_lists() -> None:
    fields = _load("griffe_fields")
    doc = textwrap.dedent("""\
        Settings (all SI).

        u_max: largest σ/μ [fraction].
        v_min_m_s / v_max_m_s: speed bounds
            of the QP [m/s].
        kp, kd: gains; a wrap at the margin
        carries on in lower case.
        A new paragraph: not an entry.

            code(x): indented, kept
        """)
    assert fields.as_lists(doc).splitlines() == [
        "Settings (all SI).", "",
        "- `u_max`: largest σ/μ [fraction].",
        "- `v_min_m_s`, `v_max_m_s`: speed bounds", "  of the QP [m/s].",
        "- `kp`, `kd`: gains; a wrap at the margin", "  carries on in lower case.", "",
        "A new paragraph: not an entry.", "", "    code(x): indented, kept"]


def test_the_example_on_the_scenario_page_loads(tmp_path: Path) -> None:
    text = gen.scenario_reference()
    m = re.search(r"```toml\n(.*?)\n```", text, re.S)
    assert m, "the scenario reference shows no example"
    scn = _write_and_load(tmp_path, m.group(1) + "\n")
    assert scn.part == "panel" and scn.thresholds.max_collisions == 0
