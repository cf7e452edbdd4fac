"""A depth video in 3-D, in one self-contained HTML page.

The page shows each depth video as a surface mesh (plotly.js's WebGL
``surface``, embedded in the page: it works from ``file://`` with the
browser offline), draped with its video frame in grey or coloured by
depth, with plotly's orbit, zoom and pan, a time slider, play/pause at the
video's frame rate, and controls for the relief's exaggeration and the
colouring. The depth range and the exaggeration are fixed once for the
whole video, so one frame's shape compares with the next.

Why plotly: its offline HTML embeds plotly.js (4.8 MB), a well-kept WebGL
surface with orbit controls built in; the page's own script only decodes
the frames and swaps them into the surface (``Plotly.restyle``), so a
scrub redraws one mesh of at most :data:`SIDE` vertices a side. The mesh is
decimated for display (block means) and, for long videos, every k-th frame
kept so that the page holds at most :data:`SAMPLES` vertex-frames; the page
says so. The data stay at full resolution in ``depth.npz``. Depth is
stored as int16 over the video's range and the grey as uint8, base64 in
the page: a 1920×1080×300 reconstruction is a page of about 17 MB. NaN
depth (off the surface: ``reconstruct``'s ``mask``) is a hole in the mesh,
and the scene's extent stays that of the frame.

:class:`ViewerFrames` gathers the decimated frames a chunk at a time (the
streaming writer feeds it); :func:`view` writes a page from arrays or a
reconstruction folder.
"""

from __future__ import annotations

import base64
import json
import math
import os
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..checks import option_error
from .decode import iter_npz_frames, read_left_half

__all__ = ["view", "ViewerFrames", "write_page", "SIDE", "SAMPLES"]

SIDE = 128
"""Mesh vertices along the longer side of a frame, at most."""
SAMPLES = 3_000_000
"""Vertex-frames a page holds at most; longer videos keep every k-th frame."""
HOLE = -32768
"""The int16 depth of a vertex off the surface (NaN): the page leaves a hole there."""
FULL_RESOLUTION = "The depth at full resolution: depth.npz."
RELIEF = 0.073
"""The surface's depth standard deviation in frame widths at exaggeration 1
(the training surfaces' median, as ``nrdepth.io.PLY_RELIEF``)."""

PathLike = Union[str, "os.PathLike[str]"]


