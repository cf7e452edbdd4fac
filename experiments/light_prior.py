"""How the width of the light-from-above prior trades reading the relief's
sign against the lights a model covers: held-out sign-correct rate, in-clip
flip rate and MAE-SN per frame against the azimuth of a single directional
light, for models trained with different ``--light-azimuth`` ranges.

Every azimuth bin (|azimuth| from image-up, 15° wide, 0° to 180°) holds the
same clips for every model: ``--clips`` of them, half lit from the left
(negative azimuths), half from the right, every other generator setting at
its default. Under an orthographic camera a clip lit from azimuth a renders
as its mirrored relief lit from a + 180°, so a model can be right at a only
by being wrong at a + 180°: the curve shows where each model puts that
boundary and how sharply.

    python experiments/light_prior.py campaign/prior_45 campaign/prior_70 campaign/prior_85 \\
        --labels "±45°,±70°,±85°" -o docs/light_prior

``--camera-fov LO,HI`` (degrees) and ``--crop-share LO,HI`` render the bins
through a pinhole (``GeneratorConfig.camera_fov``): a relief and its mirror
image then render differently, so a model may be right on both sides.
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from typing import Dict, List

import numpy as np
import torch

import nrdepth
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.scores.metrics import mae_sn, sign_rates
from nrdepth.model import load_model, predict_depth

BIN_DEGREES = 15


def bin_clips(lo: float, hi: float, clips: int, seed: int, camera: Dict[str, tuple]):
    """``clips`` held-out clips lit by one directional light with |azimuth| in
    [lo, hi] degrees, half on each side of image-up, seen by ``camera``
    (``GeneratorConfig`` fields); returns (video, truth at the network's half
    resolution)."""
    videos, truths = [], []
    for side, count in ((-1, clips // 2), (1, clips - clips // 2)):
        azimuth = sorted((side * math.radians(lo), side * math.radians(hi)))
        config = nrdepth.GeneratorConfig(light_count=(1, 1), light_azimuth=tuple(azimuth), point_light_probability=0.0, **camera)
        generated = nrdepth.generate_clips(count, seed=seed + (side > 0), config=config)
        videos.append(generated.video)
        truths.append(torch.nn.functional.avg_pool2d(torch.from_numpy(generated.depth).float(), 2).numpy())
    return np.concatenate(videos), np.concatenate(truths)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="model.safetensors files or run folders")
    parser.add_argument("--labels", default=None, help="comma-separated, one per model (default: the paths)")
    parser.add_argument("--clips", type=int, default=32, help="clips per azimuth bin")
    parser.add_argument("--camera-fov", default=None, metavar="LO,HI", help="a pinhole camera's field of view, degrees (default: orthographic)")
    parser.add_argument("--crop-share", default="1,1", metavar="LO,HI", help="with --camera-fov: the clip's share of its frame's width")
    parser.add_argument("-o", "--out", default=None, help="write OUT.csv and OUT.png")
    args = parser.parse_args()
    camera = {}
    if args.camera_fov:
        fov = tuple(math.radians(float(v)) for v in args.camera_fov.split(","))
        camera = {"camera_fov": fov, "crop_share": tuple(float(v) for v in args.crop_share.split(","))}
    labels = args.labels.split(",") if args.labels else args.models
    if len(labels) != len(args.models):
        parser.error(f"--labels: expected {len(args.models)} labels, got {len(labels)}")
    torch.set_grad_enabled(False)
    nets = [load_model(m, device="cpu") for m in args.models]
    rows: List[Dict[str, float]] = []
    print(f"{args.clips} held-out clips a bin, one directional light; sign-correct % / flips % / MAE-SN per frame")
    print(f"{'|azimuth|':>12s}" + "".join(f"{label:>24s}" for label in labels))
    for k, lo in enumerate(range(0, 180, BIN_DEGREES)):
        hi = lo + BIN_DEGREES
        video, truth = bin_clips(lo, hi, args.clips, TEST_SEED + 1000 * (k + 1), camera)
        cells = []
        for label, net in zip(labels, nets):
            pred = predict_depth(net, video)
            rates = [sign_rates(p, g) for p, g in zip(pred, truth)]
            row = {
                "model": label, "azimuth_lo": lo, "azimuth_hi": hi,
                "sign_correct": float(np.mean([r["sign_correct"] for r in rates])),
                "flip": float(np.mean([r["flip"] for r in rates])),
                "mae_sn_frame": float(np.mean([mae_sn(p, g, "frame") for p, g in zip(pred, truth)])),
            }
            rows.append(row)
            cells.append(f"{100 * row['sign_correct']:5.1f} / {100 * row['flip']:5.1f} / {row['mae_sn_frame']:.3f}")
        print(f"{lo:>5d}–{hi:<3d}°  " + "".join(f"{c:>24s}" for c in cells), flush=True)
    if args.out:
        write(rows, labels, Path(args.out))


def write(rows: List[Dict[str, float]], labels: List[str], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.parent.mkdir(parents=True, exist_ok=True)
    with out.with_suffix(".csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for label in labels:
        mine = [r for r in rows if r["model"] == label]
        centre = [(r["azimuth_lo"] + r["azimuth_hi"]) / 2 for r in mine]
        axes[0].plot(centre, [100 * r["sign_correct"] for r in mine], marker="o", label=label)
        axes[1].plot(centre, [r["mae_sn_frame"] for r in mine], marker="o", label=label)
    axes[0].axhline(50, color="grey", linestyle=":", label="a guess")
    axes[0].set_ylabel("relief sign correct, % of frames")
    axes[1].set_ylabel("MAE-SN, each frame aligned")
    for ax in axes:
        ax.axvline(90, color="grey", linewidth=0.8)
        ax.set_xlabel("|light azimuth| from image-up, degrees")
        ax.set_xticks(range(0, 181, 30))
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=110)
    print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
