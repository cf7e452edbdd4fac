"""Where a model's score on ``phisft_R1`` comes from: the real cloth scored
three ways per model, on ``bench_real.py``'s crop (108×108, 50 frames).

- patches: the network's raw outputs on 27 patches of 64×64×16 (offsets 0,
  22, 44 on each image axis; frames 0, 17, 34), each aligned per frame to
  the truth box-averaged 2×2 to the output's half resolution, no stitching:
  the local reading;
- coarse: the coarse pass alone (the crop resized to 64×64, both readings
  averaged as ``reconstruct`` does), resized back: the large-scale reading at
  0.6× scale that every patch is aligned to;
- stitched: ``nrdepth.reconstruct``, as ``bench_real.py`` scores it;

all as MAE-SN per frame over the pixels with a ground-truth value, beside
the flat plane's.

    python benchmarks/real_scales.py MODEL [MODEL ...]     # 'default' is the shipped model
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import torch

import nrdepth
from nrdepth.metrics import flat_baseline, mae_sn
from nrdepth.model import DEFAULT_MODEL, load_model, predict_depth
from nrdepth.stitch import coarse_depth

from bench_real import DATA

CROP = (110, 218, 106, 214)


def patches(video: np.ndarray, truth: np.ndarray) -> tuple:
    """27 clips (uint8) and their truth at half resolution (NaN where no pixel of a 2×2 block has one)."""
    clips, truths = [], []
    for t in (0, 17, 34):
        for y in (0, 22, 44):
            for x in (0, 22, 44):
                clips.append(video[t : t + 16, y : y + 64, x : x + 64])
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks stay NaN
                    truths.append(np.nanmean(truth[t : t + 16, y : y + 64, x : x + 64].reshape(16, 32, 2, 32, 2), axis=(2, 4)))
    return np.stack(clips), np.stack(truths)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="model.safetensors or run folder; 'default' for the shipped model")
    args = parser.parse_args()
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    top, bottom, left, right = CROP
    video, truth = data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
    mask = np.isfinite(truth)
    clips, clip_truth = patches(video, truth)
    clip_masks = np.isfinite(clip_truth)
    plane_patches = np.mean([flat_baseline(g, "frame", mask=m) for g, m in zip(clip_truth, clip_masks)])
    print(f"phisft_R1, rows {top}–{bottom}, columns {left}–{right}: MAE-SN per frame (flat plane: patches "
          f"{plane_patches:.4f}, whole crop {flat_baseline(truth, 'frame', mask=mask):.4f})")
    print(f"{'model':50s}{'patches':>9s}{'coarse':>9s}{'stitched':>10s}")
    cpu = torch.device("cpu")
    for name in args.models:
        net = load_model(DEFAULT_MODEL if name == "default" else name, device="cpu")
        local = np.mean([mae_sn(p, g, "frame", mask=m) for p, g, m in zip(predict_depth(net, clips), clip_truth, clip_masks)])
        coarse = mae_sn(coarse_depth(video, net, 8, cpu), truth, "frame", mask=mask)
        stitched = mae_sn(nrdepth.reconstruct(video, net, device="cpu"), truth, "frame", mask=mask)
        print(f"{name[-50:]:50s}{local:>9.4f}{coarse:>9.4f}{stitched:>10.4f}", flush=True)


if __name__ == "__main__":
    main()
