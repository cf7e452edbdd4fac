"""What bounds MAE-SN from the first frame on the held-out clips: the score
of the true depth when what an orthographic video cannot show is unknown —
the generator's motion along the optical axis (``drift_z``), or each frame's
mean depth — beside the flat plane's.

    python benchmarks/first_frame_floor.py [--clips 128]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth
from nrdepth.evaluate import TEST_SEED


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=128)
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
    print(f"MAE-SN from the first frame over {args.clips} held-out clips (seed {TEST_SEED}), mean ± std")
    for name, values in rows.items():
        print(f"{name:36s}{np.mean(values):.4f} ± {np.std(values):.4f}")


if __name__ == "__main__":
    main()
