"""Bent sheets of paper rendered by a physically based path tracer that this
project did not write (Mitsuba 3, ``scalar_rgb``): a check on sheets that no
training clip and no rule of the sheet stage was drawn from.

Each video is one :class:`Scene`, drawn from its seed alone: an A4 print
(a photo, text or a map; matte or glossy) bent isometrically about one axis
(a cylinder's bend, whose curvature changes over the video: the middle away
from the camera, toward it, or turning from one to the other), moving rigidly,
in front of a static background (a textured table or wall, or a plain one)
under one point light (above, below, beside or at the camera, as a phone's
flash) and a dim fill, seen through a pinhole of 30–75° across the frame.

Frames and units: the camera at the origin looking along +z, image row 0 at
the top; the truth is the depth along the optical axis (z, scene units, NaN
off every surface) and the sheet's mask, both per pixel, each pixel fully on
the sheet in every sample (its edges left out). Videos are cached outside the
repository (``NRDEPTH_RENDERED``, default ``~/.cache/nrdepth/rendered``), one
``.npz`` a seed: ``video`` uint8 (T, H, W) gray, ``depth`` float32 (T, H, W),
``sheet`` bool (T, H, W), ``focal`` (pixels), ``scene`` (JSON).

The seeds split once, before any score was read: even seeds are the
selection set (where a rule may read), odd seeds the report set.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Optional, Tuple

import numpy as np

__all__ = ["Scene", "scene_of", "render_video", "load_video", "cache_folder", "true_tracks", "SELECTION", "REPORT", "split_of"]

PRINTS, BACKGROUNDS, LIGHTS, BENDS, FINISHES = ("photo", "text", "map"), ("table", "wall", "plain"), ("above", "below", "beside", "camera"), \
    ("away", "toward", "turning"), ("matte", "glossy")
SELECTION, REPORT = "selection", "report"


def split_of(seed: int) -> str:
    """The set a seed belongs to, fixed before any score was read: even seeds select, odd seeds report."""
    return SELECTION if seed % 2 == 0 else REPORT


@dataclass(frozen=True)
class Scene:
    """One rendered video, every choice drawn from ``seed`` (:func:`scene_of`)."""

    seed: int
    frames: int
    size: Tuple[int, int]  # (H, W) pixels
    fov: float  # degrees across the frame's width
    print_kind: str
    finish: str
    background: str
    light: str
    bend: str
    curvature: float  # the largest bend, 1 / scene units (the sheet is 0.297 long)
    cycles: float  # how many times the bend swings over the video
    axis: float  # the bend's axis in the sheet's plane, radians from its long side
    tilt: Tuple[float, float]  # the sheet's largest rigid turn about x and y, radians
    distance: float  # the sheet's centre from the camera, scene units
    spp: int = 4  # samples a pixel: the sensor's noise of a dim room

    @property
    def focal(self) -> float:
        """Pixels."""
        return 0.5 * self.size[1] / math.tan(math.radians(self.fov) / 2)


def scene_of(seed: int, frames: Optional[int] = None, size: Optional[Tuple[int, int]] = None, spp: int = 4) -> Scene:
    """The scene of ``seed``: everything drawn from it (``frames`` and ``size`` may be given)."""
    rng = np.random.default_rng([seed, 2026_12_07])
    fov = float(rng.uniform(30.0, 75.0))
    side = int(rng.choice([256, 320]))
    shape = size or (side, side)
    # The sheet fills about half the frame's width whatever the lens: its distance follows the field of view.
    distance = SHEET[0] / 2 / math.tan(math.radians(fov) / 2) / float(rng.uniform(0.45, 0.7))
    return Scene(seed=seed, frames=frames or int(rng.choice([64, 96, 128])), size=tuple(int(v) for v in shape), fov=fov,
                 print_kind=str(rng.choice(PRINTS)), finish=str(rng.choice(FINISHES, p=[0.6, 0.4])), background=str(rng.choice(BACKGROUNDS)),
                 light=str(rng.choice(LIGHTS)), bend=str(rng.choice(BENDS)), curvature=float(rng.uniform(4.0, 12.0)),
                 cycles=float(rng.uniform(1.0, 2.5)), axis=float(rng.uniform(-0.6, 0.6) + rng.choice([0.0, math.pi / 2])),
                 tilt=(float(rng.uniform(0.1, 0.45)), float(rng.uniform(0.1, 0.45))), distance=float(distance), spp=spp)


def cache_folder() -> Path:
    return Path(os.environ.get("NRDEPTH_RENDERED", Path.home() / ".cache" / "nrdepth" / "rendered"))


# ---- the sheet's shape ----------------------------------------------------

SHEET = (0.21, 0.297)  # A4, metres: (width, length)
GRID = (42, 60)  # vertices across and along


def curvature_at(scene: Scene, t: float) -> float:
    """The signed curvature at time ``t`` in [0, 1]: positive bends the middle away from the camera."""
    swing = math.sin(2 * math.pi * scene.cycles * t + 0.3)
    if scene.bend == "away":
        return scene.curvature * (0.55 + 0.45 * swing)
    if scene.bend == "toward":
        return -scene.curvature * (0.55 + 0.45 * swing)
    return scene.curvature * swing  # turning: from one side to the other


def sheet_vertices(scene: Scene, t: float) -> np.ndarray:
    """The sheet's vertices (GRID[0] * GRID[1], 3) at time ``t``: a flat A4 bent
    isometrically about an axis at ``scene.axis`` (a cylinder of the curvature
    at ``t``), turned rigidly and placed ``scene.distance`` in front of the camera."""
    u, v = np.meshgrid(np.linspace(-SHEET[0] / 2, SHEET[0] / 2, GRID[0]), np.linspace(-SHEET[1] / 2, SHEET[1] / 2, GRID[1]))
    across = np.array([math.cos(scene.axis), math.sin(scene.axis)])  # the bend's direction in the sheet (perpendicular to its axis)
    s = u * across[0] + v * across[1]
    along = (u * -across[1] + v * across[0])
    k = curvature_at(scene, t)
    if abs(k) < 1e-6:
        bent, lift = s, np.zeros_like(s)
    else:
        bent, lift = np.sin(k * s) / k, (1 - np.cos(k * s)) / k  # arc length kept: an isometry
    # lift > 0 with k > 0: the edges come toward the camera (−z), the middle stays behind them
    x = bent * across[0] - along * across[1]
    y = bent * across[1] + along * across[0]
    z = -lift
    points = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    points -= points.mean(axis=0)
    ax, ay = scene.tilt[0] * math.sin(2 * math.pi * 0.7 * t + 1.1), scene.tilt[1] * math.sin(2 * math.pi * 0.5 * t + 0.4)
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    drift = np.array([0.02 * math.sin(2 * math.pi * t), 0.015 * math.cos(2 * math.pi * 0.8 * t), 0.0])
    return points @ (ry @ rx).T + np.array([0.0, 0.0, scene.distance]) + drift


def _pixels(scene: Scene, points: np.ndarray) -> np.ndarray:
    """Where camera-frame ``points`` (..., 3) appear: (..., 2) column, row, pixel centres at integers."""
    H, W = scene.size
    return np.stack([scene.focal * points[..., 0] / points[..., 2] + W / 2 - 0.5,
                     scene.focal * points[..., 1] / points[..., 2] + H / 2 - 0.5], axis=-1)


def true_tracks(scene: Scene, start: np.ndarray, depth: Optional[np.ndarray] = None) -> np.ndarray:
    """Where the sheet's points seen at ``start`` (n, 2) in the first frame
    are in each of the scene's frames: (T, n, 2) column, row, from the
    sheet's own geometry (each start's place on the sheet, then that place
    carried through :func:`sheet_vertices`). NaN for a start off the sheet;
    with the render's ``depth`` (T, H, W), also where a point is hidden (its
    depth not the render's within 1 %) or out of the frame."""
    from scipy.interpolate import RegularGridInterpolator, griddata

    start = np.asarray(start, np.float64)
    T, (H, W) = scene.frames, scene.size
    on_sheet = griddata(_pixels(scene, sheet_vertices(scene, 0.0)), sheet_uv(), start, method="linear")  # (u, v) of each start
    found = np.isfinite(on_sheet).all(axis=1)
    axes = (np.linspace(0, 1, GRID[1]), np.linspace(0, 1, GRID[0]))  # v along, u across: the vertices' grid
    out = np.full((T, len(start), 2), np.nan)
    for t in range(T):
        place = RegularGridInterpolator(axes, sheet_vertices(scene, t / max(T - 1, 1)).reshape(GRID[1], GRID[0], 3))(on_sheet[found][:, ::-1])
        out[t, found] = _pixels(scene, place)
        if depth is not None:
            xy = out[t, found]
            inside = (xy[:, 0] >= 0) & (xy[:, 0] <= W - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= H - 1)
            rendered = np.full(len(xy), np.nan)
            rows, cols = np.rint(xy[inside, 1]).astype(int), np.rint(xy[inside, 0]).astype(int)
            rendered[inside] = depth[t][rows, cols]
            seen = inside & (np.abs(rendered - place[:, 2]) <= 0.01 * place[:, 2])
            out[t, np.flatnonzero(found)[~seen]] = np.nan
    return out


