"""The paper's Table 2, rerun: generated 256×256×16 videos drawn outside the
training ranges (as ``bench_reconstruct.py``: intensity, folding,
flexibility and speed from the training maximum to 1.6× it), each
reconstructed by nrdepth (the shipped model unless --model), by CSF2 from
exact tracks of up to 33×33 mesh vertices (nrdepth.baselines.tracks; optional pixel
noise) interpolated to every pixel, and by a flat plane; MAE-SN mean ± std
for both alignments beside the paper's figures; KSTA (our reading of its
paper, nrdepth.baselines.nrsfm.ksta) from the same tracks.

    python benchmarks/bench_table2.py [--videos 100] [--K 2] [--d 4] [--noise 0] [--picture docs/benchmarks/table2.png]
    # split over processes, then one table from their rows:
    python benchmarks/bench_table2.py --videos 50 --start 0 --rows a.csv & python benchmarks/bench_table2.py --videos 50 --start 50 --rows b.csv
    python benchmarks/bench_table2.py --summarise a.csv b.csv
    # rerun some methods only (e.g. after a change to KSTA); --summarise joins rows by video
    python benchmarks/bench_table2.py --methods KSTA --rows ksta.csv && python benchmarks/bench_table2.py --summarise all.csv ksta.csv
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

import nrdepth
import nrdepth.model
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.baselines.nrsfm import cameras, csf2, ksta
from nrdepth.baselines.tracks import clip_tracks, densify, measurement_matrix, nrsfm_depth

from nrdepth.scores.generated import out_of_range

PAPER = {"nrdepth": (0.5907, 0.4536), "CSF2": (0.8746, 0.6372), "KSTA": (0.8738, 0.6369)}
"""The paper's Table 2 (per-frame MAE-SN, mean ± std over 1,000 videos)."""


METHODS = ("nrdepth", "CSF2", "KSTA", "flat plane")


def summarise(rows: list, header: str) -> None:
    print(header)
    print(f"{'':14s}{'per frame':>18s}{'from 1st frame':>18s}{'paper, per frame':>20s}{'seconds a video':>17s}")
    for name in [m for m in METHODS if f"{m} frame" in rows[0]]:
        frame = np.array([float(r[f"{name} frame"]) for r in rows])
        first = np.array([float(r[f"{name} first"]) for r in rows])
        paper = f"{PAPER[name][0]:.4f} ± {PAPER[name][1]:.4f}" if name in PAPER else ""
        sec = f"{np.mean([float(r[f'{name} seconds']) for r in rows]):.1f}" if f"{name} seconds" in rows[0] else ""
        print(f"{name:14s}{frame.mean():>9.4f} ± {frame.std():.4f}{first.mean():>9.4f} ± {first.std():.4f}{paper:>20s}{sec:>17s}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None)
    parser.add_argument("--videos", type=int, default=100)
    parser.add_argument("--start", type=int, default=0, help="index of the first video")
    parser.add_argument("--K", type=int, default=2, help="CSF2's and KSTA's rank-3 spaces")
    parser.add_argument("--d", type=int, default=4, help="CSF2's DCT functions and KSTA's kernel ones (of 16 frames)")
    parser.add_argument("--methods", default=",".join(METHODS), help="comma list of the methods to run")
    parser.add_argument("--noise", type=float, default=0.0, help="pixel noise on the tracks")
    parser.add_argument("--picture", type=Path, default=None, help="PNG of the first video: frames | truth | nrdepth | CSF2 | KSTA")
    parser.add_argument("--rows", type=Path, default=None, help="CSV of every video's scores, written as they come")
    parser.add_argument("--summarise", type=Path, nargs="+", default=None, help="print the table of these --rows files and stop")
    args = parser.parse_args()
    if args.summarise:
        joined: dict = {}  # video → its scores; a later file's columns replace an earlier one's
        for path in args.summarise:
            for r in csv.DictReader(path.open()):
                joined.setdefault(r["video"], {}).update(r)
        rows = list(joined.values())
        summarise(rows, f"MAE-SN over {len(rows)} generated 256×256×16 videos outside the training ranges (seed {TEST_SEED}), from {', '.join(map(str, args.summarise))}")
        return
    methods = args.methods.split(",")
    if not set(methods) <= set(METHODS) or (args.picture is not None and set(methods) != set(METHODS)):
        parser.error(f"--methods: expected a comma list of {', '.join(METHODS)} (all of them with --picture)")
    config = out_of_range(nrdepth.GeneratorConfig(size=256))
    model = nrdepth.model.load_model(args.model) if "nrdepth" in methods else None
    rows = []
    writer = None
    for i in range(args.start, args.start + args.videos):
        clip = nrdepth.generate_clips(1, seed=TEST_SEED, config=config, start=i)
        video, truth = clip.video[0], clip.depth[0]
        depths, seconds = {}, {}
        if "nrdepth" in methods:
            start = time.perf_counter()
            depths["nrdepth"] = nrdepth.reconstruct(video, model)
            seconds["nrdepth"] = time.perf_counter() - start
        if {"CSF2", "KSTA"} & set(methods):  # the tracks and cameras only the baselines use
            tracks = clip_tracks(clip.params[0], config, noise=args.noise, seed=i)
            W = measurement_matrix(tracks.xy)
            Rs = cameras(W)
        for name, method in (("CSF2", csf2), ("KSTA", ksta)):
            if name not in methods:
                continue
            start = time.perf_counter()
            result = method(W, K=args.K, d=args.d, Rs=Rs)
            depths[name] = densify(tracks.xy, nrsfm_depth(result.shapes, result.cameras), truth.shape)
            seconds[name] = time.perf_counter() - start
        if "flat plane" in methods:
            depths["flat plane"] = np.zeros_like(truth)
        row = {"video": i}
        for name, depth in depths.items():
            row.update({f"{name} {a}": nrdepth.mae_sn(depth, truth, a) for a in ("frame", "first")})
            if name in seconds:
                row[f"{name} seconds"] = seconds[name]
        rows.append(row)
        if args.rows is not None:
            if writer is None:
                handle = args.rows.open("w", newline="")
                writer = csv.DictWriter(handle, fieldnames=list(row))
                writer.writeheader()
            writer.writerow(row)
            handle.flush()
        if i == args.start and args.picture is not None:
            from nrdepth.io.figures import ColourBar, labelled
            from nrdepth.engine.preview import save_png
            from nrdepth.io import colorize_depth, depth_range

            value_range = depth_range(truth)
            columns = [np.repeat(video[..., None], 3, axis=-1)] + [colorize_depth(nrdepth.gbr_align(d, truth), value_range) for d in (truth, depths["nrdepth"], depths["CSF2"], depths["KSTA"])]
            picture_rows = [np.concatenate([np.pad(c[t], ((2, 2), (2, 2), (0, 0)), constant_values=255) for c in columns], axis=1) for t in (0, 8, 15)]
            save_png(args.picture, labelled(np.concatenate(picture_rows), ["frames", "truth", "nrdepth", "CSF2", "KSTA"], 260,
                                            colour_bar=ColourBar(*value_range, "depth (half-widths of the patch)")))
    summarise(rows, f"MAE-SN over {args.videos} generated 256×256×16 videos outside the training ranges (seed {TEST_SEED}); "
                    f"CSF2 and KSTA with K={args.K}, d={args.d}, tracks of up to 33×33 vertices, pixel noise {args.noise}")


if __name__ == "__main__":
    main()
