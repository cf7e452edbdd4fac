"""A prototype for the stitcher: the default stitch (joint alignment, Hann
windows) with each patch's GBRs tied between consecutive frames,

    E(g) + Σ_{n,f} ν_{n,f} ‖g_{n,f+1} − g_{n,f}‖²,

E the joint alignment's per-frame objective (``rust/joint.rs``), solved for
the whole video at once (scipy's sparse direct solver: small videos only).
``--tie uniform`` uses ν_{n,f} = ν; ``--tie adaptive`` weighs it by how much
the patch's own reading changes, ν exp(−(1 − ρ)/``--scale``), ρ the
correlation of the patch's two standardised frames. At ν = 0 it reproduces
``nrdepth.stitch`` to rounding (printed). Scores, beside the default and the
paper's stitch of the same patches, ``bench_reconstruct.py``'s generated
videos inside and outside the training ranges and ``bench_real.py``'s crop
of ``phisft_R1``; MAE-SN per frame / from the first frame, and paired
differences to the default (mean ± standard error over the videos).

    python benchmarks/temporal_tie.py [--model PATH] [--videos 8] [--nu 30] [--tie adaptive] [--scale 0.02]
"""

from __future__ import annotations

import argparse

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
import torch

import nrdepth
from bench_reconstruct import out_of_range  # this script's folder is on sys.path
from nrdepth.evaluate import TEST_SEED
from nrdepth.stitch import COARSE_WEIGHT, coarse_depth, inference_model, patch_depths, patch_layout
from real_scales import phisft_at_bin


def tied_stitch(patches: np.ndarray, coarse: np.ndarray, mu: float, nu: float, scale: float | None) -> np.ndarray:
    """The joint alignment with Hann windows and the temporal tie (module docstring)."""
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
    g = spl.spsolve(normal, mu * (design.T @ target))
    return (stitched @ g).reshape(t_len, h, w).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--videos", type=int, default=8, help="generated videos a set")
    parser.add_argument("--nu", type=float, default=30.0, help="the tie's weight ν")
    parser.add_argument("--tie", choices=("uniform", "adaptive"), default="adaptive")
    parser.add_argument("--scale", type=float, default=0.02, help="the adaptive tie's scale of 1 − ρ")
    args = parser.parse_args()
    cpu = torch.device("cpu")
    net = inference_model(args.model, cpu)
    scale = args.scale if args.tie == "adaptive" else None
    base = nrdepth.GeneratorConfig(size=256)
    clips = {name: nrdepth.generate_clips(args.videos, seed=TEST_SEED, config=config) for name, config in (("inside", base), ("outside", out_of_range(base)))}
    sets = {name: list(zip(c.video, c.depth)) for name, c in clips.items()}
    sets["phisft_R1 (4×4)"] = [phisft_at_bin(4)]
    print(f"tie {args.tie}, ν = {args.nu:g}{f', scale {scale:g}' if scale else ''}; MAE-SN per frame / from the first frame")
    for name, videos in sets.items():
        rows = []
        for video, truth in videos:
            mask = np.isfinite(truth) if np.isnan(truth).any() else None
            layout = patch_layout(video.shape)
            coarse = coarse_depth(video, net, 8, cpu)
            patches = np.concatenate([d for _, d in patch_depths(video, net, layout, 8, cpu)])
            default = nrdepth.stitch(patches, coarse, layout)
            depths = (nrdepth.stitch(patches, coarse, layout, alignment="coarse", window="triangle"), default,
                      tied_stitch(patches, coarse, COARSE_WEIGHT, args.nu, scale))
            untied = tied_stitch(patches, coarse, COARSE_WEIGHT, 0.0, None)
            rows.append([nrdepth.mae_sn(d, truth, a, mask=mask) for d in depths for a in ("frame", "first")]
                        + [float(np.abs(untied - default).max() / default.std())])
        r = np.array(rows)
        diff = r[:, 4:6] - r[:, 2:4]
        se = diff.std(axis=0, ddof=1) / np.sqrt(len(r)) if len(r) > 1 else np.zeros(2)
        print(f"{name} ({len(r)}): paper's stitch {r[:, 0].mean():.4f} / {r[:, 1].mean():.4f}, default {r[:, 2].mean():.4f} / {r[:, 3].mean():.4f}, "
              f"tied {r[:, 4].mean():.4f} / {r[:, 5].mean():.4f}; tied − default {diff[:, 0].mean():+.4f} ± {se[0]:.4f} / {diff[:, 1].mean():+.4f} ± {se[1]:.4f}; "
              f"ν = 0 against the default stitch: {r[:, 6].max():.1e} of its std", flush=True)


if __name__ == "__main__":
    main()
