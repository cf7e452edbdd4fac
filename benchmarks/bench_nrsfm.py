"""The classic motion-capture NRSfM benchmark: PTA (from the files) beside
CSF2 and KSTA (nrdepth.baselines.nrsfm; KSTA in our reading of its paper) on drink,
pickup, yoga, stretch and dance, with the benchmark's 3-D error
(nrdepth.baselines.nrsfm.error_3d; see shared/data/nrsfm/README.md).

Given several K or d fractions, every setting is run and printed, then a
table of each method's best setting per sequence: the selection is made on
the benchmark's own error, as the published tables choose K per sequence, so
it says what each method can reach, not what it gives untuned.

    python benchmarks/bench_nrsfm.py [--K 4] [--d-fraction 0.1] [--sequences yoga,dance]
    python benchmarks/bench_nrsfm.py --K 2,3,4,6,8 --d-fraction 0.1,0.2 [--rows sweep.csv]
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from nrdepth.baselines.nrsfm import cameras, csf2, error_3d, ksta

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "nrsfm"
SEQUENCES = ("drink", "pickup", "yoga", "stretch", "dance")
METHODS = {"CSF2": csf2, "KSTA": ksta}


def numbers(kind):
    return lambda text: [kind(v) for v in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--K", type=numbers(int), default=[4], help="complementary rank-3 spaces (comma list to sweep)")
    parser.add_argument("--d-fraction", type=numbers(float), default=[0.1], help="DCT functions d = ceil(fraction · T) (comma list to sweep)")
    parser.add_argument("--sequences", default=",".join(SEQUENCES))
    parser.add_argument("--rows", type=Path, default=None, help="CSV of every run, written as they come")
    args = parser.parse_args()
    print(f"{'sequence':10s}{'T':>6s}{'n':>5s}{'PTA':>9s}{'CSF2':>9s}{'KSTA':>9s}   K, d, seconds (CSF2, KSTA)")
    runs = []
    writer = csv.writer(args.rows.open("w", newline="")) if args.rows else None
    if writer:
        writer.writerow(["sequence", "T", "n", "K", "d", "PTA", "CSF2", "KSTA", "CSF2 seconds", "KSTA seconds"])
    for name in args.sequences.split(","):
        m = loadmat(DATA / f"{name}.mat")
        W, S = m["W"], m["S"]
        T, n = W.shape[0] // 2, W.shape[1]
        pta = error_3d(m["Shat"] / float(np.squeeze(m["scale"])), S)
        Rs = cameras(W)
        for K in args.K:
            for fraction in args.d_fraction:
                d = math.ceil(fraction * T)
                errors, seconds = {}, {}
                for method, solve in METHODS.items():
                    start = time.perf_counter()
                    result = solve(W, K=K, d=d, Rs=Rs)
                    # dance's truth is in the (fixed) camera's frame: turn each frame by its estimated camera first.
                    errors[method] = error_3d(result.shapes, S, result.cameras if name == "dance" else None)
                    seconds[method] = time.perf_counter() - start
                runs.append({"sequence": name, "T": T, "n": n, "K": K, "d": d, "PTA": pta, **errors})
                if writer:
                    writer.writerow([name, T, n, K, d, pta, errors["CSF2"], errors["KSTA"], seconds["CSF2"], seconds["KSTA"]])
                print(f"{name:10s}{T:>6d}{n:>5d}{pta:>9.4f}{errors['CSF2']:>9.4f}{errors['KSTA']:>9.4f}   "
                      f"{K}, {d}, {seconds['CSF2']:.0f} s, {seconds['KSTA']:.0f} s", flush=True)
    if len(args.K) * len(args.d_fraction) > 1:
        print("\nbest setting per sequence (chosen on this error), method: error (K, d)")
        for name in args.sequences.split(","):
            mine = [r for r in runs if r["sequence"] == name]
            best = {method: min(mine, key=lambda r: r[method]) for method in METHODS}
            print(f"{name:10s}PTA {mine[0]['PTA']:.4f}   " + "   ".join(
                f"{method} {b[method]:.4f} ({b['K']}, {b['d']})" for method, b in best.items()))


if __name__ == "__main__":
    main()
