"""The ``nrdepth`` command line: a thin layer over the Python API."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Optional, Sequence

from . import __version__


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

    return GeneratorConfig(frames=args.frames, size=args.size, grid=args.grid, textures=args.textures)


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
    from .train import TrainConfig, train

    config = TrainConfig(
        loss=args.loss, base=args.base, batch_size=args.batch_size, steps_per_epoch=args.steps, epochs=args.epochs,
        lr=args.lr, seed=args.seed, data=args.data, generator=_generator_config(args),
        validation_clips=args.validation_clips, workers=args.workers, device=args.device, compile=args.compile,
    )
    summary = train(args.out, config, progress=not args.quiet, max_epochs=args.max_epochs)
    if summary:
        print(json.dumps(summary, indent=2))
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from .evaluate import evaluate, format_summary

    summary = evaluate(args.model, args.data, args.out, clips=args.clips, config=_generator_config(args), device=args.device)
    print(format_summary(summary))
    return 0


def _add_generator_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seed", type=int, default=0, help="run seed: clip i is a pure function of (config, seed, i)")
    p.add_argument("--textures", default=None, help="folder of PNG/JPEG images to crop textures from (default: procedural)")
    p.add_argument("--frames", type=int, default=16, help="frames per clip")
    p.add_argument("--size", type=int, default=64, help="image side in pixels")
    p.add_argument("--grid", type=int, default=64, help="mesh vertices per side")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nrdepth", description=__doc__)
    parser.add_argument("--version", action="version", version=f"nrdepth {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

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
    p.add_argument("--loss", default="gbr", help="gbr | tr_sc | aligned")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--steps", type=int, default=500, help="steps per epoch")
    p.add_argument("--max-epochs", type=int, default=None, help="epochs to run in this call (resume later)")
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--base", type=int, default=16, help="width of the first network stage")
    p.add_argument("--data", default=None, help="dataset folder; default: fresh clips every step")
    p.add_argument("--validation-clips", type=int, default=64)
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
    p.add_argument("--device", default="auto")
    _add_generator_options(p)
    p.set_defaults(run=_evaluate)

    p = sub.add_parser("preview", help="picture of sample clips and of the surface parameter sweep")
    p.add_argument("out", nargs="?", default="preview.png", help="output PNG (default: preview.png)")
    p.add_argument("--clips", type=int, default=3, help="sample clips (rows)")
    _add_generator_options(p)
    p.set_defaults(run=_preview)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError) as e:
        print(f"nrdepth {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
