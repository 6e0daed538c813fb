"""Images and videos on disk: PNG, GIF/MP4 (atomic writes), and the film-thickness legend [µm].

Images are (H, W, 3|4) uint8 arrays; frame rates in frames per second [1/s].
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

from paintcell.core.atomic_io import atomic_path
from paintcell.output.render_backend import RenderError
from paintcell.output.render_film import DEFAULT_CMAP, colormap_rgb


def _check_image(image: npt.ArrayLike) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.size == 0:
        raise RenderError(f"image must be (H, W, 3|4), got shape {img.shape}")
    if img.dtype != np.uint8:
        raise RenderError(f"image must be uint8, got {img.dtype}")
    return img


def _readable(path: Path) -> Path:
    from paintcell.output.plots import readable

    return readable(path)


def write_png(path: str | os.PathLike[str], image: npt.ArrayLike) -> Path:
    """Write an (H, W, 3|4) uint8 image as PNG atomically; returns the path."""
    img = _check_image(image)
    path = Path(path)
    with atomic_path(path) as tmp:
        Image.fromarray(img).save(tmp, format="PNG")
    return _readable(path)


def write_video(path: str | os.PathLike[str], frames: Sequence[np.ndarray] | Iterable[np.ndarray],
                fps: float = 10.0) -> Path:
    """Write frames ((H, W, 3) uint8 each) at `fps` [1/s] as `.gif` (Pillow) or `.mp4`
    (needs imageio + imageio-ffmpeg); atomic; returns the path."""
    frames = [_check_image(f)[:, :, :3] for f in frames]
    if not frames:
        raise RenderError("a video needs at least one frame")
    if fps <= 0:
        raise RenderError(f"fps must be > 0, got {fps}")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        # One palette for the whole clip, from a montage of up to 8 frames: 10× faster than a
        # palette per frame, and no colour flicker between frames.
        sample = frames[::max(1, len(frames) // 8)][:8]
        pal = Image.fromarray(np.concatenate(sample, axis=0)).quantize(
            colors=255, method=Image.Quantize.MEDIANCUT)
        pil = [Image.fromarray(f).quantize(palette=pal, dither=Image.Dither.NONE)
               for f in frames]
        with atomic_path(path) as tmp:
            pil[0].save(tmp, format="GIF", save_all=True, append_images=pil[1:],
                        duration=max(int(round(1000.0 / fps)), 20), loop=0, optimize=False)
        return _readable(path)
    if suffix == ".mp4":
        try:
            import imageio.v2 as imageio  # type: ignore[import-not-found]
        except ImportError as e:
            raise RenderError("MP4 needs imageio and imageio-ffmpeg (pip install imageio "
                              "imageio-ffmpeg); or write a .gif") from e
        with atomic_path(path) as tmp:
            imageio.mimsave(tmp, cast(Any, frames), fps=fps, macro_block_size=1)
        return _readable(path)
    raise RenderError(f"unknown video format {path.suffix!r}: use .gif or .mp4")


def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """DejaVu Sans from matplotlib (has the µ glyph), else Pillow's default font."""
    from matplotlib import get_data_path

    ttf = Path(get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"
    try:
        return ImageFont.truetype(str(ttf), size_px)
    except OSError:
        return ImageFont.load_default(size_px)


def add_colorbar(image: npt.ArrayLike, vmin_um: float, vmax_um: float,
                 cmap: str = DEFAULT_CMAP) -> np.ndarray:
    """Return a copy of `image` (H, W, 3) with a film-thickness legend [µm] drawn over its right
    edge (same size as the input)."""
    img = _check_image(image)[:, :, :3]
    h, w = img.shape[:2]
    font = _font(max(h // 32, 8))
    bar_w, pad = max(w // 48, 5), max(w // 100, 2)
    labels = [f"{v:.3g}" for v in (vmin_um, 0.5 * (vmin_um + vmax_um), vmax_um)]
    text_w = int(max(font.getlength(t) for t in labels + ["[µm]"]))
    panel_w = min(bar_w + text_w + 4 * pad, w // 3)
    out = Image.fromarray(np.ascontiguousarray(img))
    draw = ImageDraw.Draw(out)
    x0 = w - panel_w
    draw.rectangle([x0, 0, w - 1, h - 1], fill=(255, 255, 255))
    top, bottom = int(0.12 * h), int(0.9 * h)
    colours = colormap_rgb(cmap, max(bottom - top, 2))[::-1]  # high values on top
    strip = np.repeat(colours[:, None, :], bar_w, axis=1)
    out.paste(Image.fromarray(np.ascontiguousarray(strip)), (x0 + pad, top))
    for frac, text in zip((0.0, 0.5, 1.0), labels, strict=True):
        y = int(bottom - frac * (bottom - top))
        draw.line([(x0 + pad + bar_w, y), (x0 + 2 * pad + bar_w, y)], fill=(0, 0, 0))
        draw.text((x0 + 2 * pad + bar_w, y), text, fill=(0, 0, 0), font=font, anchor="lm")
    draw.text((x0 + panel_w // 2, top // 2), "[µm]", fill=(0, 0, 0), font=font, anchor="mm")
    return np.asarray(out)
