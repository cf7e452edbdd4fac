"""The default's contrast read off anchored refinements
(docs/campaign.md, "The focal length's strain from anchored refinements"):
each candidate ``estimate_focal(anchor=a)`` (``canchor=a`` in
``sheet_levers.py``'s setting) with its contrast gated at ``t`` in place
of today's unanchored contrast at 2 (``MIN_CONTRAST``), the points and
strain gates as they are; the default's reading
(``default_gate.default_reading``: the stage at 0.1 where the gates
hold, the network elsewhere) on the sheets and on ``--noise``, against
today's default and the network, paired per frame. Without ``--only``,
every candidate and the rule's choice; with it, that candidate alone
(the rule's fresh read). With ``--or-today``, each candidate where its
gate holds and today's default elsewhere (which reads where today's
gate holds).

    python experiments/anchor_gate.py docs/reconstruction/anchor_{below,above}_*.csv --noise docs/reconstruction/anchor_noise_*.csv
    python experiments/anchor_gate.py docs/reconstruction/gate_{below,above}_*.csv --noise docs/reconstruction/gate_noise_*.csv --only 0.03 1.5
    python experiments/anchor_gate.py docs/reconstruction/either_{below,above}_*.csv --noise docs/reconstruction/either_noise_*.csv --only 0.03 1.5 --or-today
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from default_gate import MIN_READ, default_reading, lights_agree, rows_of  # noqa: E402
from strain_gate import T, column, paired  # noqa: E402

D = T + ":fov=40:whole=1:moving=1:relmove=0.2:trim=3:contrast=1:estimate=2"
ANCHORS = (0.01, 0.03, 0.09)
THRESHOLDS = (1.1, 1.2, 1.3, 1.4, 1.5, 1.75, 2.0)
MARGIN = 1.2
"""A candidate is eligible where its gate at ``t / MARGIN`` reads none of the selection's noise videos."""
SHEET_BOUND, NOISE_BOUND = 0.002, 0.005
"""The fresh read: against today, the mean plus one standard error at most this; the noise against the network, the mean at most this."""


def setting(anchor: float) -> str:
    return f"{D}:canchor={anchor:g}"


def main() -> None:
    from nrdepth.reconstruct.sheet import MAX_STRAIN, MIN_CONTRAST as TODAY

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs of the sheets (D and D:canchor=a for each anchor)")
    parser.add_argument("--noise", type=Path, nargs="+", required=True, help="sheet_levers.py's CSVs of videos that are no sheet")
    parser.add_argument("--only", nargs=2, type=float, metavar=("ANCHOR", "THRESHOLD"), default=None, help="one candidate, and the rule's fresh criteria")
    parser.add_argument("--or-today", action="store_true", help="each candidate where its gate holds, today's default elsewhere")
    args = parser.parse_args()
    gates = (MAX_STRAIN, MIN_READ, 400)
    sheets, noise = rows_of(args.csv), rows_of(args.noise)
    network, noise_network = column(sheets, "network per frame"), column(noise, "network per frame")
    today, today_read = default_reading(sheets, D, *gates, TODAY)
    today_noise, today_noise_read = default_reading(noise, D, *gates, TODAY)
    print(f"{len(sheets)} sheets: the network {network.mean():.4f}, the bowl {column(sheets, 'bowl per frame').mean():.4f}; "
          f"{len(noise)} noise videos: the network {noise_network.mean():.4f}")
    print(f"today (contrast >= {TODAY:g}) reads {today_read.sum()} sheets, {paired(today, network)} against the network; {lights_agree(sheets, today_read)}")
    candidates = [tuple(args.only)] if args.only else [(a, t) for a in ANCHORS for t in THRESHOLDS]
    eligible = []
    for anchor, threshold in candidates:
        on_sheets, read = default_reading(sheets, setting(anchor), *gates, threshold)
        on_noise, noise_read = default_reading(noise, setting(anchor), *gates, threshold)
        near_noise = default_reading(noise, setting(anchor), *gates, threshold / MARGIN)[1].sum()
        if args.or_today:
            on_sheets, read = np.where(read, on_sheets, today), read | today_read
            on_noise, noise_read = np.where(noise_read, on_noise, today_noise), noise_read | today_noise_read
        print(f"anchor {anchor:<4g} >= {threshold:<4g}: sheets read {read.sum():2d} (both {(read & today_read).sum()}), {paired(on_sheets, today)} against today, "
              f"{paired(on_sheets, network)} against the network; noise read {noise_read.sum()} ({near_noise} at {threshold / MARGIN:.2f}), "
              f"{paired(on_noise, noise_network)} against the network; {lights_agree(sheets, read)}")
        if args.only:
            change = on_sheets - today
            upper = change.mean() + change.std(ddof=1) / np.sqrt(len(change))
            noise_mean = float((on_noise - noise_network).mean())
            print(f"fresh criteria: sheets mean + SE {upper:+.4f} (bound +{SHEET_BOUND}): {'pass' if upper <= SHEET_BOUND else 'FAIL'}; "
                  f"noise {noise_mean:+.4f} (bound +{NOISE_BOUND}): {'pass' if noise_mean <= NOISE_BOUND else 'FAIL'}; against today's noise {paired(on_noise, today_noise)}")
        elif near_noise == 0:
            eligible.append((float((on_sheets - today).mean()), -threshold, anchor))
    if not args.only:
        best = min(eligible) if eligible else None
        if best is not None and best[0] < 0:
            print(f"chosen: anchor {best[2]:g}, contrast >= {-best[1]:g} ({best[0]:+.4f} against today)")
        else:
            print("no eligible candidate reads the sheets better than today: none chosen")


if __name__ == "__main__":
    main()
