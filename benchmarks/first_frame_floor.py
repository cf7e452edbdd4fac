"""What bounds MAE-SN from the first frame on the held-out clips: the score
of the true depth when what an orthographic video cannot show is unknown —
the generator's motion along the optical axis (``drift_z``), or each frame's
mean depth — beside the flat plane's. With ``--model``, the same split for
a model's prediction: as it is, with each frame's mean depth replaced by the
truth's without the z drift (what a perfect predictor of the visible
offsets would give), and with each frame's offset refitted to the truth
(``first_offset``).

    python benchmarks/first_frame_floor.py [--clips 128] [--model PATH|default]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth
from nrdepth.evaluate import TEST_SEED
from nrdepth.metrics import gbr_fit


def with_offsets(pred: np.ndarray, truth: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """``pred`` (T, H, W) with each frame's mean moved so that, through frame
    0's GBR onto ``truth`` (scale λ), the frames' means follow ``visible``'s."""
    lam = gbr_fit(pred[0], truth[0])[2]
    return pred - pred.mean(axis=(1, 2), keepdims=True) + visible.mean(axis=(1, 2), keepdims=True) / lam


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
        rows["model, offsets refitted (first_offset)"] = [nrdepth.mae_sn(p, g, "first_offset") for p, g in zip(pred, truth)]
    print(f"MAE-SN from the first frame over {args.clips} held-out clips (seed {TEST_SEED}), mean ± std")
    for name, values in rows.items():
        print(f"{name:40s}{np.mean(values):.4f} ± {np.std(values):.4f}")


if __name__ == "__main__":
    main()
