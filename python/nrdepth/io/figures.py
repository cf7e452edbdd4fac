"""Pictures with words: a mosaic of frames and depth maps (uint8 RGB, laid
out by the caller) given column titles, a title and a colour bar with values
and units by matplotlib, rendered back to a uint8 RGB array so that callers
keep writing PNGs as before (:func:`nrdepth.engine.preview.save_png`).

The mosaic is drawn at one screen pixel per image pixel (no resampling);
the colour bar uses the same ramp as :func:`nrdepth.io.colorize_depth`
(near = small depth = yellow, far = blue).
"""

from __future__ import annotations

from typing import NamedTuple, Optional, Sequence

import numpy as np

from .colours import COLOURS

__all__ = ["ColourBar", "labelled"]

DPI = 100


class ColourBar(NamedTuple):
    """A depth colour bar: the value range the mosaic's colours span, and its label (with units)."""

    lo: float
    hi: float
    label: str = "depth"


def labelled(image: np.ndarray, titles: Sequence[str], cell_width: int, colour_bar: Optional[ColourBar] = None,
             title: Optional[str] = None) -> np.ndarray:
    """``image`` (H, W, 3) uint8 under ``titles``, one per column of
    ``cell_width`` pixels, with an optional ``title`` above and
    ``colour_bar`` on the right: uint8 RGB, at least as large as ``image``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize
    from matplotlib.figure import Figure

    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"image: expected uint8 (H, W, 3), got {image.dtype} {image.shape}")
    h, w = image.shape[:2]
    top = 26 + (22 if title else 0)
    right = 110 if colour_bar else 8
    fig = Figure(figsize=((w + right + 8) / DPI, (h + top + 8) / DPI), dpi=DPI)
    FigureCanvasAgg(fig)
    W, H = w + right + 8, h + top + 8
    ax = fig.add_axes((8 / W, 8 / H, w / W, h / H))
    ax.imshow(image, interpolation="nearest")
    ax.set_axis_off()
    size = 9 if cell_width >= 90 else 7
    for k, name in enumerate(titles):
        ax.text((k + 0.5) * cell_width, -6, name, ha="center", va="bottom", fontsize=size, clip_on=False, wrap=True)
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 4 / H, va="top")
    if colour_bar:
        cax = fig.add_axes(((w + 24) / W, 8 / H + 0.1 * h / H, 14 / W, 0.8 * h / H))
        # colorize_depth maps hi (far) to ramp 0 and lo (near) to the ramp's end.
        ramp = ListedColormap(COLOURS[::-1] / 255.0)
        bar = fig.colorbar(ScalarMappable(Normalize(colour_bar.lo, colour_bar.hi), ramp), cax=cax)
        bar.set_label(colour_bar.label, fontsize=8)
        bar.ax.tick_params(labelsize=7)
        bar.ax.invert_yaxis()  # near at the top, as it reads in the pictures: yellow up
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def frame_rows(columns: list, titles: list, colour_bar: Optional[ColourBar] = None, frames_shown: int = 4) -> np.ndarray:
    """Rows of frames under column titles, with a depth colour bar when the
    depth columns share one range; each column a (T, H, W, 3) uint8 video."""
    t = len(columns[0])
    rows = []
    for k in np.linspace(0, t - 1, frames_shown).round().astype(int):
        rows.append(np.concatenate([np.pad(c[k], ((2, 2), (2, 2), (0, 0)), constant_values=255) for c in columns], axis=1))
    return labelled(np.concatenate(rows, axis=0), titles, columns[0].shape[2] + 4, colour_bar=colour_bar)


def gray_rgb(video: np.ndarray) -> np.ndarray:
    """Gray frames (…, H, W) as RGB (…, H, W, 3)."""
    return np.repeat(video[..., None], 3, axis=-1)
