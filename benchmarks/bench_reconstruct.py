"""The main job on generated videos: its time and accuracy, and flat sheets in, flat out.

``job``: Reconstruction of whole videos: time and accuracy.

1. Time to reconstruct a 256×256×16 video, split into the network half
   (coarse pass + every patch, with cutting and resizing) and the Rust half
   (alignment and overlap-add: the default stitch, and the paper's;
   temporal alignment), on the CPU and on CUDA when present. The shipped
   model unless --model.
2. The stitched MAE-SN of generated 256×256×16 videos drawn inside the
   training ranges and, as in the paper's second experiment, outside them
   (stronger, more flexible, more folded, faster surfaces), both MAE-SN
   alignments, beside the flat baseline. The same patches stitched four
   ways: the default (joint alignment, ``--coarse-weight``, Hann windows),
   the paper's (each patch aligned to the coarse pass on its own, triangle
   windows), and the two mixed ones; the default then temporally aligned;
   the coarse pass alone. Then each stitch's contrast at the 32-pixel patch
   period (``nrdepth.grid_contrast``: seams), beside the truth's, over the
   whole frame and over its inner 192×192 pixels (one patch period left
   out at each border).

    python benchmarks/bench_reconstruct.py job [--model PATH] [--videos 8] [--repeats 3] [--seed S] [--coarse-weight MU]

``flat``: Flat in, flat out: the flat textured sheets of the test suite
(``tests/test_reconstruct.py``: tilted, turning, lit from above, vertices
fixed in the image) reconstructed in pixels, and the same sheets with bumps
whose RMS is 3 % of the frame's width. Prints, per texture family, the
largest over frames of the reconstruction's residual about its best plane
over the true depth's standard deviation (the test asks for < 0.2 on the
flat sheet), and the bumps' reconstructed relief over their true relief
(geometric mean over frames; 1 is right).

    python benchmarks/bench_reconstruct.py flat [--model PATH] [--families fractal,weave,plaid,stripes,cells]

    python benchmarks/bench_reconstruct.py job [--help]
    python benchmarks/bench_reconstruct.py flat [--help]
"""

from __future__ import annotations

# ---- job ------------------------------------------------------------
MAIN_JOB_DOC = "Reconstruction of whole videos: time and accuracy.\n\n1. Time to reconstruct a 256×256×16 video, split into the network half\n   (coarse pass + every patch, with cutting and resizing) and the Rust half\n   (alignment and overlap-add: the default stitch, and the paper's;\n   temporal alignment), on the CPU and on CUDA when present. The shipped\n   model unless --model.\n2. The stitched MAE-SN of generated 256×256×16 videos drawn inside the\n   training ranges and, as in the paper's second experiment, outside them\n   (stronger, more flexible, more folded, faster surfaces), both MAE-SN\n   alignments, beside the flat baseline. The same patches stitched four\n   ways: the default (joint alignment, ``--coarse-weight``, Hann windows),\n   the paper's (each patch aligned to the coarse pass on its own, triangle\n   windows), and the two mixed ones; the default then temporally aligned;\n   the coarse pass alone. Then each stitch's contrast at the 32-pixel patch\n   period (``nrdepth.grid_contrast``: seams), beside the truth's, over the\n   whole frame and over its inner 192×192 pixels (one patch period left\n   out at each border).\n\n    python benchmarks/bench_reconstruct.py job [--model PATH] [--videos 8] [--repeats 3] [--seed S] [--coarse-weight MU]\n"
import argparse
import time

import numpy as np
import torch

import nrdepth
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth import _core
from nrdepth.reconstruct import coarse_depth, inference_model, patch_depths
from nrdepth.scores.generated import out_of_range
from nrdepth.reconstruct.stitch import COARSE_WEIGHT, TEMPORAL_WEIGHT, temporal_align


