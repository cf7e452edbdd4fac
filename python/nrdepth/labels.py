"""Words and colour bars on pictures, without a font library: a 5×7 pixel
font (lower case, digits, a little punctuation), drawn at an integer scale.

    picture = titled(picture, ["frames", "ground truth", "nrdepth"], cell_width)
    picture = with_colour_bar(picture, "near", "far")
"""

from __future__ import annotations

from typing import Dict, Sequence

import numpy as np

__all__ = ["text", "titled", "with_colour_bar"]

# Each glyph: 7 rows of 5 pixels, '#' on.
_GLYPHS: Dict[str, str] = {
    "a": ".....|.....|.###.|....#|.####|#...#|.####", "b": "#....|#....|####.|#...#|#...#|#...#|####.",
    "c": ".....|.....|.###.|#....|#....|#...#|.###.", "d": "....#|....#|.####|#...#|#...#|#...#|.####",
    "e": ".....|.....|.###.|#...#|#####|#....|.###.", "f": "..##.|.#..#|.#...|###..|.#...|.#...|.#...",
    "g": ".....|.....|.####|#...#|.####|....#|.###.", "h": "#....|#....|#.##.|##..#|#...#|#...#|#...#",
    "i": "..#..|.....|.##..|..#..|..#..|..#..|.###.", "j": "...#.|.....|..##.|...#.|...#.|#..#.|.##..",
    "k": "#....|#....|#..#.|#.#..|##...|#.#..|#..#.", "l": ".##..|..#..|..#..|..#..|..#..|..#..|.###.",
    "m": ".....|.....|##.#.|#.#.#|#.#.#|#...#|#...#", "n": ".....|.....|#.##.|##..#|#...#|#...#|#...#",
    "o": ".....|.....|.###.|#...#|#...#|#...#|.###.", "p": ".....|.....|####.|#...#|####.|#....|#....",
    "q": ".....|.....|.##.#|#..##|.####|....#|....#", "r": ".....|.....|#.##.|##..#|#....|#....|#....",
    "s": ".....|.....|.###.|#....|.###.|....#|####.", "t": ".#...|.#...|###..|.#...|.#...|.#..#|..##.",
    "u": ".....|.....|#...#|#...#|#...#|#..##|.##.#", "v": ".....|.....|#...#|#...#|#...#|.#.#.|..#..",
    "w": ".....|.....|#...#|#...#|#.#.#|#.#.#|.#.#.", "x": ".....|.....|#...#|.#.#.|..#..|.#.#.|#...#",
    "y": ".....|.....|#...#|#...#|.####|....#|.###.", "z": ".....|.....|#####|...#.|..#..|.#...|#####",
    "0": ".###.|#...#|#..##|#.#.#|##..#|#...#|.###.", "1": "..#..|.##..|..#..|..#..|..#..|..#..|.###.",
    "2": ".###.|#...#|....#|...#.|..#..|.#...|#####", "3": "#####|...#.|..#..|...#.|....#|#...#|.###.",
    "4": "...#.|..##.|.#.#.|#..#.|#####|...#.|...#.", "5": "#####|#....|####.|....#|....#|#...#|.###.",
    "6": "..##.|.#...|#....|####.|#...#|#...#|.###.", "7": "#####|....#|...#.|..#..|.#...|.#...|.#...",
    "8": ".###.|#...#|#...#|.###.|#...#|#...#|.###.", "9": ".###.|#...#|#...#|.####|....#|...#.|.##..",
    " ": ".....|.....|.....|.....|.....|.....|.....", "-": ".....|.....|.....|#####|.....|.....|.....",
    ".": ".....|.....|.....|.....|.....|.##..|.##..", ",": ".....|.....|.....|.....|.##..|..#..|.#...",
    "(": "...#.|..#..|.#...|.#...|.#...|..#..|...#.", ")": ".#...|..#..|...#.|...#.|...#.|..#..|.#...",
    "/": ".....|....#|...#.|..#..|.#...|#....|.....", ":": ".....|.##..|.##..|.....|.##..|.##..|.....",
    "=": ".....|.....|#####|.....|#####|.....|.....", "+": ".....|..#..|..#..|#####|..#..|..#..|.....",
}
_BITMAPS = {c: np.array([[ch == "#" for ch in row] for row in g.split("|")]) for c, g in _GLYPHS.items()}


