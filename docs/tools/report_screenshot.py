"""Open a `report.html` in headless Chromium: console errors, first-screen layout, screenshot.

    python docs/tools/report_screenshot.py [REPORT_HTML] [--png docs/img/report_first_screen.png]

Without REPORT_HTML it runs `paintcell run scenarios/door.toml --fast` into a temporary folder
first (a few minutes). docs/img/report_first_screen.png is made this way. Needs the `dev` extra
(playwright) and a Chromium: playwright's own (`python -m playwright install chromium`) or the
system's (`apt-get install chromium`; found on PATH as chromium, chromium-browser or
google-chrome, or named by $PAINTCELL_CHROMIUM). `tests/test_report_browser.py` uses
`inspect_report`.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
VIEWPORT = (1280, 800)
#: elements of the first screen (paintcell.output.report_sections ids).
FIRST_SCREEN = ("#verdict", "#film-map", "#film-histogram", "#pass-table")
#: Chromium flags: WebGL (the report's 3-D film view) on SwiftShader, the software GPU Chromium
#: ships, so a headless run draws the same with or without a GPU and its driver's performance
#: messages do not reach the console.
CHROMIUM_ARGS = ("--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader")


def find_chromium() -> str | None:
    """Path of a system Chromium, or None (then playwright's own browser is tried)."""
    env = os.environ.get("PAINTCELL_CHROMIUM")
    if env:
        return env
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def inspect_report(html_path: str | Path, png: str | Path | None = None,
                   viewport: tuple[int, int] = VIEWPORT) -> dict[str, Any]:
    """Load the page in headless Chromium at `viewport` [px]; return what a test checks.

    Returns {"console": [(type, text)] of console messages and page errors, "boxes": {selector:
    bounding box dict or None}, "texts": {selector: inner text}, "images_ok": {selector: True
    when its <img> decoded (naturalWidth > 0)}, "pass_rows": rows of the pass table}; writes a
    screenshot of the first screen to `png` when given.
    """
    from playwright.sync_api import Error, sync_playwright

    exe = find_chromium()
    with sync_playwright() as p:
        try:
            browser = p.chromium.launch(executable_path=exe, args=list(CHROMIUM_ARGS))
        except Error as e:
            raise RuntimeError("no headless Chromium: `apt-get install chromium` or "
                               f"`python -m playwright install chromium` ({str(e)[:200]})") from e
        try:
            page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
            console: list[tuple[str, str]] = []
            page.on("console", lambda m: console.append((m.type, m.text)))
            page.on("pageerror", lambda e: console.append(("pageerror", str(e))))
            page.goto(Path(html_path).resolve().as_uri(), wait_until="load")
            boxes = {s: page.locator(s).first.bounding_box() for s in FIRST_SCREEN}
            texts = {s: page.locator(s).first.inner_text() for s in FIRST_SCREEN
                     + ("#inside-pct",)}
            images_ok = {s: bool(page.evaluate(
                f"() => {{ const i = document.querySelector('{s} img');"
                " return i !== null && i.complete && i.naturalWidth > 0; }"))
                for s in ("#film-map", "#film-histogram")}
            n_rows = page.locator("#pass-table tbody tr").count()
            if png is not None:
                Path(png).parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(png))
        finally:
            browser.close()
    return {"console": console, "boxes": boxes, "texts": texts, "images_ok": images_ok,
            "pass_rows": n_rows}


def run_door(out: Path) -> Path:
    """`paintcell run scenarios/door.toml --fast --out OUT`; return OUT/report.html."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "paintcell", "run", "scenarios/door.toml",
                           "--fast", "--out", str(out)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=1200)
    if proc.returncode not in (0, 1):  # 1: a threshold failed; the report is still written
        raise RuntimeError(f"door run failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return out / "report.html"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("report", nargs="?", type=Path,
                    help="report.html to open (default: run the door scenario at --fast first)")
    ap.add_argument("--png", type=Path, default=ROOT / "docs/img/report_first_screen.png",
                    help="where to write the first-screen screenshot (1280×800 px)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        html_path = args.report or run_door(Path(tmp) / "door")
        r = inspect_report(html_path, args.png)
        size_mb = Path(html_path).stat().st_size / 1e6
    print(f"screenshot: {args.png}")
    for sel, box in r["boxes"].items():
        print(f"{sel}: {box}")
    print(f"console messages: {len(r['console'])} {r['console'][:5]}")
    print(f"report size: {size_mb:.2f} MB")
    return 1 if any(t in ("error", "pageerror") for t, _ in r["console"]) else 0


if __name__ == "__main__":
    raise SystemExit(main())
