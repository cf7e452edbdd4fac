"""Two readings of the same videos, paired: one column of a per-video CSV
(``isometric_generated.py --csv``) against a column of the same or another
CSV, matched by the videos' ``light`` and ``clip``. Prints each reading's
mean, their paired difference (mean ± standard error), and on how many
videos the first is lower (better).

    python experiments/paired.py A.csv "fused at 0.2 per frame" B.csv "fused at 0.3 per frame"
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np


def column(path: Path, name: str) -> dict:
    """``name``'s values in ``path``, keyed by (light, clip)."""
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    if not rows or name not in rows[0]:
        raise SystemExit(f"{path}: no column {name!r}; its columns: {list(rows[0]) if rows else []}")
    return {(row["light"], row["clip"]): float(row[name]) for row in rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("first_csv", type=Path)
    parser.add_argument("first_column")
    parser.add_argument("second_csv", type=Path)
    parser.add_argument("second_column")
    args = parser.parse_args()
    first, second = column(args.first_csv, args.first_column), column(args.second_csv, args.second_column)
    videos = sorted(set(first) & set(second))
    if len(videos) < 2 or len(videos) != len(first) or len(videos) != len(second):
        raise SystemExit(f"expected the same videos in both CSVs, got {len(first)} and {len(second)} with {len(videos)} in common")
    a, b = np.array([first[v] for v in videos]), np.array([second[v] for v in videos])
    difference = a - b
    print(f"{len(videos)} videos: {args.first_column} ({args.first_csv.name}) {a.mean():.4f}, "
          f"{args.second_column} ({args.second_csv.name}) {b.mean():.4f}; "
          f"paired difference {difference.mean():+.4f} ± {difference.std(ddof=1) / math.sqrt(len(videos)):.4f}, "
          f"the first lower on {int(np.sum(difference < 0))} of {len(videos)}")


if __name__ == "__main__":
    main()
