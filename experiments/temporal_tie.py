"""The joint alignment's temporal tie (``rust/joint.rs``): scores the
stitcher at several temporal weights ν (``--weights``, per pixel of a patch;
0 solves each frame on its own) beside the paper's stitch of the same
patches, on ``bench_reconstruct.py``'s generated videos inside and outside
the training ranges and ``bench_real.py``'s crop of ``phisft_R1``: MAE-SN
per frame / from the first frame, paired differences to the first weight
(mean ± standard error over the videos) and the stitch's time a video.

The stitcher solves the tie in temporal blocks of the hop, each together
with the block after it, so it streams. ``--symmetric NU`` adds the
prototype it came from, in scipy: the same tie at ν exp(−(1 − ρ)/``--scale``)
a patch-frame, solved for the whole video at once (``--lags whole``;
scipy's sparse direct solver: small videos only, so not a stitcher) or in
blocks, LAG blocks ahead (``--lags 1`` is the stitcher's scheme).

    python experiments/temporal_tie.py [--model PATH] [--videos 8] [--seed S] [--weights 0,0.004,0.0075,0.015] [--symmetric 30 [--lags whole,0,1]]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
import torch

import nrdepth

from nrdepth.scores.generated import out_of_range
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.reconstruct import coarse_depth, inference_model, patch_depths
from nrdepth.reconstruct.stitch import COARSE_WEIGHT, patch_layout
from nrdepth.scores.real import phisft_at_bin


def tied_stitch(patches: np.ndarray, coarse: np.ndarray, mu: float, nu: float, scale: float | None, lag: int | None = None) -> np.ndarray:
    """The joint alignment with Hann windows and the temporal tie (module docstring); ``lag``: solve in blocks (below)."""
    t_len, h, w = coarse.shape
    layout = patch_layout(coarse.shape)
    lt, ls, _ = layout.patch
    pt, py, px = layout.pad
    hann = lambda n: np.sin(np.pi * (np.arange(n) + 0.5) / n) ** 2  # noqa: E731
    wt, ws = hann(lt), hann(ls)
    yy, xx = np.mgrid[0:ls, 0:ls]
    u, v = (xx + 0.5) / ls - 0.5, (yy + 0.5) / ls - 0.5
    index, standardised = {}, {}
    stitch_rows, rows, cols, window_vals, design_vals, pixels, roots = [], [], [], [], [], [], []
    r0 = 0
    for n, (ot, oy, ox) in enumerate(layout.origins):
        gy, gx = oy - py + yy, ox - px + xx
        inside = (gy >= 0) & (gy < h) & (gx >= 0) & (gx < w)
        if not inside.any():
            continue
        pix, m = gy[inside] * w + gx[inside], int(inside.sum())
        for f in range(lt):
            t = ot - pt + f
            if not 0 <= t < t_len:
                continue
            p = patches[n, f][inside].astype(np.float64)
            p = (p - p.mean()) / (p.std() if p.std() > 0 else 1.0)
            a = np.stack([u[inside], v[inside], p, np.ones(m)], 1)
            weight = wt[f] * ws[yy[inside]] * ws[xx[inside]]
            k = index[(n, t)] = len(index)
            standardised[(n, t)] = p
            for j in range(4):
                stitch_rows.append(t * h * w + pix)
                rows.append(r0 + np.arange(m))
                cols.append(np.full(m, 4 * k + j))
                window_vals.append(weight * a[:, j])
                design_vals.append(a[:, j])
            pixels.append(t * h * w + pix)
            roots.append(np.sqrt(weight))
            r0 += m
    unknowns = 4 * len(index)
    col = np.concatenate(cols)
    stitched = sp.csr_matrix((np.concatenate(window_vals), (np.concatenate(stitch_rows), col)), shape=(t_len * h * w, unknowns))
    design = sp.csr_matrix((np.concatenate(design_vals), (np.concatenate(rows), col)), shape=(r0, unknowns))
    root = sp.diags(np.concatenate(roots))
    pick = sp.csr_matrix((np.ones(r0), (np.arange(r0), np.concatenate(pixels))), shape=(r0, t_len * h * w))
    disagreement = root @ (design - pick @ stitched)
    tie_rows, tie_cols, tie_vals, count = [], [], [], 0
    for (n, t), k in index.items():
        nxt = index.get((n, t + 1))
        if nxt is None:
            continue
        rho = float(np.mean(standardised[(n, t)] * standardised[(n, t + 1)]))
        strength = np.sqrt(nu * (np.exp(-(1 - rho) / scale) if scale else 1.0))
        for j in range(4):
            tie_rows += [count, count]
            tie_cols += [4 * k + j, 4 * nxt + j]
            tie_vals += [-strength, strength]
            count += 1
    tie = sp.csr_matrix((tie_vals, (tie_rows, tie_cols)), shape=(max(count, 1), unknowns))
    normal = (disagreement.T @ disagreement + mu * (design.T @ design) + tie.T @ tie + 1e-9 * sp.eye(unknowns)).tocsc()
    target = coarse.astype(np.float64).ravel()[np.concatenate(pixels)]
    rhs = mu * (design.T @ target)
    if lag is None:
        g = spl.spsolve(normal, rhs)
        return (stitched @ g).reshape(t_len, h, w).astype(np.float32)
    # Blocks of the temporal hop (the frames two windows of patches cover), in
    # time order: blocks b … b + lag solved together, block b kept; the ties
    # to frames before the first block's are held at their solved GBRs.
    hop = lt // 2
    block_of = lambda t: (t + pt) // hop  # noqa: E731
    frame_cols, patch_of = {}, {}
    for (n, t), k in index.items():
        frame_cols.setdefault(t, []).append(k)
        patch_of[k] = n
    g = np.zeros(unknowns)
    ties_back = {}  # k → (k at t − 1, ν)
    for (n, t), k in index.items():
        prev = index.get((n, t - 1))
        if prev is not None:
            rho = float(np.mean(standardised[(n, t - 1)] * standardised[(n, t)]))
            ties_back[k] = (prev, nu * (np.exp(-(1 - rho) / scale) if scale else 1.0))
    for b in sorted({block_of(t) for t in range(t_len)}):
        frames = [t for t in range(t_len) if b <= block_of(t) <= b + lag]
        ks = sorted(k for t in frames for k in frame_cols[t])
        cols_s = np.concatenate([np.arange(4 * k, 4 * k + 4) for k in ks])
        block = normal[cols_s][:, cols_s].tolil()
        r = rhs[cols_s].copy()
        where = {k: i for i, k in enumerate(ks)}
        # ``normal`` holds each tie's ν on the diagonal at both ends: a tie to
        # the solved frame before the first pulls toward its GBR; one to the
        # frame after the last, not solved yet, is left out.
        for k in frame_cols[frames[0]]:
            if k in ties_back:
                prev, strength = ties_back[k]
                r[4 * where[k]:4 * where[k] + 4] += strength * g[4 * prev:4 * prev + 4]
        for k in frame_cols[frames[-1]]:
            nxt = index.get((patch_of[k], frames[-1] + 1))
            if nxt is not None:
                for j in range(4):
                    block[4 * where[k] + j, 4 * where[k] + j] -= ties_back[nxt][1]
        solved = spl.spsolve(block.tocsc(), r)
        for t in frames:
            if block_of(t) == b:
                for k in frame_cols[t]:
                    g[4 * k:4 * k + 4] = solved[4 * where[k]:4 * where[k] + 4]
    return (stitched @ g).reshape(t_len, h, w).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--videos", type=int, default=8, help="generated videos a set")
    parser.add_argument("--seed", type=int, default=TEST_SEED, help=f"generator seed of the videos (default {TEST_SEED}, held out)")
    parser.add_argument("--weights", default="0,0.004,0.0075,0.015", help="the stitcher's temporal weights ν to compare, per pixel (comma-separated; the first is the reference)")
    parser.add_argument("--symmetric", type=float, default=None, metavar="NU",
                        help="also the symmetric tie over the whole video (scipy) at this weight ν per patch-frame, adaptive with --scale (the prototype: 30)")
    parser.add_argument("--scale", type=float, default=0.02, help="the symmetric tie's scale of 1 − ρ")
    parser.add_argument("--lags", default="whole", help="how the symmetric tie is solved: 'whole' (the whole video at once) or LAG, in blocks of the temporal hop, "
                        "blocks b … b + LAG together, block b kept (comma-separated, e.g. whole,0,1)")
    args = parser.parse_args()
    cpu = torch.device("cpu")
    net = inference_model(args.model, cpu)
    weights = [float(v) for v in args.weights.split(",")]
    lags = [None if v == "whole" else int(v) for v in args.lags.split(",")]
    base = nrdepth.GeneratorConfig(size=256)
    clips = {name: nrdepth.generate_clips(args.videos, seed=args.seed, config=config) for name, config in (("inside", base), ("outside", out_of_range(base)))}
    sets = {name: list(zip(c.video, c.depth)) for name, c in clips.items()}
    sets["phisft_R1 (4×4)"] = [phisft_at_bin(4)]
    labels = ["paper's stitch"] + [f"ν = {v:g}" for v in weights]
    if args.symmetric is not None:
        labels += [f"symmetric ν = {args.symmetric:g}, " + ("whole" if lag is None else f"lag {lag}") for lag in lags]
    print(f"MAE-SN per frame / from the first frame; differences to ν = {weights[0]:g} paired over the videos (mean ± standard error); stitch time a video")
    for name, videos in sets.items():
        scores, seconds = [], np.zeros(len(labels))
        for video, truth in videos:
            mask = np.isfinite(truth) if np.isnan(truth).any() else None
            layout = patch_layout(video.shape)
            coarse = coarse_depth(video, net, 8, cpu)
            patches = np.concatenate([d for _, d in patch_depths(video, net, layout, 8, cpu)])
            stitches = [lambda: nrdepth.stitch(patches, coarse, layout, alignment="coarse", window="triangle")]
            stitches += [lambda v=v: nrdepth.stitch(patches, coarse, layout, temporal_weight=v) for v in weights]
            if args.symmetric is not None:
                stitches += [lambda lag=lag: tied_stitch(patches, coarse, COARSE_WEIGHT, args.symmetric, args.scale, lag) for lag in lags]
            row = []
            for i, run in enumerate(stitches):
                start = time.perf_counter()
                depth = run()
                seconds[i] += time.perf_counter() - start
                row.append([nrdepth.mae_sn(depth, truth, a, mask=mask) for a in ("frame", "first")])
            scores.append(row)
        r = np.array(scores)  # (videos, stitches, 2)
        print(f"{name} ({len(r)} videos)")
        for i, label in enumerate(labels):
            line = f"  {label:>22}: {r[:, i, 0].mean():.4f} / {r[:, i, 1].mean():.4f}"
            if i > 1:
                diff = r[:, i] - r[:, 1]
                se = diff.std(axis=0, ddof=1) / np.sqrt(len(r)) if len(r) > 1 else np.zeros(2)
                line += f"   {diff[:, 0].mean():+.4f} ± {se[0]:.4f} / {diff[:, 1].mean():+.4f} ± {se[1]:.4f}"
            print(f"{line}   {1000 * seconds[i] / len(r):.0f} ms", flush=True)


if __name__ == "__main__":
    main()
