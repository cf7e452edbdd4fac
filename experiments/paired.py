"""Two readings of the same videos, paired: one column of a per-video CSV
(``isometric_generated.py --csv``) against a column of the same or another
CSV, matched by the videos' ``light`` and ``clip``. Prints each reading's
mean, their paired difference (mean ± standard error), and on how many
videos the first is lower (better). With ``--best``: how far a choice
per video could go, the mean over the videos of each one's lowest reading
per frame among every reading of the CSVs given (the plane and the bowl
aside), picked by its truth, beside the plane.

    python experiments/paired.py A.csv "fused at 0.2 per frame" B.csv "fused at 0.3 per frame"
    python experiments/paired.py --best A.csv B.csv
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np


def read(path: Path, *names: str) -> list:
    """``path``'s rows, one a video, checked to have ``light``, ``clip`` and ``names``."""
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    missing = [n for n in ("light", "clip", *names) if not rows or n not in rows[0]]
    if missing:
        raise SystemExit(f"{path}: expected a row per video with the columns {missing}; its columns: {list(rows[0]) if rows else []}")
    return rows


def column(path: Path, name: str) -> dict:
    """``name``'s values in ``path``, keyed by (light, clip)."""
    rows = read(path, name)
    return {(row["light"], row["clip"]): float(row[name]) for row in rows}


def best(paths: list) -> None:
    """Each video's lowest reading per frame among every reading of ``paths``, averaged, beside the plane."""
    readings, plane = {}, {}
    for path in paths:
        rows = read(path, "plane per frame")
        names = [n for n in rows[0] if n.endswith(" per frame") and n not in ("plane per frame", "bowl per frame")]
        for row in rows:
            video = (row["light"], row["clip"])
            readings.setdefault(video, []).extend(float(row[n]) for n in names)
            plane[video] = float(row["plane per frame"])
    count = {len(r) for r in readings.values()}
    if len(count) != 1:
        raise SystemExit(f"expected the same videos in every CSV, got videos with {sorted(count)} readings")
    lowest = np.mean([min(r) for r in readings.values()])
    print(f"{len(readings)} videos, the best of {count.pop()} readings on each: {lowest:.4f} per frame, "
          f"{lowest / np.mean(list(plane.values())):.3f}× the plane ({np.mean(list(plane.values())):.4f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("pair", nargs="*", metavar="CSV COLUMN", help="the first CSV and its column, the second CSV and its column")
    parser.add_argument("--best", nargs="+", type=Path, metavar="CSV", help="the best reading of each video among every reading of these CSVs")
    args = parser.parse_args()
    if args.best:
        return best(args.best)
    if len(args.pair) != 4:
        parser.error("expected FIRST_CSV FIRST_COLUMN SECOND_CSV SECOND_COLUMN, or --best CSV [CSV ...]")
    (first_csv, first_name), (second_csv, second_name) = (Path(args.pair[0]), args.pair[1]), (Path(args.pair[2]), args.pair[3])
    first, second = column(first_csv, first_name), column(second_csv, second_name)
    videos = sorted(set(first) & set(second))
    if len(videos) < 2 or len(videos) != len(first) or len(videos) != len(second):
        raise SystemExit(f"expected the same videos in both CSVs, got {len(first)} and {len(second)} with {len(videos)} in common")
    a, b = np.array([first[v] for v in videos]), np.array([second[v] for v in videos])
    difference = a - b
    print(f"{len(videos)} videos: {first_name} ({first_csv.name}) {a.mean():.4f}, "
          f"{second_name} ({second_csv.name}) {b.mean():.4f}; "
          f"paired difference {difference.mean():+.4f} ± {difference.std(ddof=1) / math.sqrt(len(videos)):.4f}, "
          f"the first lower on {int(np.sum(difference < 0))} of {len(videos)}")


if __name__ == "__main__":
    main()
