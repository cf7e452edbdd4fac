"""The classic motion-capture NRSfM benchmark: PTA (from the files) beside
CSF2 and KSTA (nrdepth.nrsfm; KSTA in our reading of its paper) on drink, pickup, yoga, stretch and dance, with the
benchmark's 3-D error (nrdepth.nrsfm.error_3d; see shared/data/nrsfm/README.md).

    python benchmarks/bench_nrsfm.py [--K 4] [--d-fraction 0.1] [--sequences yoga,dance]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from nrdepth.nrsfm import cameras, csf2, error_3d, ksta

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "nrsfm"
SEQUENCES = ("drink", "pickup", "yoga", "stretch", "dance")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--K", type=int, default=4, help="CSF2's number of complementary rank-3 spaces")
    parser.add_argument("--d-fraction", type=float, default=0.1, help="DCT functions d = ceil(fraction · T)")
    parser.add_argument("--sequences", default=",".join(SEQUENCES))
    args = parser.parse_args()
    print(f"{'sequence':10s}{'T':>6s}{'n':>5s}{'PTA':>9s}{'CSF2':>9s}{'KSTA':>9s}   K, d, seconds (CSF2, KSTA)")
    for name in args.sequences.split(","):
        m = loadmat(DATA / f"{name}.mat")
        W, S = m["W"], m["S"]
        T, n = W.shape[0] // 2, W.shape[1]
        pta = error_3d(m["Shat"] / float(np.squeeze(m["scale"])), S)
        d = math.ceil(args.d_fraction * T)
        Rs = cameras(W)
        errors, seconds = [], []
        for method in (csf2, ksta):
            start = time.perf_counter()
            result = method(W, K=args.K, d=d, Rs=Rs)
            # dance's truth is in the (fixed) camera's frame: turn each frame by its estimated camera first.
            errors.append(error_3d(result.shapes, S, result.cameras if name == "dance" else None))
            seconds.append(time.perf_counter() - start)
        print(f"{name:10s}{T:>6d}{n:>5d}{pta:>9.4f}{errors[0]:>9.4f}{errors[1]:>9.4f}   {args.K}, {d}, {seconds[0]:.0f} s, {seconds[1]:.0f} s", flush=True)


if __name__ == "__main__":
    main()