def timing(model, device: str, repeats: int) -> None:
    video = nrdepth.generate_clips(1, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256)).video[0]
    dev = torch.device(device)
    net = inference_model(model, dev)
    layout = nrdepth.patch_layout(video.shape)

    def run() -> dict:
        seconds = {"network": 0.0, "stitch": 0.0, "paper": 0.0, "temporal": 0.0}
        start = time.perf_counter()
        coarse = coarse_depth(video, net, 8, dev)
        default, paper = _core.Stitcher(coarse, layout.patch, "hann", COARSE_WEIGHT), _core.Stitcher(coarse, layout.patch, "triangle")
        chunks = patch_depths(video, net, layout, 8, dev)
        while True:
            try:
                origins, depth = next(chunks)
            except StopIteration:
                break
            middle = time.perf_counter()
            seconds["network"] += middle - start
            default.add(depth, origins)
            after = time.perf_counter()
            paper.add(depth, origins)
            start = time.perf_counter()
            seconds["stitch"] += after - middle
            seconds["paper"] += start - after
        seconds["network"] += time.perf_counter() - start
        middle = time.perf_counter()
        stitched = default.finish()
        after = time.perf_counter()
        paper.finish()
        seconds["stitch"] += after - middle
        seconds["paper"] += time.perf_counter() - after
        start = time.perf_counter()
        temporal_align(stitched)
        seconds["temporal"] = time.perf_counter() - start
        return seconds

    run()  # warm-up
    best = min((run() for _ in range(repeats)), key=lambda s: s["network"] + s["stitch"] + s["temporal"])
    print(f"256×256×16 on {device} ({len(layout.origins)} patches + {-(-len(video) // 16)} coarse window(s), torch threads "
          f"{torch.get_num_threads()}), best of {repeats}: total {best['network'] + best['stitch'] + best['temporal']:.2f} s = network "
          f"{best['network']:.2f} s + stitching {best['stitch'] * 1e3:.0f} ms + temporal alignment {best['temporal'] * 1e3:.0f} ms "
          f"(the paper's stitch instead: {best['paper'] * 1e3:.0f} ms)")


def accuracy(model, videos: int, device: str, seed: int = TEST_SEED, coarse_weight: float = COARSE_WEIGHT) -> None:
    base = nrdepth.GeneratorConfig(size=256)
    dev = torch.device(device)
    net = inference_model(model, dev)
    stitches = {  # (alignment, window) → row label
        ("joint", "hann"): f"nrdepth (default: joint alignment, μ = {coarse_weight:g}, ν = {TEMPORAL_WEIGHT:g}, Hann windows)",
        ("coarse", "triangle"): "the paper's stitch (coarse alignment, triangle windows)",
        ("joint", "triangle"): "joint alignment, triangle windows",
        ("coarse", "hann"): "coarse alignment, Hann windows",
    }
    print(f"MAE-SN over {videos} generated 256×256×16 videos (seed {seed}), mean ± std")
    print(f"{'':72s}{'per frame':>18s}{'from 1st frame':>18s}")
    for name, config in (("inside training ranges", base), ("outside training ranges", out_of_range(base))):
        clips = nrdepth.generate_clips(videos, seed=seed, config=config)
        rows = {k: [] for k in (*stitches.values(), "the default with temporal_align", "coarse pass alone", "flat baseline")}
        grid = {k: [] for k in (*stitches.values(), "truth")}
        for video, truth in zip(clips.video, clips.depth):
            layout = nrdepth.patch_layout(video.shape)
            coarse = coarse_depth(video, net, 8, dev)
            patches = np.concatenate([depth for _, depth in patch_depths(video, net, layout, 8, dev)])
            depths = {label: nrdepth.stitch(patches, coarse, layout, alignment=a, coarse_weight=coarse_weight, window=w) for (a, w), label in stitches.items()}
            default = depths[stitches["joint", "hann"]]
            for key, depth in {**depths, "the default with temporal_align": temporal_align(default), "coarse pass alone": coarse}.items():
                rows[key].append([nrdepth.mae_sn(depth, truth, a) for a in ("frame", "first")])
            rows["flat baseline"].append([nrdepth.flat_baseline(truth, a) for a in ("frame", "first")])
            # Whole frame, and without a patch period at each border (where patches reach into the padding).
            for key, depth in {**depths, "truth": truth}.items():
                grid[key].append([nrdepth.grid_contrast(depth[:, c:-c or None, c:-c or None]) for c in (0, 32)])
        print(name)
        for key, values in rows.items():
            v = np.array(values)
            print(f"  {key:72s}{v[:, 0].mean():>9.4f} ± {v[:, 0].std():.4f}{v[:, 1].mean():>9.4f} ± {v[:, 1].std():.4f}")
        print("  contrast at the 32-pixel patch period (about 1 without a grid; seams show above the truth's, missing grid frequencies below):")
        print(f"  {'':72s}{'whole frame':>18s}{'inner 192×192':>18s}")
        for key, values in grid.items():
            g = np.array(values)
            print(f"  {key:72s}{g[:, 0].mean():>9.3f} ± {g[:, 0].std():.3f} {g[:, 1].mean():>9.3f} ± {g[:, 1].std():.3f}")