def sheet_faces() -> np.ndarray:
    i, j = np.meshgrid(np.arange(GRID[1] - 1), np.arange(GRID[0] - 1), indexing="ij")
    a = (i * GRID[0] + j).ravel()
    return np.concatenate([np.stack([a, a + GRID[0], a + 1], 1), np.stack([a + 1, a + GRID[0], a + GRID[0] + 1], 1)]).astype(np.uint32)


def sheet_uv() -> np.ndarray:
    u, v = np.meshgrid(np.linspace(0, 1, GRID[0]), np.linspace(0, 1, GRID[1]))
    return np.stack([u.ravel(), v.ravel()], 1)


# ---- the prints and backgrounds ----------------------------------------------

def print_image(kind: str, rng: np.random.Generator, size: Tuple[int, int] = (1188, 840)) -> np.ndarray:
    """An RGB print (H, W, 3) in [0, 1] on white paper: a photo, text, or a map."""
    from PIL import Image, ImageDraw, ImageFont

    h, w = size
    if kind == "photo":
        import matplotlib

        photo = Image.open(Path(matplotlib.__file__).parent / "mpl-data" / "sample_data" / "grace_hopper.jpg").convert("RGB")
        photo = photo.rotate(float(rng.uniform(-8, 8)), resample=Image.BILINEAR, expand=False).resize((w - 80, h - 120))
        page = Image.new("RGB", (w, h), (245, 245, 240))
        page.paste(photo, (40, 60))
        image = np.asarray(page, np.float32) / 255
        return np.clip(image * rng.uniform(0.85, 1.1, 3), 0, 1)
    page = Image.new("RGB", (w, h), (247, 246, 242))
    draw = ImageDraw.Draw(page)
    if kind == "text":
        font = ImageFont.load_default(size=int(rng.integers(22, 34)))
        words = ["sheet", "depth", "paper", "bend", "camera", "light", "video", "shape", "print", "surface", "the", "of", "and", "frame"]
        y = 50
        while y < h - 60:
            line = " ".join(rng.choice(words, int(rng.integers(5, 10))))
            draw.text((45, y), line, fill=tuple(int(c) for c in rng.integers(0, 60, 3)), font=font)
            y += int(font.size * rng.uniform(1.3, 1.7))
            if rng.random() < 0.12:
                y += 30
    else:  # a map: land, water, roads
        for _ in range(int(rng.integers(6, 12))):
            centre = rng.uniform(0, 1, 2) * (w, h)
            radius = rng.uniform(60, 220)
            angles = np.sort(rng.uniform(0, 2 * np.pi, 9))
            polygon = [tuple(centre + radius * rng.uniform(0.5, 1.2) * np.array([np.cos(a), np.sin(a)])) for a in angles]
            draw.polygon(polygon, fill=tuple(int(c) for c in rng.integers(150, 235, 3)))
        for width, colour in ((9, (110, 160, 220)), (5, (200, 60, 40)), (3, (60, 60, 60))):
            for _ in range(int(rng.integers(4, 9))):
                points = np.cumsum(rng.normal(0, 60, (14, 2)), axis=0) + rng.uniform(0, 1, 2) * (w, h)
                draw.line([tuple(p) for p in points], fill=colour, width=width)
    return np.asarray(page, np.float32) / 255