def _block_mean(frames: np.ndarray, step: int) -> np.ndarray:
    """(n, H, W) → (n, ⌈H/step⌉, ⌈W/step⌉) block means (edge blocks partial)
    of the values that are not NaN; NaN where a block has none."""
    n, h, w = frames.shape
    hh, ww = -(-h // step) * step, -(-w // step) * step
    padded = np.pad(frames.astype(np.float32), ((0, 0), (0, hh - h), (0, ww - w)), mode="edge")
    blocks = padded.reshape(n, hh // step, step, ww // step, step)
    if not np.isnan(padded).any():
        return blocks.mean(axis=(2, 4))
    on = ~np.isnan(blocks)
    count = on.sum(axis=(2, 4))
    total = np.where(on, blocks, np.float32(0)).sum(axis=(2, 4))
    return np.where(count > 0, total / np.maximum(count, 1), np.float32(np.nan)).astype(np.float32)


class ViewerFrames:
    """The frames of one depth video (and optionally its grey video) as the
    page shows them, gathered a chunk at a time: a video of ``shape`` (T,
    H, W) is decimated to at most :data:`SIDE` vertices a side by block
    means, and every ``keep``-th frame is kept so that the page holds at
    most :data:`SAMPLES` vertex-frames."""

    def __init__(self, shape: Tuple[int, int, int], side: int = SIDE, samples: int = SAMPLES) -> None:
        t, h, w = shape
        self.shape = (t, h, w)
        self.step = max(1, math.ceil(max(h, w) / side))
        self.mesh = (-(-h // self.step), -(-w // self.step))
        self.keep = max(1, math.ceil(t * self.mesh[0] * self.mesh[1] / samples))
        self.depth: List[np.ndarray] = []
        self.grey: List[np.ndarray] = []
        self.seen = 0

    def add(self, depth: np.ndarray, grey: Optional[np.ndarray] = None) -> None:
        """The next frames: float depth (n, H, W), finite or NaN (no surface), and uint8 grey (n, H, W) or None."""
        infinite = np.isinf(np.asarray(depth, dtype=np.float64)).any(axis=(1, 2))
        if infinite.any():
            raise option_error("depth", f"frame {self.seen + int(np.argmax(infinite))} holds infinite depth; expected finite values "
                               "(NaN where there is no surface)")
        picked = [i for i in range(len(depth)) if (self.seen + i) % self.keep == 0]
        self.seen += len(depth)
        if picked:
            self.depth.append(_block_mean(np.asarray(depth)[picked], self.step))
            if grey is not None:
                self.grey.append(np.rint(_block_mean(np.asarray(grey)[picked], self.step)).astype(np.uint8))

    def payload(self, name: str) -> dict:
        """The page's data for this video: int16 depth over its range
        (:data:`HOLE` where it is NaN), uint8 grey, base64."""
        depth = np.concatenate(self.depth)
        if np.isnan(depth).all():
            raise ValueError("depth: expected some depth on the surface, got only NaN")
        # Near up: the surface's height is minus the depth, in its standard deviations.
        height = -(depth - np.nanmean(depth, dtype=np.float64)) / (np.nanstd(depth, dtype=np.float64) or 1.0)
        lo, hi = float(np.nanmin(height)), float(np.nanmax(height))
        scale = (hi - lo) / 65534.0 or 1.0
        quantised = np.rint(np.nan_to_num((height - lo) / scale - 32767.0, nan=HOLE)).astype("<i2")
        t, h, w = depth.shape
        return {
            "name": name,
            "frames": t,
            "rows": h,
            "cols": w,
            "zscale": scale,
            "zoffset": lo + 32767.0 * scale,
            "zmin": lo,
            "zmax": hi,
            "z": base64.b64encode(quantised.tobytes()).decode("ascii"),
            "grey": base64.b64encode(np.concatenate(self.grey).tobytes()).decode("ascii") if self.grey else None,
        }

    def note(self) -> str:
        t, h, w = self.shape
        parts = [f"mesh {self.mesh[1]}×{self.mesh[0]} of the {w}×{h} depth (block means of {self.step}×{self.step} pixels)" if self.step > 1
                 else f"mesh {w}×{h}, the depth's own"]
        if self.keep > 1:
            parts.append(f"every {self.keep}th of the {t} frames")
        return "Shown: " + ", ".join(parts) + "."


def write_page(path: PathLike, videos: Sequence[Tuple[str, ViewerFrames]], fps: float = 25.0, title: str = "nrdepth", note: str = "") -> Path:
    """One HTML page showing ``videos`` ((name, frames) pairs, the same
    length after thinning) side by side, each in its own 3-D scene, under
    one time slider, ``note`` after what the page shows; written
    atomically. Returns its path."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    if not videos:
        raise ValueError("videos: expected at least one (name, ViewerFrames)")
    data = [frames.payload(name) for name, frames in videos]
    if len({d["frames"] for d in data}) != 1:
        raise ValueError(f"videos: expected the same number of frames, got {[d['frames'] for d in data]}")
    keep = videos[0][1].keep
    figure = make_subplots(rows=1, cols=len(data), specs=[[{"type": "scene"}] * len(data)], subplot_titles=[d["name"] for d in data],
                           horizontal_spacing=0.02)
    layout = {}
    for i, d in enumerate(data):
        rows, cols = d["rows"], d["cols"]
        x = (np.arange(cols) + 0.5) / cols
        y = -(np.arange(rows) + 0.5) / cols  # row 0 at the top, one frame width = 1
        figure.add_trace(go.Surface(x=x, y=y, z=np.zeros((rows, cols)), showscale=False, hoverinfo="skip",
                                    lighting={"ambient": 0.55, "diffuse": 0.6, "specular": 0.15, "roughness": 0.9}), row=1, col=i + 1)
        span = RELIEF * (d["zmax"] - d["zmin"])
        layout[f"scene{i + 1 if i else ''}"] = {
            "aspectmode": "manual",
            "aspectratio": {"x": 1.0, "y": rows / cols, "z": span},
            # Fixed ranges: a hole at a border (depth off the surface) must not rescale the scene from frame to frame.
            "xaxis": {"visible": False, "range": [0.0, 1.0]}, "yaxis": {"visible": False, "range": [-rows / cols, 0.0]},
            "zaxis": {"visible": False, "range": [d["zmin"], d["zmax"]]},
            "camera": {"eye": {"x": 0.0, "y": -1.1, "z": 1.2}, "up": {"x": 0, "y": 0, "z": 1}},
        }
    figure.update_layout(title={"text": title, "x": 0.01}, margin={"l": 0, "r": 0, "t": 60, "b": 0}, paper_bgcolor="white", **layout)
    config = {"fps": fps / keep, "note": " ".join([videos[0][1].note()] + ([note] if note else [])), "videos": data, "relief": RELIEF, "hole": HOLE}
    script = _SCRIPT.replace("__DATA__", json.dumps(config))
    html = figure.to_html(include_plotlyjs=True, full_html=True, div_id="nrdepth-view", post_script=script,
                          config={"displaylogo": False, "responsive": True}, default_height="88vh")
    path = Path(path)
    if path.is_dir():
        raise option_error("path", f"{path} is a folder; expected the page's file name (viewer.html)")
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}")
    try:
        tmp.write_text(html, encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # no partial page left behind, whatever stopped it
        raise
    return path


def view(
    depth: Union[np.ndarray, PathLike],
    video: Optional[np.ndarray] = None,
    path: Optional[PathLike] = None,
    fps: float = 25.0,
    title: str = "nrdepth",
) -> Path:
    """Write a 3-D viewer page (module docstring) of a depth video: an
    array (T, H, W) with its uint8 video (T, H, W) (or None: coloured by
    depth only; NaN off the surface), or a reconstruction folder of ``nrdepth reconstruct``
    (its ``depth.npz`` read a chunk at a time, the grey frames from the
    left half of its ``side_by_side.mp4``). ``path``: the page (default:
    ``viewer.html`` in the folder, or in the working folder for an array).
    Returns its path."""
    if isinstance(depth, (str, os.PathLike)):
        return _view_folder(Path(depth), path, title)
    depth = np.asarray(depth)
    if depth.dtype.kind != "f" or depth.ndim != 3 or min(depth.shape) < 1 or np.isinf(depth).any() or np.isnan(depth).all():
        raise ValueError(f"depth: expected a float depth video (T, H, W), finite or NaN off the surface, got {depth.dtype} {depth.shape}")
    if video is not None:
        video = np.asarray(video)
        if video.dtype != np.uint8 or video.shape != depth.shape:
            raise ValueError(f"video: expected uint8 frames of the depth's shape {depth.shape}, got {video.dtype} {video.shape}")
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: expected a positive frame rate, got {fps!r}")
    frames = ViewerFrames(depth.shape)
    frames.add(depth, video)
    return write_page(Path("viewer.html") if path is None else path, [("depth", frames)], fps, title)


def sheet_note(sheet: Optional[str]) -> str:
    """The page's line for the sheet stage's decision (``depth.npz``'s ``sheet``, JSON, with its ``line``), or ""."""
    return str(json.loads(sheet).get("line", "")) if sheet else ""


def _view_folder(folder: Path, path: Optional[PathLike], title: str) -> Path:
    if not (folder / "depth.npz").is_file():
        raise ValueError(f"depth: {folder} holds no depth.npz (expected a folder written by nrdepth reconstruct)")
    shape, dtype, chunks = iter_npz_frames(folder / "depth.npz", "depth")
    if dtype.kind != "f" or len(shape) != 3 or min(shape) < 1:
        raise option_error("depth", f"{folder / 'depth.npz'} holds depth of {dtype} {shape}; expected a float depth video (T, H, W)")
    frames = ViewerFrames(shape)
    fps = 25.0
    greys: Iterable[Optional[np.ndarray]] = iter(lambda: None, 0)
    video = folder / "side_by_side.mp4"
    if video.is_file():
        fps, greys = read_left_half(video, shape[1:])
    greys = iter(_rechunk(greys, shape[0]))
    for depth, grey in zip(chunks, greys):
        if grey is not None and len(grey) != len(depth):
            raise option_error("video", f"{video} holds {'more' if len(grey) > len(depth) else 'fewer'} frames than the {shape[0]} of "
                               f"{folder / 'depth.npz'}")
        try:
            frames.add(depth, grey)
        except ValueError as error:
            raise option_error("depth", f"{folder / 'depth.npz'}: {error.detail}") from None
    extra = next(greys, None)
    if frames.seen < shape[0] or extra is not None:
        raise option_error("video", f"{video} holds {'fewer' if frames.seen < shape[0] else 'more'} frames than the {shape[0]} of "
                           f"{folder / 'depth.npz'}")
    with np.load(folder / "depth.npz") as saved:
        sheet = str(saved["sheet"]) if "sheet" in saved.files else None
    return write_page(folder / "viewer.html" if path is None else path, [("depth", frames)], fps, title, " ".join(filter(None, [FULL_RESOLUTION, sheet_note(sheet)])))


def _rechunk(greys: Iterable[Optional[np.ndarray]], total: int, size: int = 16) -> Iterable[Optional[np.ndarray]]:
    """Grey frames regrouped ``size`` at a time (as ``iter_npz_frames`` gives depth), or Nones."""
    buffer: List[np.ndarray] = []
    for grey in greys:
        if grey is None:
            yield None
            continue
        buffer.append(grey)
        if len(buffer) == size:
            yield np.stack(buffer)
            buffer = []
    if buffer:
        yield np.stack(buffer)


_SCRIPT = r"""
(function () {
  const div = document.getElementById('{plot_id}');
  const D = __DATA__;
  const decode = (text, Type) => {
    const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
    return new Type(bytes.buffer);
  };
  const videos = D.videos.map((v) => ({ ...v, Z: decode(v.z, Int16Array), G: v.grey ? decode(v.grey, Uint8Array) : null }));
  const frames = videos[0].frames;
  const grid = (v, source, t, scale, offset) => {
    const n = v.rows * v.cols, out = new Array(v.rows);
    for (let y = 0; y < v.rows; y++) {
      const row = new Array(v.cols);
      for (let x = 0; x < v.cols; x++) {
        const value = source[t * n + y * v.cols + x];
        row[x] = source === v.Z && value === D.hole ? null : value * scale + offset;  // null: a hole in plotly's surface
      }
      out[y] = row;
    }
    return out;
  };
  const bar = document.createElement('div');
  bar.id = 'nrdepth-controls';
  bar.style.cssText = 'font: 14px sans-serif; padding: 6px 10px; display: flex; gap: 14px; align-items: center; flex-wrap: wrap';
  bar.innerHTML = `
    <button id="nrdepth-play" style="width: 5em">play</button>
    <input id="nrdepth-time" type="range" min="0" max="${frames - 1}" value="0" style="flex: 1; min-width: 200px">
    <span id="nrdepth-label"></span>
    <label>relief × <input id="nrdepth-relief" type="range" min="-2" max="3" step="0.25" value="0" style="width: 8em"> <span id="nrdepth-relief-label">1</span></label>
    <label>colour <select id="nrdepth-colour"><option value="video">video (grey)</option><option value="depth">depth</option></select></label>
    <span style="color: #666">${D.note}</span>`;
  div.parentNode.insertBefore(bar, div);
  const slider = document.getElementById('nrdepth-time'), label = document.getElementById('nrdepth-label');
  const colour = document.getElementById('nrdepth-colour'), play = document.getElementById('nrdepth-play');
  const relief = document.getElementById('nrdepth-relief'), reliefLabel = document.getElementById('nrdepth-relief-label');
  if (!videos.every((v) => v.G)) { colour.value = 'depth'; colour.disabled = true; }
  const GREY = [[0, '#000000'], [1, '#ffffff']];
  const DEPTH = [[0, '#30123b'], [0.25, '#4686fb'], [0.5, '#1ae4b6'], [0.75, '#faba39'], [1, '#7a0403']];
  let frame = 0;
  const show = (t) => {
    frame = t;
    const update = { z: [], surfacecolor: [], colorscale: [], cmin: [], cmax: [] };
    for (const v of videos) {
      const z = grid(v, v.Z, t, v.zscale, v.zoffset);
      const byVideo = colour.value === 'video' && v.G;
      update.z.push(z);
      update.surfacecolor.push(byVideo ? grid(v, v.G, t, 1, 0) : z);
      update.colorscale.push(byVideo ? GREY : DEPTH);
      update.cmin.push(byVideo ? 0 : v.zmin);
      update.cmax.push(byVideo ? 255 : v.zmax);
    }
    slider.value = t;
    label.textContent = `frame ${t + 1} / ${frames}`;
    return Plotly.restyle(div, update, videos.map((_, i) => i));
  };
  const setRelief = () => {
    const factor = Math.pow(2, Number(relief.value));
    reliefLabel.textContent = factor.toFixed(2).replace(/\.?0+$/, '');
    const update = {};
    videos.forEach((v, i) => { update[`scene${i ? i + 1 : ''}.aspectratio.z`] = D.relief * (v.zmax - v.zmin) * factor; });
    return Plotly.relayout(div, update);
  };
  let playing = false;
  const loop = async () => {
    while (playing) {
      const start = performance.now();
      await show((frame + 1) % frames);
      await new Promise((done) => setTimeout(done, Math.max(0, 1000 / D.fps - (performance.now() - start))));
    }
  };
  play.onclick = () => { playing = !playing; play.textContent = playing ? 'pause' : 'play'; if (playing) loop(); };
  slider.oninput = () => { playing = false; play.textContent = 'play'; show(Number(slider.value)); };
  colour.onchange = () => show(frame);
  relief.oninput = setRelief;
  window.nrdepthViewer = { show, frames };
  show(0);
})();
"""
