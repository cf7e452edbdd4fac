"""Where a model's score on ``phisft_R1`` comes from: the real cloth scored
three ways per model, on ``bench_real.py``'s crop (108×108, 50 frames).

- patches: the network's raw outputs on 27 patches of 64×64×16 (three
  origins spread evenly on each image axis, 0, 22, 44 on the 108×108 crop;
  frames 0, 17, 34), each aligned per frame to
  the truth box-averaged 2×2 to the output's half resolution, no stitching:
  the local reading;
- coarse: the coarse pass alone (the crop resized to 64×64, both readings
  averaged as ``reconstruct`` does), resized back: the large-scale reading (at
  0.6× scale on the 108×108 crop) that every patch is aligned to;
- stitched: ``nrdepth.reconstruct``, as ``bench_real.py`` scores it, and
  beside it the paper's stitch (``alignment="coarse", window="triangle"``);

all as MAE-SN per frame over the pixels with a ground-truth value, beside
the flat plane's, and for the coarse pass and the stitched depth the share
of frames whose relief sign is read right (λ > 0 in the frame's GBR fit;
MAE-SN per frame leaves the sign free).

``--cross`` adds, for two or more models, the stitched score of every
pairing of one model's coarse pass with another's patches: which of the two
passes a difference between models comes from. ``--turn`` turns the video
(and the truth) 180° first: the cloth lit from the other side of image-up.
``--bin 3`` or ``--bin 2`` scores the same region of the cloth at a finer
scale: the full 1920×1080 frames' luma box-averaged 3×3 or 2×2 (144×144 or
216×216 pixels), the ground truth splatted into that grid by
``derived_q4.npz``'s own recipe (the nearest point of each frame's cloud
per pixel, which gives that file's depth exactly at 4×4).

``--write NPZ`` saves the scored video and its truth (``video``, ``depth``)
for ``nrdepth train --real NPZ``, which scores it stitched after every epoch.

    python experiments/real_scales.py MODEL [MODEL ...] [--cross] [--bin 4|3|2] [--turn]     # 'default' is the shipped model
    python experiments/real_scales.py --write phisft_bin4.npz [--bin 4|3|2] [--turn]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import torch

import nrdepth
from nrdepth.scores.metrics import flat_baseline, mae_sn, relief_signs
from nrdepth.model import DEFAULT_MODEL, load_model, predict_depth
from nrdepth.reconstruct import coarse_depth, inference_model, patch_depths
from nrdepth.reconstruct.stitch import patch_layout


from nrdepth.scores.real import crop_at_bin, phisft_at_bin

def patches(video: np.ndarray, truth: np.ndarray) -> tuple:
    """27 clips (uint8; 3 origins spread evenly over each image axis) and
    their truth at half resolution (NaN where no pixel of a 2×2 block has one)."""
    clips, truths = [], []
    origins = np.linspace(0, video.shape[1] - 64, 3).round().astype(int)
    for t in (0, 17, 34):
        for y in origins:
            for x in origins:
                clips.append(video[t : t + 16, y : y + 64, x : x + 64])
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks stay NaN
                    truths.append(np.nanmean(truth[t : t + 16, y : y + 64, x : x + 64].reshape(16, 32, 2, 32, 2), axis=(2, 4)))
    return np.stack(clips), np.stack(truths)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", help="model.safetensors or run folder; 'default' for the shipped model")
    parser.add_argument("--cross", action="store_true", help="also stitch every model's coarse pass with every model's patches")
    parser.add_argument("--bin", type=int, choices=(4, 3, 2), default=4, help="the full frames box-averaged b×b (default 4: derived_q4.npz, bench_real.py's scale)")
    parser.add_argument("--turn", action="store_true", help="turn the video and the truth 180° (the light's side flips)")
    parser.add_argument("--write", default=None, metavar="NPZ", help="save the video and its truth for `nrdepth train --real NPZ` and stop")
    args = parser.parse_args()
    if not args.models and not args.write:
        parser.error("give one or more models, or --write NPZ")
    video, truth = phisft_at_bin(args.bin)
    if args.turn:
        video, truth = np.ascontiguousarray(video[:, ::-1, ::-1]), np.ascontiguousarray(truth[:, ::-1, ::-1])
    if args.write:
        np.savez_compressed(args.write, video=video, depth=truth)
        print(f"wrote {args.write}: phisft_R1 binned {args.bin}×{args.bin}{', turned 180°' if args.turn else ''}, video {video.shape} uint8, depth in metres (NaN: no truth)")
        return
    top, bottom, left, right = crop_at_bin(args.bin)
    mask = np.isfinite(truth)
    clips, clip_truth = patches(video, truth)
    clip_masks = np.isfinite(clip_truth)
    plane_patches = np.mean([flat_baseline(g, "frame", mask=m) for g, m in zip(clip_truth, clip_masks)])
    print(f"phisft_R1 binned {args.bin}×{args.bin}{', turned 180°' if args.turn else ''}, rows {top}–{bottom}, columns {left}–{right}: MAE-SN per frame (flat plane: patches "
          f"{plane_patches:.4f}, whole crop {flat_baseline(truth, 'frame', mask=mask):.4f})")
    print(f"{'model':50s}{'patches':>9s}{'coarse':>9s}{'stitched':>10s}{'paper':>9s}   sign right: coarse, stitched")
    cpu = torch.device("cpu")
    for name in args.models:
        net = load_model(DEFAULT_MODEL if name == "default" else name, device="cpu")
        local = np.mean([mae_sn(p, g, "frame", mask=m) for p, g, m in zip(predict_depth(net, clips), clip_truth, clip_masks)])
        depths = coarse_depth(video, net, 8, cpu), nrdepth.reconstruct(video, net, device="cpu", sheet_stage=False)
        coarse, stitched = (mae_sn(d, truth, "frame", mask=mask) for d in depths)
        paper = mae_sn(nrdepth.reconstruct(video, net, device="cpu", alignment="coarse", window="triangle", sheet_stage=False), truth, "frame", mask=mask)
        right = "".join(f"{np.mean(relief_signs(d, truth, mask=mask) > 0):>8.0%}" for d in depths)
        print(f"{name[-50:]:50s}{local:>9.4f}{coarse:>9.4f}{stitched:>10.4f}{paper:>9.4f}{right}", flush=True)
    if args.cross:
        cross(video, truth, mask, args.models)


def cross(video: np.ndarray, truth: np.ndarray, mask: np.ndarray, models: list) -> None:
    """Stitched MAE-SN per frame of every model's coarse pass (rows) with every model's patches (columns)."""
    cpu = torch.device("cpu")
    layout = patch_layout(video.shape)
    nets = [inference_model(None if name == "default" else name, cpu) for name in models]
    coarse = [coarse_depth(video, net, 8, cpu) for net in nets]
    fine = [np.concatenate([depth for _, depth in patch_depths(video, net, layout, 8, cpu)]) for net in nets]
    print("stitched: coarse pass of the row's model, patches of the column's")
    print(f"{'':50s}" + "".join(f"{j:>9d}" for j in range(len(models))))
    for i, name in enumerate(models):
        row = [mae_sn(nrdepth.stitch(patches, coarse[i], layout), truth, "frame", mask=mask) for patches in fine]
        print(f"{i} {name[-48:]:48s}" + "".join(f"{v:>9.4f}" for v in row), flush=True)


if __name__ == "__main__":
    main()
