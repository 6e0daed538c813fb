"""The product speaks of the software and the parts, never of its own making: no tracker
numbers, no work-period names, no "this change" comparisons and no commit hashes in the package,
the tests, the benchmarks, the docs, the scenarios or the README. History belongs in
CHANGELOG.md and the commit messages.

The scanner is run on planted files too, so a pattern that stopped matching would fail here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: What is scanned (relative to the repository root); CHANGELOG.md and .git are not.
SCANNED = ("paintcell", "tests", "benchmarks", "docs", "scenarios", "README.md")

#: Binary data that holds no words.
SKIP_SUFFIXES = {".png", ".gif", ".jpg", ".npz", ".npy", ".ply", ".stl", ".obj", ".step",
                 ".stp", ".iges", ".igs", ".glb", ".pyc", ".so", ".whl"}

#: Third-party code vendored as it was built (three.js names its own WebXR terms).
VENDORED = {"paintcell/output/viewer/three-film.min.js"}

#: (name, pattern): each pattern is written so that its own source text does not match it.
PATTERNS = (
    ("tracker number", re.compile(r"\bissues?[\s_-]*\d+", re.I)),
    ("tracker number", re.compile(r"\bissue[\s_-]*#", re.I)),
    ("work stop", re.compile(r"\bstop[\s_-]*\d+\b(?!\s*(?:mm|cm|m|ms|s|%|°|rad|deg))", re.I)),
    ("work period", re.compile(r"\bsess(?:ion)s?\b", re.I)),
    ("this-change comparison", re.compile(r"\b(?:before|after)\s+this\s+change\b", re.I)),
    # 7-40 lower-case hex digits with a letter and a digit, standing alone: not a decimal's
    # mantissa (after '.'), not a float exponent (before '-'/'+'), not part of a longer word.
    ("commit hash", re.compile(
        r"(?<![\w.#/-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w.+-])")),
)


def scan_text(text: str) -> list[tuple[int, str, str]]:
    """Every (line number, kind, matched text) of a project-history word in `text`."""
    hits = []
    for n, line in enumerate(text.splitlines(), 1):
        for kind, pat in PATTERNS:
            hits += [(n, kind, m.group(0)) for m in pat.finditer(line)]
    return hits


def scan_tree(root: Path, names: tuple[str, ...] = SCANNED) -> list[str]:
    """'path:line: kind "text"' for every hit in the text files under `names` of `root`."""
    out = []
    for name in names:
        base = root / name
        files = [base] if base.is_file() else sorted(p for p in base.rglob("*") if p.is_file())
        for p in files:
            if p.suffix.lower() in SKIP_SUFFIXES or "__pycache__" in p.parts \
                    or p.relative_to(root).as_posix() in VENDORED:
                continue
            data = p.read_bytes()
            if b"\0" in data:
                continue
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                continue
            out += [f"{p.relative_to(root)}:{n}: {kind} {word!r}"
                    for n, kind, word in scan_text(text)]
    return out


def test_no_project_history_words_in_the_product() -> None:
    hits = scan_tree(ROOT)
    assert not hits, f"{len(hits)} project-history words:\n" + "\n".join(hits[:60])


# Planted words, assembled so that this file's own text holds none of them.
PLANTED = [
    ("as asked in " + "issue" + " 12", "tracker number"),
    ("the " + "Iss" + "ue-3" + " bell", "tracker number"),
    ("bells/" + "issue" + "3_bell.toml", "tracker number"),
    ("measured at " + "stop" + " 4", "work stop"),
    ("the third " + "ses" + "sion's plan", "work period"),
    ("slower " + "before" + " this change", "this-change comparison"),
    ("After " + "this" + " change it passes", "this-change comparison"),
    ("baseline main " + "e91b" + "23d", "commit hash"),
    ("merged in " + ("0a1b" + "2c3d") * 5, "commit hash"),
]

#: Text that reads like a hit but is not one.
CLEAN = [
    "rates 1.0208690299958306e-05 and 2.2720e-5 m/s",
    "doi 10.1108/ir.2008.04935baf.005",
    "the tissue 3 times; a " + "stop" + " 40 mm short of the edge",   # a length, not a stop
    "colour #1f77b4; bytes 0xdeadbeef; the facade",
    "sha256 " + "ab" * 32,
    "the bell stops 40 mm short; issues of uniformity",
]


@pytest.mark.parametrize(("line", "kind"), PLANTED)
def test_scanner_finds_a_planted_word(tmp_path: Path, line: str, kind: str) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "page.md").write_text(f"# A page\n\nclean line\n{line}\n")
    (tmp_path / "clean.toml").write_text("name = 'x'\n")
    hits = scan_tree(tmp_path, ("docs", "clean.toml"))
    assert len(hits) == 1, hits
    assert hits[0].startswith("docs/page.md:4: " + kind), hits


def test_scanner_passes_clean_text(tmp_path: Path) -> None:
    (tmp_path / "notes.md").write_text("\n".join(CLEAN) + "\n")
    (tmp_path / "data.npz").write_bytes(b"issue" + b" 7\0binary")   # binary: not read
    assert scan_tree(tmp_path, ("notes.md", "data.npz")) == []
