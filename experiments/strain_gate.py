"""The sheet stage's gate on ``refined`` read off ``sheet_levers.py``'s CSVs
(docs/campaign.md, "refined where its lengths hold"): held points in
every frame through ``refined`` (``T``) where their held gate passes and
their keyframes' strain is at most τ, the flow's points through the
joint template (``F``, at 0.3) elsewhere. Without ``--tau``, τ is the
90th percentile of ``T``'s strain over the sheets whose held gate
passes (the rule's selection); with it, that τ is read (the rule's
confirmation). Per frame, for each of ``T``'s scales, the gated stage
paired against ``F`` at 0.3 and the network alone (mean ± standard
error over the sheets).

    python experiments/strain_gate.py docs/reconstruction/strain_below.csv docs/reconstruction/strain_above.csv
    python experiments/strain_gate.py docs/reconstruction/strain_check_below.csv docs/reconstruction/strain_check_above.csv --tau 0.0107
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

F = "margin=48:keyframes=8:neighbours=8:each=lengths"
T = F + ":hold=1:keep=0.8:throughout=1:template=refined"
SCALES = (0.3, 0.2, 0.1, 0.05)


def column(rows: list, name: str) -> np.ndarray:
    return np.array([float(row[name]) for row in rows])


def per_frame(setting: str, scale: float) -> str:
    return f"{setting}:every=4" + ("" if scale == 0.3 else f":scale={scale:g}") + " per frame"


def paired(a: np.ndarray, b: np.ndarray) -> str:
    d = a - b
    return f"{d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f} (better on {(d < 0).sum()} of {len(d)})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs, read as one set")
    parser.add_argument("--tau", type=float, default=None, help="the strain read (default: the 90th percentile of T's over the set)")
    parser.add_argument("--min-held", type=float, default=0.8, help="the held gate (reconstruct.sheet.MIN_HELD)")
    args = parser.parse_args()
    rows = [row for path in args.csv for row in csv.DictReader(open(path, newline=""))]
    held, strain = column(rows, f"{T} held"), column(rows, f"{T} strain")
    passes = held >= args.min_held
    tau = float(np.percentile(strain[passes], 90)) if args.tau is None else args.tau
    holds = passes & (strain <= tau)
    network, flow = column(rows, "network per frame"), column(rows, per_frame(F, 0.3))
    print(f"{len(rows)} sheets; the held gate passes on {passes.sum()}, their strains {np.sort(strain[passes]).round(4).tolist()}")
    print(f"tau {tau:.6f}{' (the 90th percentile)' if args.tau is None else ''}: T read on {holds.sum()}, F on {len(rows) - holds.sum()}")
    print(f"per frame: the network {network.mean():.4f}, F at 0.3 {flow.mean():.4f}, the bowl {column(rows, 'bowl per frame').mean():.4f}, "
          f"the plane {column(rows, 'plane per frame').mean():.4f}")
    for scale in SCALES:
        gated = np.where(holds, column(rows, per_frame(T, scale)), flow)
        print(f"T at {scale:g}: the gated stage {gated.mean():.4f}, against F at 0.3 {paired(gated, flow)}, against the network {paired(gated, network)}")


if __name__ == "__main__":
    main()
