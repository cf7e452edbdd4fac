"""The default's contrast gate read off the strain's whole curve
(docs/campaign.md, "The contrast read off the strain's whole curve"):
each candidate gate on ``estimate_focal``'s strains over its grid
(``sheet_levers.py``'s ``strains`` column, with ``contrast=1``) in place
of today's ``contrast >= 1.35``, the points and strain gates as they
are; the default's reading (``default_gate.default_reading``: the stage
at 0.1 where the gates hold, the network elsewhere) on the sheets and on
``--noise``, against the network and against today's default, paired
per frame. Without ``--only``, every candidate and the rule's choice;
with it, that candidate alone (the rule's checks).

    python experiments/contrast_gate.py docs/reconstruction/curve_below.csv docs/reconstruction/curve_above.csv --noise docs/reconstruction/curve_noise_*.csv
    python experiments/contrast_gate.py docs/reconstruction/curve_check_{below,above}.csv --noise docs/reconstruction/curve_check_noise_*.csv --only fit 1.5
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from nrdepth.isometric import FocalEstimate

sys.path.insert(0, str(Path(__file__).parent))
from default_gate import MIN_READ, holds, rows_of  # noqa: E402
from strain_gate import T, column, paired, per_frame  # noqa: E402

D = T + ":fov=40:whole=1:moving=1:relmove=0.2:trim=3:contrast=1"
THRESHOLDS = (1.2, 1.35, 1.5, 1.75, 2.0)
TODAY = ("least", 1.35)
NOISE_BOUND = 0.005


def curve(strains: np.ndarray) -> FocalEstimate:
    """``strains`` over a grid, as ``estimate_focal`` answers (its focal lengths left out)."""
    return FocalEstimate(math.nan, float(strains.min()), tuple(range(len(strains))), tuple(map(float, strains)))


def least(strains: np.ndarray) -> float:
    """Today's contrast: the smaller strain two steps either side of the least, over it."""
    return curve(strains).contrast


def interior(strains: np.ndarray) -> float:
    """As :func:`least`, but 0 unless the least lies two steps inside the grid (``FocalEstimate.inside``: both sides there)."""
    estimate = curve(strains)
    return estimate.contrast if estimate.inside else 0.0


def fit(strains: np.ndarray) -> float:
    """A parabola fitted to every strain (in the step): its value two steps from its vertex over its value there; 0 unless it opens
    upward with its vertex on the grid, infinite where it dips to zero or below."""
    steps = np.arange(len(strains), dtype=np.float64)
    c2, c1, c0 = np.polyfit(steps, strains, 2)
    if c2 <= 0:
        return 0.0
    vertex = -c1 / (2 * c2)
    if not 0 <= vertex <= steps[-1]:
        return 0.0
    bottom = c0 + c1 * vertex + c2 * vertex**2
    return float((bottom + 4 * c2) / bottom) if bottom > 0 else float("inf")


STATISTICS = {"least": least, "interior": interior, "fit": fit}


def statistic(rows: list, kind: str) -> np.ndarray:
    """Per video: the candidate's statistic off its ``strains`` (NaN where the stage recorded none)."""
    out = []
    for row in rows:
        text = row.get(f"{D} strains", "nan") or "nan"
        strains = np.array([float(v) for v in text.split()])
        out.append(STATISTICS[kind](strains) if strains.size > 2 and np.isfinite(strains).all() else np.nan)
    return np.array(out)


def reading(rows: list, kind: str, threshold: float, tau: float, points: int) -> tuple:
    """The default's per-frame error with the candidate gate, and where it reads the stage."""
    read = holds(rows, D, tau, MIN_READ, points) & (statistic(rows, kind) >= threshold)
    return np.where(read, column(rows, per_frame(D, 0.1)), column(rows, "network per frame")), read


def main() -> None:
    from nrdepth.reconstruct.sheet import MAX_STRAIN

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs of the sheets (the default setting with contrast=1)")
    parser.add_argument("--noise", type=Path, nargs="+", required=True, help="sheet_levers.py's CSVs of videos that are no sheet")
    parser.add_argument("--tau", type=float, default=MAX_STRAIN)
    parser.add_argument("--points", type=int, default=400, help="the points asked for (sheet_levers.py's points)")
    parser.add_argument("--only", nargs=2, metavar=("KIND", "THRESHOLD"), default=None, help="one candidate: least, interior or fit, and θ")
    args = parser.parse_args()
    sheets, noise = rows_of(args.csv), rows_of(args.noise)
    network, noise_network = column(sheets, "network per frame"), column(noise, "network per frame")
    today, today_read = reading(sheets, *TODAY, args.tau, args.points)
    print(f"{len(sheets)} sheets: the network {network.mean():.4f}, the bowl {column(sheets, 'bowl per frame').mean():.4f}; "
          f"{len(noise)} noise videos: the network {noise_network.mean():.4f}")
    print(f"today ({TODAY[0]} >= {TODAY[1]}) reads {today_read.sum()} sheets, {paired(today, network)} against the network")
    candidates = [(args.only[0], float(args.only[1]))] if args.only else [(kind, t) for kind in STATISTICS for t in THRESHOLDS]
    eligible = []
    for kind, threshold in candidates:
        on_sheets, read = reading(sheets, kind, threshold, args.tau, args.points)
        on_noise, noise_read = reading(noise, kind, threshold, args.tau, args.points)
        noise_mean = float((on_noise - noise_network).mean())
        print(f"{kind:>8} >= {threshold:<4g}: sheets read {read.sum():2d}, {paired(on_sheets, network)} against the network, "
              f"{paired(on_sheets, today)} against today; noise read {noise_read.sum():2d}, {paired(on_noise, noise_network)} against the network")
        if noise_mean <= NOISE_BOUND:
            eligible.append((float((on_sheets - network).mean()), -threshold, kind))
    if not args.only:
        if eligible:
            mean, threshold, kind = min(eligible)
            print(f"chosen: {kind} >= {-threshold:g} (sheets {mean:+.4f} against the network)")
        else:
            print(f"none reads the noise within +{NOISE_BOUND}: none chosen")


if __name__ == "__main__":
    main()
