"""The ``nrdepth`` command line: a thin layer over the Python API."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

from . import __version__
from .isometric import TEMPLATES
from .reconstruct import FINE_PASSES, ISOMETRIC_DROP, ISOMETRIC_SCALE, MAX_SIDE
from .stitch import ALIGNMENTS, COARSE_WEIGHT, TEMPORAL_WEIGHT, WINDOWS


def _surfaces(args: argparse.Namespace) -> int:
    from .preview import save_png, surface_sheet

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


def _generator_config(args: argparse.Namespace):
    from .generate import GeneratorConfig
    from .surface import SurfaceConfig

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
    from .dataset import write_dataset

    start = time.perf_counter()
    manifest = write_dataset(
        args.out, args.clips, seed=args.seed, config=_generator_config(args), shard_size=args.shard_size,
        shard=args.shard, progress=not args.quiet,
    )
    print(f"dataset {args.out}: manifest {manifest} ({time.perf_counter() - start:.1f} s)")
    return 0


def _preview(args: argparse.Namespace) -> int:
    from .preview import preview_sheet, save_png

    save_png(args.out, preview_sheet(seed=args.seed, clips=args.clips, config=_generator_config(args)))
    print(f"wrote {args.out}: {args.clips} sample clips (frames | depth | mesh) and the parameter sweep "
          "(low values | more constraint | non-identity Σ | more flexibility | more folding)")
    return 0


def _train(args: argparse.Namespace) -> int:
    from .train import PAPER, RECOMMENDED, TrainConfig, train

    recipe = {k: v if getattr(args, k) is None else getattr(args, k) for k, v in (PAPER if args.paper else RECOMMENDED).items()}
    config = TrainConfig(
        **recipe, base=args.base, schedule=args.schedule, amplitude=args.amplitude, init=args.init, batch_size=args.batch_size, steps_per_epoch=args.steps, epochs=args.epochs,
        seed=args.seed, data=args.data, generator=_generator_config(args),
        validation_clips=args.validation_clips, workers=args.workers, device=args.device, compile=args.compile,
        real=(args.real[0] if len(args.real) == 1 else args.real) if args.real else None, keep_every=args.keep_every, ema=args.ema,
        anchor=args.anchor,
    )
    summary = train(args.out, config, progress=not args.quiet, max_epochs=args.max_epochs)
    if summary:
        print(json.dumps(summary, indent=2))
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from .evaluate import evaluate, format_summary

    summary = evaluate(args.model, args.data, args.out, clips=args.clips, config=_generator_config(args), device=args.device, readings=args.readings)
    print(format_summary(summary))
    return 0


def _average(args: argparse.Namespace) -> int:
    from .model import average_models, save_model

    out = Path(args.out)
    path = out if out.suffix == ".safetensors" else out / "model.safetensors"
    if path.exists() and not args.overwrite:
        raise ValueError(f"out: {path} exists; --overwrite replaces it")
    if out.suffix != ".safetensors" and out.exists() and not out.is_dir():
        raise ValueError(f"out: expected a folder or a path ending in .safetensors, got the file {out}")
    model = average_models(args.models, args.weights)
    shares = args.weights or [1.0] * len(args.models)
    recipe = {"models": [str(m) for m in args.models], "weights": [w / sum(shares) for w in shares]}
    extra = {"average": recipe, **({"depth_units": model.depth_units} if model.depth_units else {})}
    path.parent.mkdir(parents=True, exist_ok=True)
    save_model(model, path, extra)
    print(f"wrote {path} (and {path.with_suffix('.json').name}): "
          + " + ".join(f"{w:.4g} × {m}" for w, m in zip(recipe["weights"], recipe["models"])))
    return 0


def _weights(text: str) -> list:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


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


def _roi(text: str) -> tuple:
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,W,H in pixels, got {text!r}") from None
    return x, y, w, h


def _pair(what: str, counts: tuple):
    """A parser of one or two comma-separated numbers (``counts``), named ``what`` in its complaint."""

    def parse(text: str):
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            values = ()
        if len(values) not in counts:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return values[0] if len(values) == 1 else values

    return parse


def _frames(text: str) -> slice:
    try:
        parts = [int(v) if v else None for v in text.split(":")]
        if not 2 <= len(parts) <= 3:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START:STOP[:STEP] (Python slice), got {text!r}") from None
    return slice(*parts)


def _reconstruct(args: argparse.Namespace) -> int:
    from .model.io import SCALED_MODEL, load_model, resolve_device
    from .reconstruct import reconstruct_file

    # Everything that can be refused is checked before any work or writing.
    device = resolve_device(args.device)
    if args.model is not None and not Path(args.model).exists():
        raise ValueError(f"--model: {args.model} not found")
    try:
        model = load_model(SCALED_MODEL if args.model is None and args.units == "pixels" else args.model, device=str(device))
    except ValueError as e:
        raise ValueError(f"--model: {e}") from None
    if args.units == "pixels" and getattr(model, "depth_units", None) != "window":
        raise ValueError("--units: 'pixels' needs a model that learnt the relief's scale (trained with --amplitude); this one gives depth up to scale")
    for flag, value, floor in (("--ply-relief", args.ply_relief, None), ("--coarse-weight", args.coarse_weight, None), ("--temporal-weight", args.temporal_weight, 0.0)):
        if value is not None and not (math.isfinite(value) and (value > 0 if floor is None else value >= floor)):
            raise ValueError(f"{flag}: expected a {'positive' if floor is None else 'non-negative'} finite number, got {value}")
    if args.max_side != 0 and args.max_side < 8:
        raise ValueError(f"--max-side: expected an integer ≥ 8, or 0 for the video's own size, got {args.max_side}")
    out = Path(args.out) if args.out is not None else Path(Path(args.input).stem + "_depth")
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if args.quiet:
            return
        if bar is None:  # once the input and output are accepted: a refusal is one line
            from tqdm import tqdm

            bar = tqdm(total=total, desc="frames", unit="frame")
        bar.update(done - bar.n)

    start = time.perf_counter()
    try:
        # The path, not the module checked above: reconstruct_file loads it in the channels-last layout (≈ 1.4× faster on the CPU).
        reconstruct_file(args.input, out, args.model, batch_size=args.batch_size, device=str(device), progress=progress, temporal=args.temporal_align,
                         roi=args.roi, frames=args.frames, units=args.units, alignment=args.alignment, coarse_weight=args.coarse_weight,
                         window=args.window, temporal_weight=args.temporal_weight, fine=args.fine, max_side=args.max_side or None,
                         flip=args.flip, png16=args.png16, ply=args.ply, ply_relief=args.ply_relief, overwrite=args.overwrite,
                         viewer=not args.no_viewer, mask=args.mask, focal=args.focal, centre=args.centre, sheet=args.sheet,
                         isometric_scale=args.isometric_scale, isometric_template=args.isometric_template, isometric_drop=args.isometric_drop)
    except ValueError as e:
        # The API names its arguments; the command line names its flags.
        name = str(e).split(":", 1)[0]
        if name in ("out", "roi", "frames", "max_side", "mask", "focal", "centre", "sheet", "isometric_scale", "isometric_template", "isometric_drop"):
            raise ValueError(f"--{name.replace('_', '-')}{str(e)[len(name):]}") from None
        raise
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start
    t, h, w = _npz_shape(out / "depth.npz", "depth")
    print(f"wrote {out}: depth of {t} frames of {w}×{h} in {seconds:.1f} s on {device} "
          f"(depth.npz, depth.mp4, side_by_side.mp4{'' if args.no_viewer else ', viewer.html'}{', png16/' if args.png16 else ''}{', ply/' if args.ply else ''})")
    return 0


def _npz_shape(path: Path, name: str) -> tuple:
    """The shape of array ``name`` in an .npz, read from its header alone."""
    import zipfile

    import numpy as np

    with zipfile.ZipFile(path) as archive, archive.open(f"{name}.npy") as f:
        version = np.lib.format.read_magic(f)
        read = np.lib.format.read_array_header_2_0 if version == (2, 0) else np.lib.format.read_array_header_1_0
        return read(f)[0]


def _demo(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .demo import demo_page, demo_picture, run_demo
    from .evaluate import TEST_SEED
    from .preview import save_png

    seed = TEST_SEED if args.seed is None else args.seed
    with tqdm(total=16, desc="frames", unit="frame", disable=args.quiet) as bar:
        result = run_demo(args.model, size=args.size, seed=seed, device=args.device, progress=lambda done, total: bar.update(done - bar.n))
    save_png(args.out, demo_picture(result))
    page = demo_page(result, Path(args.out).with_suffix(".html"))
    m, f = result["mae_sn"], result["flat"]
    t, h, w = result["video"].shape
    print(f"demo: a generated {w}×{h}×{t} deforming-surface video (seed {seed}), reconstructed in "
          f"{result['seconds']['reconstruct']:.1f} s")
    print(f"{'MAE-SN':26s}{'nrdepth':>10s}{'flat baseline':>16s}")
    print(f"{'align each frame':26s}{m['frame']:>10.4f}{f['frame']:>16.4f}")
    print(f"{'alignment from 1st frame':26s}{m['first']:>10.4f}{f['first']:>16.4f}")
    print(f"wrote {args.out}: frames | ground-truth depth | reconstruction (GBR-aligned per frame)")
    print(f"wrote {page}: the truth and the reconstruction in 3-D, one time slider (open it in a browser)")
    return 0


def _view(args: argparse.Namespace) -> int:
    from .viewer import view

    page = view(args.folder, path=args.out)
    print(f"wrote {page}: the depth video in 3-D (open it in a browser; it needs no network)")
    return 0


def _add_generator_options(p: argparse.ArgumentParser) -> None:
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


class _DefaultsFormatter(argparse.HelpFormatter):
    """Shows an option's default after its help, unless the help says it or there is none."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, False, argparse.SUPPRESS) or not action.option_strings:
            return text
        return f"{text} (default: {action.default})" if text else f"default: {action.default}"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nrdepth", description=__doc__)
    parser.add_argument("--version", action="version", version=f"nrdepth {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=lambda **kw: argparse.ArgumentParser(formatter_class=_DefaultsFormatter, **kw))

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
    _add_generator_options(p)
    p.set_defaults(run=_generate)

    p = sub.add_parser("train", help="train the depth network (online generation or a dataset); resumes in OUT")
    p.add_argument("out", help="run folder: config, checkpoints, weights, metrics")
    p.add_argument("--paper", action="store_true",
                   help="the paper's recipe: --arch unet3d --loss gbr --target depth --lr 1e-3 (default: the recommended one, "
                        "--arch unet2p1d_deep --loss aligned_both_signed --target observable --lr 3e-4); the options below override either")
    p.add_argument("--loss", default=None, help="gbr | tr_sc | aligned | aligned_clip | aligned_signed | aligned_clip_signed | aligned_both_signed | "
                   "aligned_clip_offsets_signed | aligned_both_offsets_signed | aligned_first | aligned_signed_first (default: aligned_both_signed; see nrdepth.losses)")
    p.add_argument("--arch", default=None, help="unet3d (the paper's) | unet2p1d (factorised, ~15x cheaper) | unet2p1d_global (unet2p1d whose coarsest level sees the whole clip in time) | unet2p1d_deep (unet2p1d with 4 more residual blocks on its coarsest level) (default: unet2p1d_deep)")
    p.add_argument("--schedule", default="cosine", help="cosine | constant (a campaign: --epochs may grow on resume) (default: cosine)")
    p.add_argument("--target", default=None,
                   help="depth (the rendered depth, the paper's) | observable (without the motion along the optical axis that no frame shows) (default: observable)")
    p.add_argument("--amplitude", type=float, default=0.0,
                   help="weight of the relief-amplitude term (targets in window widths; the model learns the relief's scale)")
    p.add_argument("--init", default=None, help="model.safetensors or run folder whose weights start a new run (a warm start)")
    p.add_argument("--epochs", type=int, default=20, help="epochs in the run")
    p.add_argument("--steps", type=int, default=500, help="steps per epoch")
    p.add_argument("--max-epochs", type=int, default=None, help="epochs to run in this call (resume later)")
    p.add_argument("--batch-size", type=int, default=8, help="clips per step")
    p.add_argument("--lr", type=float, default=None, help="Adam's learning rate (default: 3e-4; 1e-3 with --paper)")
    p.add_argument("--base", type=int, default=None, help="width of the first network stage (default: the architecture's, 16 / 24)")
    p.add_argument("--data", default=None, help="dataset folder; default: fresh clips every step")
    p.add_argument("--validation-clips", type=int, default=64, help="held-out clips scored after every epoch")
    p.add_argument("--real", default=None, metavar="NPZ", action="append",
                   help="a real video with ground truth, reconstructed and scored after every epoch (metrics.csv's real_* columns; it does not "
                        "choose the best weights); give it again for several (real_STEM_* columns). Dense: video uint8 (T, H, W), depth (T, H, W), "
                        "NaN where none (benchmarks/bench_real.py --write-phisft); sparse: video, frames, uv, z (benchmarks/bench_real.py --write-kinect)")
    p.add_argument("--ema", type=float, default=0.0, metavar="DECAY",
                   help="score and save an exponential moving average of the weights with this decay per step, e.g. 0.999 (default: 0, the weights themselves)")
    p.add_argument("--anchor", type=float, default=0.0, metavar="RATE",
                   help="with --init: after every step pull the weights back toward the warm start's by lr × RATE of the way "
                        "(L2-SP, decoupled; e.g. 100 at lr 5e-5 is 0.5 %% a step; default: 0, no pull)")
    p.add_argument("--keep-every", type=int, default=0, metavar="N",
                   help="also keep every N-th epoch's weights as epochs/epoch_E.safetensors (default: 0, none)")
    p.add_argument("--workers", type=int, default=2, help="DataLoader worker processes")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--compile", action="store_true", help="torch.compile the network")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_generator_options(p)
    p.set_defaults(run=_train)

    p = sub.add_parser("evaluate", help="held-out MAE-SN of a model beside the flat baseline")
    p.add_argument("model", help="model.safetensors or a run folder")
    p.add_argument("data", nargs="?", default=None, help="dataset folder (its test split); default: fresh held-out clips")
    p.add_argument("-o", "--out", default=None, help="folder for per_clip.csv and summary.json")
    p.add_argument("--clips", type=int, default=256, help="clips to score")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--readings", type=int, choices=(1, 2, 4), default=1,
                   help="readings of each clip averaged: 2 adds it mirrored left-right, 4 also upside down (nrdepth.predict_depth)")
    _add_generator_options(p)
    p.set_defaults(run=_evaluate)

    p = sub.add_parser("average", help="average the weights of models of one lineage (a model soup)")
    p.add_argument("out", help="output: a path ending in .safetensors, or a folder to write model.safetensors into (model.json beside it)")
    p.add_argument("models", nargs="+", help="two or more model.safetensors files or run folders")
    p.add_argument("--weights", type=_weights, default=None, metavar="W1,W2,...",
                   help="one weight per model, scaled to sum to 1 (default: equal)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output model")
    p.set_defaults(run=_average)

    p = sub.add_parser("reconstruct", help="depth video of a video file, an image folder or a .npy/.npz array",
                       description="Depth video of a video file, an image folder or a .npy/.npz array, streamed: memory does not grow with the "
                       "video's length. What a video costs on a 2-core CPU (measured with benchmarks/bench_video.py --long, every output "
                       "written): 0.17 s a frame at 640×480 and 0.22 s at 1920×1080 at the default --max-side 480; at their own size "
                       "(--max-side 0) 0.26 s and 2.2 s a frame. On a GPU: --device cuda (docs/reconstruction.md).")
    p.add_argument("input", help="video file (mp4, avi, gif, …), folder of images, or .npy/.npz (T, H, W[, 3])")
    p.add_argument("-o", "--out", default=None,
                   help="output folder: depth.npz, depth.mp4, side_by_side.mp4 [, png16/, ply/] (default: INPUT_depth here)")
    p.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    p.add_argument("--roi", type=_roi, default=None, help="region X,Y,W,H in pixels")
    p.add_argument("--frames", type=_frames, default=None, help="frames START:STOP[:STEP] (Python slice)")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--batch-size", type=int, default=8, help="clips per network call in the coarse pass (and with --fine patches)")
    p.add_argument("--max-side", type=int, default=MAX_SIDE,
                   help="reconstruct at a working size whose longer side is at most this many pixels, the depth resized back; 0: the video's own size "
                   "(the network reads relief at the scale of 64-pixel patches; docs/reconstruction.md)")
    p.add_argument("--fine", choices=FINE_PASSES, default=FINE_PASSES[0],
                   help="fine pass: field (the network once over the video, in tiles; default) or patches (every 64×64×16 window on its own, as the paper: 8× the work)")
    p.add_argument("--mask", default=None,
                   help="the surface's pixels: an image (every frame) or a video, image folder or .npy of the input's frames, white (128 or more of 255) "
                   "on the surface. Off it the depth is NaN (black in the videos, 0 in the PNGs, no PLY point, a hole in the viewer) and takes no part "
                   "in the alignments: for a background that moves on its own")
    p.add_argument("--focal", type=_pair("F or FX,FY in pixels", (1, 2)), default=None,
                   help="for a sheet (paper, cloth) filmed by a perspective camera: its focal length in pixels of the input's frames. The shape above "
                   "--isometric-scale then comes from inextensibility (points followed by optical flow over --sheet; nrdepth.isometric), the relief "
                   "below it from the network, and on a long video that bends the sheet many ways the relief's sign too (a short clip reads as a dome). "
                   "Holds the selected frames in memory; minutes for a few hundred frames")
    p.add_argument("--centre", type=_pair("CX,CY in pixels", (2,)), default=None, help="with --focal: the principal point in the input's frames (default: their centre)")
    p.add_argument("--sheet", type=_roi, default=None,
                   help="with --focal: a box X,Y,W,H of the first selected frame, in the input's pixels, on the sheet only (not the background or "
                   "the hands), where the points are spread (default: --roi, or the whole frame)")
    p.add_argument("--isometric-scale", type=float, default=ISOMETRIC_SCALE,
                   help=f"with --focal: the length below which the network's relief is kept, as a fraction of the frame's shorter side (default {ISOMETRIC_SCALE}; 0: the isometric depth alone)")
    p.add_argument("--isometric-template", choices=TEMPLATES, default="joint",
                   help="with --focal: the pairs' template distances (nrdepth.isometric.mdh_depths): joint (the default), refined (each pair held to "
                   "its distance in every keyframe; for a long video of a sheet bent many ways, with --isometric-drop 0.3 --isometric-scale 0.2), first "
                   "(the first frame a flat sheet facing the camera)")
    p.add_argument("--isometric-drop", type=float, default=ISOMETRIC_DROP,
                   help=f"with --focal: the share of the points left out where the flow's two directions disagree most (default {ISOMETRIC_DROP})")
    p.add_argument("--png16", action="store_true", help="also write 16-bit PNG depth frames (0: no depth; 1 … 65535 span depth.npz's png16_range)")
    p.add_argument("--ply", action="store_true", help="also write a PLY point cloud per frame")
    p.add_argument("--ply-relief", type=float, default=None,
                   help="PLY depth standard deviation in frame widths (default: 0.073, as the training surfaces)")
    p.add_argument("--temporal-align", action="store_true",
                   help="give every frame frame 0's plane and relief norm (nrdepth.temporal_align): for models trained with per-frame losses only")
    p.add_argument("--units", choices=("standard", "pixels"), default="standard",
                   help="depth.npz's scale: standard (unit std over the video) or pixels (the relief's scale as a model trained with --amplitude reads it; "
                   "without --model, the shipped one that learnt it)")
    p.add_argument("--alignment", choices=ALIGNMENTS, default=ALIGNMENTS[0],
                   help="how the patches are aligned: joint (all together, agreeing where they overlap, tied to the coarse pass by --coarse-weight; default) "
                   "or coarse (each on its own to the coarse pass, as the paper)")
    p.add_argument("--coarse-weight", type=float, default=COARSE_WEIGHT,
                   help=f"the joint alignment's weight on the coarse pass (default {COARSE_WEIGHT}; smaller trusts the patches' agreement more)")
    p.add_argument("--temporal-weight", type=float, default=TEMPORAL_WEIGHT,
                   help=f"the joint alignment's tie of each patch's GBR to the frame before, as much as the patch holds still (default {TEMPORAL_WEIGHT}; 0: frames on their own)")
    p.add_argument("--window", choices=WINDOWS, default=WINDOWS[0],
                   help="the overlap-add window: hann (default; no seams) or triangle (the paper's; the paper's stitch is --alignment coarse --window triangle)")
    p.add_argument("--no-viewer", action="store_true", help="skip viewer.html, the 3-D page of the depth video (nrdepth view OUT writes it later)")
    p.add_argument("--flip", action="store_true", help="negate the depth: the other convex/concave reading (the model assumes light from above; use for a video lit from below)")
    p.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_reconstruct)

    p = sub.add_parser("view", help="write viewer.html, the 3-D page of a reconstruction folder (nrdepth reconstruct writes it by default)")
    p.add_argument("folder", help="a folder written by nrdepth reconstruct (depth.npz, side_by_side.mp4)")
    p.add_argument("-o", "--out", default=None, help="the page (default: FOLDER/viewer.html)")
    p.set_defaults(run=_view)

    p = sub.add_parser("demo", help="reconstruct a synthesised 256×256×16 video and score it against its true depth")
    p.add_argument("out", nargs="?", default="demo.png", help="output PNG (default: demo.png); the 3-D page goes beside it (demo.html)")
    p.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    p.add_argument("--size", type=int, default=256, help="video side in pixels")
    p.add_argument("--seed", type=int, default=None, help="generator seed (default: nrdepth.evaluate.TEST_SEED, held out)")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_demo)

    p = sub.add_parser("preview", help="picture of sample clips and of the surface parameter sweep")
    p.add_argument("out", nargs="?", default="preview.png", help="output PNG (default: preview.png)")
    p.add_argument("--clips", type=int, default=3, help="sample clips (rows)")
    _add_generator_options(p)
    p.set_defaults(run=_preview)
    return parser


VALUE_MAY_START_WITH_DASH = ("--roi", "--frames", "--light-azimuth")
"""Options whose value can begin with '-' (a negative number): argparse would
take ``--roi -10,0,9,9`` for two options, so such pairs are joined with '='."""


def _join_dash_values(argv: Sequence[str]) -> list:
    joined, i = [], 0
    while i < len(argv):
        if argv[i] in VALUE_MAY_START_WITH_DASH and i + 1 < len(argv) and argv[i + 1].startswith("-") and argv[i + 1][1:2].isdigit():
            joined.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            joined.append(argv[i])
            i += 1
    return joined


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_join_dash_values(sys.argv[1:] if argv is None else list(argv)))
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError, ImportError) as e:  # ImportError: an optional dependency, named with its pip extra
        print(f"nrdepth {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nrdepth {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