def background_image(kind: str, rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """A background's RGB texture in [0, 1]: wood grain (a table), bricks (a wall), or plain grey."""
    y, x = np.mgrid[0:size, 0:size] / size
    if kind == "plain":
        return np.full((8, 8, 3), float(rng.uniform(0.35, 0.6)), np.float32)
    noise = np.real(np.fft.ifft2(np.fft.fft2(rng.normal(size=(size, size))) * np.exp(-np.hypot(*np.meshgrid(np.fft.fftfreq(size), np.fft.fftfreq(size))) * 40)))
    noise /= np.abs(noise).max()
    if kind == "table":
        grain = np.sin(2 * np.pi * (x * 3 + 2.5 * noise + 0.4 * np.sin(2 * np.pi * y * 1.3)) * 9)
        base = np.array([0.55, 0.36, 0.2]) * float(rng.uniform(0.8, 1.15))
        return np.clip(base * (0.8 + 0.12 * grain[..., None] + 0.08 * noise[..., None]), 0, 1).astype(np.float32)
    rows = (y * 14).astype(int)
    offset = (rows % 2) * 0.5
    mortar = (np.abs(((y * 14) % 1) - 0.5) > 0.44) | (np.abs(((x * 7 + offset) % 1) - 0.5) > 0.46)
    brick = np.array([0.6, 0.3, 0.22]) * (0.85 + 0.15 * noise[..., None])
    return np.where(mortar[..., None], 0.75, brick).astype(np.float32)


# ---- rendering ------------------------------------------------------------------

LIGHT_AT = {"above": (0.0, -1.2, -0.2), "below": (0.0, 1.2, -0.2), "beside": (1.2, 0.0, -0.2), "camera": (0.0, 0.0, 0.0)}
"""Each light's place relative to the camera, in units of the sheet's distance (y grows downward in the image: −y is above)."""


def _scene_dict(scene: Scene, folder: Path) -> dict:
    import mitsuba as mi

    rng = np.random.default_rng([scene.seed, 7])
    paper, back = folder / f"print_{scene.seed}.png", folder / f"background_{scene.seed}.png"
    _save_png(paper, print_image(scene.print_kind, rng))
    _save_png(back, background_image(scene.background, rng))
    texture = {"type": "bitmap", "filename": str(paper), "filter_type": "bilinear"}
    bsdf = {"type": "diffuse", "reflectance": texture} if scene.finish == "matte" else \
        {"type": "roughplastic", "diffuse_reflectance": texture, "alpha": 0.12, "int_ior": 1.5}
    bsdf = {"type": "twosided", "material": bsdf}  # seen from either side
    place = np.array(LIGHT_AT[scene.light]) * scene.distance
    far = scene.distance + 0.35
    half = far * math.tan(math.radians(scene.fov) / 2) * 1.6
    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "aov", "aovs": "pp:position,si:shape_index", "img": {"type": "path", "max_depth": 3}},
        "sensor": {"type": "perspective", "fov": scene.fov, "fov_axis": "x",
                   "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, -1, 0]),
                   "film": {"type": "hdrfilm", "width": scene.size[1], "height": scene.size[0], "rfilter": {"type": "box"},
                            "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": scene.spp, "seed": scene.seed}},
        "light": {"type": "point", "position": [float(v) for v in place + np.array([0.0, 0.0, 1e-3])],
                  "intensity": {"type": "rgb", "value": [1.3 * scene.distance ** 2] * 3}},
        "fill": {"type": "constant", "radiance": {"type": "rgb", "value": [0.3] * 3}},
        "sheet": {"type": "ply", "filename": str(folder / f"sheet_{scene.seed}.ply"), "bsdf": bsdf, "face_normals": False},
        "background": {"type": "rectangle", "to_world": T().translate([0, 0, far]).scale([half, half, 1.0]),
                       "bsdf": {"type": "twosided", "material": {"type": "diffuse", "reflectance": {"type": "bitmap", "filename": str(back)}}}},
    }