def text(words: str, scale: int = 2) -> np.ndarray:
    """``words`` as a bool mask (7·scale, 6·scale·len): lower case, digits and
    `` -.,()/:=+``; upper case is drawn lower case, anything else as a space."""
    glyphs = [_BITMAPS.get(c, _BITMAPS[" "]) for c in words.lower()]
    if not glyphs:
        return np.zeros((7 * scale, 0), bool)
    spaced = [np.pad(g, ((0, 0), (0, 1))) for g in glyphs]
    return np.kron(np.concatenate(spaced, axis=1), np.ones((scale, scale), bool)).astype(bool)


def _stamp(canvas: np.ndarray, mask: np.ndarray, top: int, left: int, colour=(0, 0, 0)) -> None:
    h, w = mask.shape
    h, w = min(h, canvas.shape[0] - top), min(w, canvas.shape[1] - left)
    region = canvas[top : top + h, left : left + w]
    region[mask[:h, :w]] = colour


def titled(picture: np.ndarray, titles: Sequence[str], cell_width: int, scale: int = 2) -> np.ndarray:
    """The picture (H, W, 3) uint8 under a white band holding one title
    centred over each column of ``cell_width`` pixels; a title wider than its
    column is wrapped at spaces, and drawn smaller if a word still does not
    fit."""
    blocks = [_wrapped(title, cell_width, scale) for title in titles]
    band = np.full((max(b.shape[0] for b in blocks) + 8, picture.shape[1], 3), 255, np.uint8)
    for k, mask in enumerate(blocks):
        left = max(k * cell_width + (cell_width - mask.shape[1]) // 2, k * cell_width)
        _stamp(band, mask[:, :cell_width], 4, left)
    return np.concatenate([band, picture], axis=0)


def _wrapped(title: str, width: int, scale: int) -> np.ndarray:
    """``title`` as lines no wider than ``width`` at the largest scale up to
    ``scale`` where every word fits (scale 1 at least): a bool mask."""
    words = title.split(" ")
    while scale > 1 and max(text(w, scale).shape[1] for w in words) > width:
        scale -= 1
    lines = [words[0]]
    for word in words[1:]:
        if text(f"{lines[-1]} {word}", scale).shape[1] <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    masks = [text(line, scale) for line in lines]
    block = np.zeros((len(masks) * 8 * scale - scale, max(m.shape[1] for m in masks)), bool)  # a blank row of scale between lines
    for i, m in enumerate(masks):
        offset = (block.shape[1] - m.shape[1]) // 2
        block[i * 8 * scale : i * 8 * scale + 7 * scale, offset : offset + m.shape[1]] = m
    return block


def with_colour_bar(picture: np.ndarray, low: str, high: str, ramp=None, scale: int = 2) -> np.ndarray:
    """The picture with a vertical colour bar on its right: ``high``'s colour
    at the top (labelled ``high``), ``low``'s at the bottom. ``ramp`` maps
    values in [0, 1] to RGB floats (default: nrdepth's depth colours)."""
    if ramp is None:
        from .preview import colormap as ramp
    height = picture.shape[0]
    width = max(text(low, scale).shape[1], text(high, scale).shape[1], 16) + 8
    bar = np.full((height, width, 3), 255, np.uint8)
    label = 7 * scale + 4
    values = np.linspace(1.0, 0.0, max(height - 2 * label, 2))
    colours = (np.asarray(ramp(values)) * 255 + 0.5).astype(np.uint8)
    bar[label : label + len(values), 4:20] = colours[:, None, :]
    _stamp(bar, text(high, scale), 2, 4)
    _stamp(bar, text(low, scale), height - label + 2, 4)
    return np.concatenate([picture, bar], axis=1)
