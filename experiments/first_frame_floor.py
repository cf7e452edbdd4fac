"""What bounds MAE-SN from the first frame on the held-out clips: the score
of the true depth when what an orthographic video cannot show is unknown —
the generator's motion along the optical axis (``drift_z``), or each frame's
mean depth — beside the flat plane's. With ``--model``, the same split for
a model's prediction: as it is, with each frame's mean depth replaced by the
truth's without the z drift (what a perfect predictor of the visible
offsets would give), with each frame's plane (tilt and offset) replaced
by the truth's without the z drift (a perfect predictor of the visible
plane motion), and with each frame's offset refitted to the truth
(``first_offset``); and how much of the plane's motion the model predicts.

    python experiments/first_frame_floor.py [--clips 128] [--model PATH|default]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.scores.metrics import gbr_fit


def with_offsets(pred: np.ndarray, truth: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """``pred`` (T, H, W) with each frame's mean moved so that, through frame
    0's GBR onto ``truth`` (scale λ), the frames' means follow ``visible``'s."""
    lam = gbr_fit(pred[0], truth[0])[2]
    return pred - pred.mean(axis=(1, 2), keepdims=True) + visible.mean(axis=(1, 2), keepdims=True) / lam


def planes(video: np.ndarray) -> np.ndarray:
    """Each frame's least-squares plane (T, H, W) of a video (T, H, W)."""
    t, h, w = video.shape
    y, x = np.mgrid[0:h, 0:w]
    design = np.stack([x.ravel(), y.ravel(), np.ones(h * w)], 1)
    coeffs = np.linalg.lstsq(design, video.reshape(t, -1).T, rcond=None)[0]
    return (design @ coeffs).T.reshape(t, h, w)


def with_planes(pred: np.ndarray, truth: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """``pred`` (T, H, W) with each frame's plane replaced so that, through
    frame 0's GBR onto ``truth`` (scale λ), the frames' planes (tilt and
    offset) follow ``visible``'s."""
    lam = gbr_fit(pred[0], truth[0])[2]
    return pred - planes(pred) + planes(visible) / lam


def plane_motion(pred: np.ndarray, truth: np.ndarray, visible: np.ndarray) -> tuple:
    """Each frame's plane (x slope, y slope, mean) minus frame 0's, of
    ``pred`` through frame 0's GBR scale and of ``visible``: two (T, 3)."""
    lam = gbr_fit(pred[0], truth[0])[2]

    def motion(video: np.ndarray) -> np.ndarray:
        plane = planes(video)
        c = np.stack([plane[:, 0, 1] - plane[:, 0, 0], plane[:, 1, 0] - plane[:, 0, 0], video.mean(axis=(1, 2))], 1)
        return c - c[0]

    return lam * motion(pred), motion(visible)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=128)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder ('default': the shipped model)")
    args = parser.parse_args()
    clips = nrdepth.generate_clips(args.clips, seed=TEST_SEED)
    truth = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth), 2).numpy().astype(np.float64)  # the network's resolution
    t = np.linspace(0, 1, truth.shape[1])[:, None, None]  # E_t's translation grows linearly over the clip
    drift = [np.asarray(p["surface"]["drift"])[2] for p in clips.params]
    rows = {
        "truth without its z drift": [nrdepth.mae_sn(g + dz * t, g, "first") for g, dz in zip(truth, drift)],
        "truth, each frame's mean removed": [nrdepth.mae_sn(g - g.mean(axis=(1, 2), keepdims=True), g, "first") for g in truth],
        "flat plane": [nrdepth.flat_baseline(g, "first") for g in truth],
    }
    if args.model is not None:
        from nrdepth.model import load_model, predict_depth

        pred = predict_depth(load_model(None if args.model == "default" else args.model), clips.video).astype(np.float64)
        visible = truth + np.array(drift)[:, None, None, None] * t  # each frame's depth without the z drift
        rows["model"] = [nrdepth.mae_sn(p, g, "first") for p, g in zip(pred, truth)]
        rows["model, visible offsets from the truth"] = [nrdepth.mae_sn(with_offsets(p, g, v), g, "first") for p, g, v in zip(pred, truth, visible)]
        rows["model, visible planes from the truth"] = [nrdepth.mae_sn(with_planes(p, g, v), g, "first") for p, g, v in zip(pred, truth, visible)]
        rows["model, offsets refitted (first_offset)"] = [nrdepth.mae_sn(p, g, "first_offset") for p, g in zip(pred, truth)]
    print(f"MAE-SN from the first frame over {args.clips} held-out clips (seed {TEST_SEED}), mean ± std")
    for name, values in rows.items():
        print(f"{name:40s}{np.mean(values):.4f} ± {np.std(values):.4f}")
    if args.model is not None:
        moved, wanted = (np.concatenate(m) for m in zip(*(plane_motion(p, g, v) for p, g, v in zip(pred, truth, visible))))
        explained = 1 - ((moved - wanted) ** 2).sum(0) / (wanted**2).sum(0)
        gain = (moved * wanted).sum(0) / (moved**2).sum(0)
        print("the model's plane motion (each frame's minus frame 0's) against the truth's without the z drift:")
        print("  share of the truth's variance explained (x slope, y slope, mean): " + ", ".join(f"{e:.2f}" for e in explained))
        print("  least-squares gain of the model's onto the truth's:                " + ", ".join(f"{g:.2f}" for g in gain))


if __name__ == "__main__":
    main()
