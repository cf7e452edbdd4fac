"""``nrdepth reconstruct``, ``view`` and ``demo``: the main job's commands."""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ..engine.preview import save_png
from ..io.decode import npz_header
from ..io.viewer import view
from ..reconstruct import reconstruct_file
from ..reconstruct.api import SheetFallback
from ..reconstruct.decision import SheetDecision
from ..reconstruct.batch import ENGINES, THREADS, reconstruct_many
from ..reconstruct.options import add_flags, flag_of, options_from_flags

__all__ = ["add_commands"]


def _reconstruct(args: argparse.Namespace) -> int:
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
        # Everything that can be refused is checked before any work or writing.
        options = options_from_flags(args)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SheetFallback)  # said below, in the sheet's line
            reconstruct_file(args.input, out, args.model, options, progress=progress)
    except (ValueError, TypeError) as e:
        raise _with_flags(e) from None
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start
    (t, h, w), _ = npz_header(out / "depth.npz", "depth")
    with np.load(out / "depth.npz") as saved:  # the sheet stage's decision, in one line (depth.npz keeps it as "sheet")
        if "sheet" in saved:
            print(SheetDecision.from_dict(json.loads(str(saved["sheet"]))).line())
        network = json.loads(str(saved["network"]))
    print(f"wrote {out}: depth of {t} frames of {w}×{h} in {seconds:.1f} s on {network['device']} ({network['precision']}) "
          f"(depth.npz, depth.mp4, side_by_side.mp4{', viewer.html' if options.viewer else ''}{', png16/' if options.png16 else ''}{', ply/' if options.ply else ''})")
    return 0


def _with_flags(error: Exception) -> Exception:
    """The API names its arguments (error.option); the command line names its flags."""
    option = getattr(error, "option", None)
    if option is None or option in ("input", "inputs"):
        return error
    return type(error)(f"{flag_of(option)}: {error.detail}")


def _reconstruct_many(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    frames, start = 0, time.perf_counter()
    bar = None

    def progress(done: int, total: int, row) -> None:
        nonlocal bar, frames
        if bar is None:
            bar = tqdm(total=total, initial=done, desc="videos", unit="video", disable=args.quiet)
            return
        frames += row.frames if row.status == "done" else 0
        bar.set_postfix_str(f"{frames / (time.perf_counter() - start):.1f} frames/s", refresh=False)
        bar.update(done - bar.n)
        if row.status == "failed":
            bar.write(f"failed: {row.input}: {row.error}", file=sys.stderr)

    try:
        options = options_from_flags(args)
        rows = reconstruct_many(args.inputs, args.out, args.model, options, engine=args.engine, workers=args.workers,
                                threads=args.threads, address=args.address, progress=progress)
    except (ValueError, TypeError) as e:
        raise _with_flags(e) from None
    finally:
        if bar is not None:
            bar.close()
    counts = {status: sum(r.status == status for r in rows) for status in ("done", "skipped", "failed")}
    print(f"wrote {Path(args.out) / 'summary.csv'}: {len(rows)} videos, {counts['done']} done, {counts['skipped']} complete before, "
          f"{counts['failed']} failed, in {time.perf_counter() - start:.1f} s")
    return 1 if counts["failed"] else 0


def _demo(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from ..demo import demo_page, demo_picture, run_demo
    from ..learning.evaluate import TEST_SEED
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
    page = view(args.folder, path=args.out)
    print(f"wrote {page}: the depth video in 3-D (open it in a browser; it needs no network)")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reconstruct", help="depth video of a video file, an image folder or a .npy/.npz array",
                       description="Depth video of a video file, an image folder or a .npy/.npz array, streamed: memory does not grow with the "
                       "video's length. The flags are the fields of nrdepth.ReconstructOptions; what a video costs: docs/benchmarks.md.")
    p.add_argument("input", help="video file (mp4, avi, gif, …), folder of images, or .npy/.npz (T, H, W[, 3])")
    p.add_argument("-o", "--out", default=None,
                   help="output folder: depth.npz, depth.mp4, side_by_side.mp4 [, png16/, ply/] (default: INPUT_depth here)")
    p.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    add_flags(p)  # one flag per field of nrdepth.ReconstructOptions
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_reconstruct)

    p = sub.add_parser("reconstruct-many", help="reconstruct many videos, each into its own folder, side by side (here or on Ray)",
                       description="nrdepth reconstruct on every video of INPUTS, each into OUT/NAME, with the same options; a video whose "
                       "folder is complete is skipped, so a rerun resumes; a video that fails is reported in OUT/summary.csv and the others "
                       "go on. Exit status 1 if any video failed.")
    p.add_argument("inputs", nargs="+", help="videos, image folders, folders of videos, glob patterns (quoted) or .txt files listing videos")
    p.add_argument("-o", "--out", required=True, help="the batch's folder: a folder per video and summary.csv")
    p.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    p.add_argument("--engine", choices=ENGINES, default="local",
                   help="local: a process pool on this machine; ray: Ray tasks on a cluster (pip install 'nrdepth[ray]')")
    p.add_argument("--workers", type=int, default=None, help=f"local: videos at a time (default: one per {THREADS} cores, or per GPU with "
                   "--device cuda)")
    p.add_argument("--threads", type=int, default=None, help="torch threads (Ray: CPUs) per video (default: local, the cores shared "
                   f"between the workers; ray, {THREADS} or a node's CPUs if fewer)")
    p.add_argument("--address", default=None, help="ray: the cluster's address (default: a running one, else one started here)")
    add_flags(p, leave_out=("overwrite",))  # one flag per field of nrdepth.ReconstructOptions
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_reconstruct_many)

    p = sub.add_parser("view", help="write viewer.html, the 3-D page of a reconstruction folder (nrdepth reconstruct writes it by default)")
    p.add_argument("folder", help="a folder written by nrdepth reconstruct (depth.npz, side_by_side.mp4)")
    p.add_argument("-o", "--out", default=None, help="the page (default: FOLDER/viewer.html)")
    p.set_defaults(run=_view)

    p = sub.add_parser("demo", help="reconstruct a synthesised 256×256×16 video and score it against its true depth")
    p.add_argument("out", nargs="?", default="demo.png", help="output PNG (default: demo.png); the 3-D page goes beside it (demo.html)")
    p.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    p.add_argument("--size", type=int, default=256, help="video side in pixels")
    p.add_argument("--seed", type=int, default=None, help="generator seed (default: nrdepth.learning.evaluate.TEST_SEED, held out)")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_demo)