def main_job() -> None:
    parser = argparse.ArgumentParser(description=MAIN_JOB_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--videos", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=TEST_SEED, help=f"generator seed of the scored videos (default {TEST_SEED}, held out)")
    parser.add_argument("--coarse-weight", type=float, default=COARSE_WEIGHT, help=f"the joint alignment's weight on the coarse pass (default {COARSE_WEIGHT})")
    args = parser.parse_args()
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    for device in devices:
        timing(args.model, device, args.repeats)
    accuracy(args.model, args.videos, devices[-1], args.seed, args.coarse_weight)

# ---- flat ------------------------------------------------------------
MAIN_FLAT_DOC = "Flat in, flat out: the flat textured sheets of the test suite\n(``tests/test_reconstruct.py``: tilted, turning, lit from above, vertices\nfixed in the image) reconstructed in pixels, and the same sheets with bumps\nwhose RMS is 3 % of the frame's width. Prints, per texture family, the\nlargest over frames of the reconstruction's residual about its best plane\nover the true depth's standard deviation (the test asks for < 0.2 on the\nflat sheet), and the bumps' reconstructed relief over their true relief\n(geometric mean over frames; 1 is right).\n\n    python benchmarks/bench_reconstruct.py flat [--model PATH] [--families fractal,weave,plaid,stripes,cells]\n"
import sys
from pathlib import Path


import nrdepth.model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_reconstruct import FLAT_SHEET_WINDOW, flat_sheet_residual, flat_sheet_video, plane_residuals  # noqa: E402


def main_flat() -> None:
    parser = argparse.ArgumentParser(description=MAIN_FLAT_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="a model with a depth scale (default: the shipped nrdepth.model.SCALED_MODEL)")
    parser.add_argument("--families", default="fractal,weave,plaid,stripes,cells")
    args = parser.parse_args()
    model = nrdepth.model.load_model(args.model or nrdepth.model.SCALED_MODEL)
    print(f"{'texture':10s}{'flat: residual / depth std':>28s}{'bumps: relief / true':>24s}")
    for family in args.families.split(","):
        flat_video, flat_depth = flat_sheet_video(family)
        bumps_video, bumps_depth = flat_sheet_video(family, relief=0.08)
        to_pixels = flat_video.shape[2] / FLAT_SHEET_WINDOW
        flat = flat_sheet_residual(nrdepth.reconstruct(flat_video, model, device="cpu", units="pixels"), flat_depth * to_pixels)
        ratio = plane_residuals(nrdepth.reconstruct(bumps_video, model, device="cpu", units="pixels")) / plane_residuals(bumps_depth * to_pixels)
        print(f"{family:10s}{flat:>28.3f}{np.exp(np.log(ratio).mean()):>24.3f}")


COMMANDS = {"job": main_job, "flat": main_flat}


if __name__ == "__main__":
    import sys

    command = sys.argv.pop(1) if sys.argv[1:] and sys.argv[1] in COMMANDS else sys.exit(f"usage: {sys.argv[0]} {{{'|'.join(COMMANDS)}}} [--help]")
    COMMANDS[command]()