def _save_png(path: Path, image: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(np.rint(np.clip(image, 0, 1) * 255).astype(np.uint8)).save(path)


def _write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> None:
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"property float u\nproperty float v\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    vertex = np.concatenate([vertices, uv], axis=1).astype("<f4")
    face = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    face["n"], face["i"] = 3, faces
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(vertex.tobytes())
        out.write(face.tobytes())


def render_video(scene: Scene, path: Optional[Path] = None) -> Path:
    """Renders ``scene`` into the cache (or ``path``), atomically; returns the file."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")  # the LLVM variants abort with the system's libLLVM on these machines
    path = Path(path or cache_folder() / f"sheet_{scene.seed}.npz")
    path.parent.mkdir(parents=True, exist_ok=True)
    faces, uv = sheet_faces(), sheet_uv()
    H, W = scene.size
    frames, depth, sheet = (np.zeros((scene.frames, H, W), dtype) for dtype in (np.uint8, np.float32, bool))
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        _write_ply(folder / f"sheet_{scene.seed}.ply", sheet_vertices(scene, 0.0), faces, uv)
        loaded = mi.load_dict(_scene_dict(scene, folder))
        params = mi.traverse(loaded)
        key = next(k for k in params.keys() if k.endswith("vertex_positions"))
        sheet_index = _sheet_index(loaded)
        for t in range(scene.frames):
            params[key] = type(params[key])(sheet_vertices(scene, t / max(scene.frames - 1, 1)).astype(np.float32).ravel())
            params.update()
            image = np.array(mi.render(loaded, seed=scene.seed * 1000 + t), dtype=np.float32)
            rgb, position, index = image[..., :3], image[..., 3:6], image[..., 6]
            gray = 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
            frames[t] = np.rint(np.clip(gray, 0, 1) ** (1 / 2.2) * 255)  # an sRGB-like response
            on_sheet = np.abs(index - sheet_index) < 1e-4
            hit = position[..., 2] > 1e-6
            depth[t] = np.where(hit, position[..., 2], np.nan)
            sheet[t] = on_sheet & hit
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}.npz")
    np.savez_compressed(tmp, video=frames, depth=depth, sheet=sheet, focal=np.float64(scene.focal), scene=json.dumps(dataclasses.asdict(scene)))
    os.replace(tmp, path)
    return path


def _sheet_index(scene) -> int:
    """The sheet's index among the scene's shapes, as the ``shape_index`` AOV counts them."""
    return 1 + next(i for i, shape in enumerate(scene.shapes()) if shape.id() == "sheet")  # 0: no surface


def load_video(seed: int) -> Dict[str, np.ndarray]:
    """The cached video of ``seed`` (:func:`render_video` first)."""
    path = cache_folder() / f"sheet_{seed}.npz"
    if not path.exists():
        raise FileNotFoundError(f"seed: no rendered video {path}; render it first (python benchmarks/bench_sheet_stage.py render --seeds {seed})")
    with np.load(path) as saved:
        out = {name: saved[name] for name in saved.files}
    out["scene"] = json.loads(str(out["scene"]))
    return out
