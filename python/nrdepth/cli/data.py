"""``nrdepth surfaces``, ``generate`` and ``preview``: the data engine's commands."""

from __future__ import annotations

import argparse
import math
import time

from ..engine.dataset import write_dataset
from ..engine.generate import GeneratorConfig
from ..engine.preview import preview_sheet, save_png, surface_sheet
from ..engine.surface import SurfaceConfig

__all__ = ["add_commands", "add_generator_options", "generator_config"]


def _surfaces(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    sheet = surface_sheet(seed=args.seed, clips=args.clips, frames=args.frames, grid=args.grid, columns=args.columns)
    save_png(args.out, sheet)
    print(
        f"wrote {args.out}: {args.clips} clips × {args.frames} frames on a {args.grid}×{args.grid} grid "
        f"(seed {args.seed}) in {time.perf_counter() - start:.2f} s"
    )
    return 0


def _shard(text: str) -> tuple:
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected i/N, got {text!r}") from None
    return i, n


def generator_config(args: argparse.Namespace) -> GeneratorConfig:
    """The :class:`~nrdepth.GeneratorConfig` of the generator's flags (:func:`add_generator_options`)."""
    extra = {}
    if args.light_azimuth is not None:
        extra["light_azimuth"] = args.light_azimuth
    if args.intensity is not None:
        extra["surface"] = SurfaceConfig(intensity=args.intensity)
    if args.window_width is not None:
        extra["window_width"] = args.window_width
    for name in ("blur", "gamma"):
        if getattr(args, name, None) is not None:
            extra[name] = getattr(args, name)
    if args.sheets is not None:
        extra["sheet_probability"] = args.sheets
    if args.backdrops is not None:
        extra["backdrop_probability"] = args.backdrops
    if args.backdrop_brightness is not None:
        extra["backdrop_brightness"] = args.backdrop_brightness
    if args.camera_fov is not None:
        extra["camera_fov"] = tuple(math.radians(v) for v in args.camera_fov)
    if args.crop_share is not None:
        extra["crop_share"] = args.crop_share
    if args.perspective is not None:
        extra["camera_probability"] = args.perspective
    if args.texture_families is not None:
        extra["texture_families"] = tuple(args.texture_families.split(","))
    return GeneratorConfig(frames=args.frames, size=args.size, grid=args.grid, textures=args.textures, **extra)


def _generate(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    manifest = write_dataset(
        args.out, args.clips, seed=args.seed, config=generator_config(args), shard_size=args.shard_size,
        shard=args.shard, progress=not args.quiet,
    )
    print(f"dataset {args.out}: manifest {manifest} ({time.perf_counter() - start:.1f} s)")
    return 0


def _preview(args: argparse.Namespace) -> int:
    save_png(args.out, preview_sheet(seed=args.seed, clips=args.clips, config=generator_config(args)))
    print(f"wrote {args.out}: {args.clips} sample clips (frames | depth | mesh) and the parameter sweep "
          "(low values | more constraint | non-identity Σ | more flexibility | more folding)")
    return 0


def _azimuth(text: str) -> tuple:
    if text == "uniform":
        return (-math.pi, math.pi)
    lo, hi = _interval(text, "LO,HI in degrees from image-up or 'uniform'")
    return math.radians(lo), math.radians(hi)


def _interval(text: str, expected: str = "LO,HI") -> tuple:
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    return lo, hi


def add_generator_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seed", type=int, default=0, help="run seed: clip i is a pure function of (config, seed, i)")
    p.add_argument("--textures", default=None, help="folder of PNG/JPEG images to crop textures from (default: procedural)")
    p.add_argument("--frames", type=int, default=16, help="frames per clip")
    p.add_argument("--size", type=int, default=64, help="image side in pixels")
    p.add_argument("--grid", type=int, default=64, help="mesh vertices per side")
    p.add_argument("--light-azimuth", type=_azimuth, default=None, metavar="LO,HI",
                   help="light azimuths in degrees from image-up, clockwise (default: -70,70, light from above); 'uniform' for all")
    p.add_argument("--intensity", type=_interval, default=None, metavar="LO,HI",
                   help="range of the surfaces' displacement intensity κ (default: 0.03,0.12; 0 is a flat sheet)")
    p.add_argument("--window-width", type=_interval, default=None, metavar="LO,HI",
                   help="range of the view window's width in half-widths of the patch, i.e. the zoom (default: 0.8,1.2; "
                        "smaller shows the surface magnified)")
    p.add_argument("--blur", type=_interval, default=None, metavar="LO,HI",
                   help="range of the camera's Gaussian blur, standard deviation in pixels (default: 0,0, none)")
    p.add_argument("--gamma", type=_interval, default=None, metavar="LO,HI",
                   help="range of the camera's response exponent, v -> v**gamma (default: 1,1, linear)")
    p.add_argument("--sheets", type=float, default=None, metavar="P",
                   help="share of clips that are sheets bent isometrically: rolls, bends and folds whose curvature moves "
                        "(default: 0, the coloured-noise surfaces alone)")
    p.add_argument("--backdrops", type=float, default=None, metavar="P",
                   help="share of clips whose view is wider than the sheet: its border shows over a background, and "
                        "the depth is masked to the sheet (needs a signed loss; default: 0, the view inside the sheet)")
    p.add_argument("--backdrop-brightness", type=_interval, default=None, metavar="LO,HI",
                   help="range of the backdrops' brightness, 0 black to 1 white (default: 0.05,0.9)")
    p.add_argument("--camera-fov", type=_interval, default=None, metavar="LO,HI",
                   help="a perspective camera: range of the field of view, in degrees, across the frame a clip is cut from "
                        "(default: 0,0, the orthographic camera)")
    p.add_argument("--crop-share", type=_interval, default=None, metavar="LO,HI",
                   help="with --camera-fov: range of a clip's width as a share of its frame's (default: 1,1, the whole frame)")
    p.add_argument("--perspective", type=float, default=None, metavar="P",
                   help="with --camera-fov: share of clips seen through the pinhole, the others orthographically (default: 1)")
    p.add_argument("--texture-families", default=None, metavar="A,B,...",
                   help="procedural texture families to draw from, of fractal, stripes, plaid, cells, weave, print "
                        "(print: text and line drawings on white paper; default: all but print)")


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("surfaces", help="synthesise deforming surfaces and write a picture of them")
    p.add_argument("out", nargs="?", default="surfaces.png", help="output PNG (default: surfaces.png)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first clip; clip i uses seed + i")
    p.add_argument("--clips", type=int, default=4, help="number of clips (rows)")
    p.add_argument("--frames", type=int, default=16, help="frames per clip")
    p.add_argument("--grid", type=int, default=64, help="mesh vertices per side")
    p.add_argument("--columns", type=int, default=4, help="frames shown per clip")
    p.set_defaults(run=_surfaces)

    p = sub.add_parser("generate", help="write a sharded HDF5 dataset of training clips (resumable)")
    p.add_argument("out", help="dataset folder")
    p.add_argument("--clips", type=int, default=153600, help="number of clips (the paper used 153600)")
    p.add_argument("--shard-size", type=int, default=1024, help="clips per shard file")
    p.add_argument("--shard", type=_shard, default=(0, 1), help="write only shards k with k mod N = i (i/N)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_generator_options(p)
    p.set_defaults(run=_generate)

    p = sub.add_parser("preview", help="picture of sample clips and of the surface parameter sweep")
    p.add_argument("out", nargs="?", default="preview.png", help="output PNG (default: preview.png)")
    p.add_argument("--clips", type=int, default=3, help="sample clips (rows)")
    add_generator_options(p)
    p.set_defaults(run=_preview)
