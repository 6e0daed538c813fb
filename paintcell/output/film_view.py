"""The report's interactive 3-D view of `film.glb`: rotate, zoom, hover for the film in µm.

`film_view_html` returns one HTML section that works offline from the single report file: the
GLB embedded as base64 text, three.js (r187: WebGL renderer, glTF loader, orbit controls) as one
minified script vendored under `paintcell/output/viewer/` with its MIT licence (`README.md`
there says how the bundle is rebuilt), and the view's own script `viewer/film_view.js`. The
legend is the spec colour scale of `paintcell.output.report_film` over its colour range, with the
spec window's limits marked. About 0.65 MB of script plus 4/3 of the GLB's size.
"""

from __future__ import annotations

import base64
import html
from functools import cache
from pathlib import Path

import numpy as np

from paintcell.core.safe_paths import read_regular_bytes
from paintcell.output.report_film import FilmData, spec_range_um, spec_rgb

__all__ = ["THREE_BUNDLE", "VIEW_SCRIPT", "film_view_html"]

_HERE = Path(__file__).resolve().parent / "viewer"
THREE_BUNDLE = _HERE / "three-film.min.js"
VIEW_SCRIPT = _HERE / "film_view.js"
# Legend gradient stops: enough that the three thirds of the scale read as they are drawn.
_LEGEND_STOPS = 31

_CSS = """
.film-3d { position: relative; max-width: 1000px; }
.film-3d canvas { width: 100%; height: 520px; display: block; border: 1px solid #ddd;
                  cursor: grab; touch-action: none; }
.film-tip { position: absolute; pointer-events: none; background: rgba(0,0,0,0.78);
            color: #fff; padding: 2px 6px; border-radius: 3px; font-size: 0.85em; }
.film-legend { display: flex; align-items: center; gap: 8px; margin: 0.3em 0; font-size: 0.85em; }
.film-legend .bar { width: 360px; height: 14px; border: 1px solid #999; }
.film-3d button { margin-right: 4px; }
"""


@cache
def _script(path: Path) -> str:
    text = path.read_text(encoding="utf-8")
    if "</script" in text.lower():  # would end the inline <script> early
        raise ValueError(f"{path} holds '</script'; it cannot be inlined in report.html")
    return text


def _hex(rgb: np.ndarray) -> list[str]:
    return ["#" + "".join(f"{round(255 * c):02x}" for c in row) for row in rgb]


def legend_html(film: FilmData) -> str:
    """The colour bar of the 3-D view: the spec scale over its range [µm], the window marked."""
    target_um = 1e6 * film.target_m
    lo, hi = spec_range_um(target_um, film.tolerance)
    t_m = 1e-6 * np.linspace(lo, hi, _LEGEND_STOPS)
    stops = ", ".join(_hex(spec_rgb(t_m, target_um, film.tolerance)))
    w_lo, w_hi = (1e6 * x for x in film.window_m)
    return (f'<div class="film-legend"><span>{lo:.1f} µm</span>'
            f'<span class="bar" style="background: linear-gradient(to right, {stops})"></span>'
            f'<span>{hi:.1f} µm</span><span>— spec window {w_lo:.1f}–{w_hi:.1f} µm (green), '
            "blue thinner, red thicker</span></div>")


def film_view_html(glb: Path, film: FilmData | None, ident: str = "film-3d") -> str:
    """The 3-D view section of `glb` (a `film.glb`); `film` gives the legend (None: none).

    ident: the section's HTML id (the embedded data's id is derived from it)."""
    data = base64.b64encode(read_regular_bytes(Path(glb))).decode("ascii")
    legend = legend_html(film) if film is not None else ""
    return (
        f"<style>{_CSS}</style>"
        f'<section class="film-3d" id="{html.escape(ident)}" data-glb="{html.escape(ident)}-glb">'
        "<p>The executed film on the part, the passes (black lines, the bell's path) and the "
        "robot base (orange cone). Drag to rotate, scroll to zoom, right-drag to pan; point at "
        "the part for the film there. The same scene is <code>film.glb</code> in the results "
        "folder (glTF 2.0: Blender, any glTF viewer).</p>"
        '<p><button type="button" data-view="part">part</button>'
        '<button type="button" data-view="cell">whole cell</button></p>'
        f"{legend}"
        '<canvas aria-label="3-D view of the executed film"></canvas>'
        '<div class="film-tip" hidden></div><p class="film-status">loading the 3-D view…</p>'
        "</section>\n"
        f'<script type="application/octet-stream" id="{html.escape(ident)}-glb">{data}</script>\n'
        f"<script>{_script(THREE_BUNDLE)}</script>\n<script>{_script(VIEW_SCRIPT)}</script>\n")
