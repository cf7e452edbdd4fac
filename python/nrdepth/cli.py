"""The ``nrdepth`` command line: a thin layer over the Python API."""

from __future__ import annotations

import argparse
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
