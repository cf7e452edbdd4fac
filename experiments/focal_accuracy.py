"""How near the truth the focal length the default's points pick lies on
generated sheets (``SheetDecision.focal_estimate``): ``estimate_focal``'s
strains over its grid (``sheet_levers.py``'s ``strains`` column, a
setting with ``contrast=1`` read through the 40° guess) give the
estimate, the guess's ``focal ratio`` the truth. Each sheet (light, clip)
once, from the first CSV that has its curve; the share within 25 % of the
truth, and the median ratio, over every sheet with a curve, over those
whose contrast reaches each threshold, and over those the default reads
(its gates as ``default_gate.py`` reads them: the points left, τ and the
contrast at 2).

    python experiments/focal_accuracy.py docs/reconstruction/*_{below,above}*.csv
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from nrdepth import Camera, GeneratorConfig
from nrdepth.isometric.focal import STEPS, focal_grid, least_strain

sys.path.insert(0, str(Path(__file__).parent))
from default_gate import MIN_READ, holds  # noqa: E402
from strain_gate import T  # noqa: E402

D = T + ":fov=40:whole=1:moving=1:relmove=0.2:trim=3:contrast=1"


def estimates(paths: list, setting: str, through: int = 0) -> np.ndarray:
    """(n, 4): each sheet's estimate over its true focal length, its contrast, whether the default reads it (1 or 0), and
    how many points the estimate read (after the trim where the setting trims).
    ``through``: the setting's ``estimate`` lever (1: its ``focal ratio`` is the estimate's; 2: the estimate's where
    bracketed, :attr:`~nrdepth.isometric.FocalEstimate.inside`; 0: the guess's)."""
    from nrdepth.reconstruct.sheet import MAX_STRAIN, MIN_CONTRAST

    side = GeneratorConfig().size  # the ratio does not depend on it: the guess and the grid both scale with the frame
    focals, guess = focal_grid((side, side)), Camera.guessed((side, side)).focal[0]
    seen = {}
    for path in paths:
        rows = list(csv.DictReader(open(path, newline="")))
        if not rows or f"{setting} strains" not in rows[0]:
            continue
        read = holds(rows, setting, MAX_STRAIN, MIN_READ, 400, MIN_CONTRAST)  # 400: sheet_levers.py's points
        for row, by_default in zip(rows, read):
            key, curve, ratio = (row.get("light"), row.get("clip")), row.get(f"{setting} strains"), row.get(f"{setting} focal ratio")
            if key in seen or not curve or not ratio:
                continue
            strains = np.array([float(v) for v in curve.split()])
            if len(strains) == STEPS:
                estimate = least_strain(focals, strains)
                read_through = estimate.focal if through == 1 or (through == 2 and estimate.inside) else guess
                points = float(row.get(f"{setting} trimmed") or row.get(f"{setting} points") or "nan")
                seen[key] = (estimate.focal / (read_through / float(ratio)), estimate.contrast, float(by_default), points)
    return np.array(list(seen.values())).reshape(-1, 4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs of sheets through pinholes")
    parser.add_argument("--setting", default=D, help="the setting whose strains are read (default: the default's, D)")
    parser.add_argument("--contrasts", default="0,1.35,2,3", help="comma-separated contrast thresholds")
    parser.add_argument("--points", type=int, default=100, help="also over the sheets whose estimate read at least this many points")
    parser.add_argument("--estimate", type=int, choices=(0, 1, 2), default=None,
                        help="the setting's estimate lever, which says whose focal ratio it recorded (default: read off the setting; 0 "
                             "where it is not a setting, e.g. truth)")
    args = parser.parse_args()
    through = args.estimate
    if through is None:
        through = int(next((item.partition("=")[2] for item in args.setting.split(":") if item.startswith("estimate=")), 0))
    found = estimates(args.csv, args.setting, through)
    print(f"{len(found)} sheets with the strain's curve")
    ratio, contrast, read, points = found.T
    subsets = [(f"contrast at least {threshold:g}", contrast >= threshold) for threshold in map(float, args.contrasts.split(","))]
    many = points >= args.points
    subsets += [(f"at least {args.points} points read", many), (f"at least {args.points} points read, contrast at least 2", many & (contrast >= 2)),
                (f"fewer than {args.points} points read", ~many), ("read by the default", read > 0)]
    for label, kept in subsets:
        if kept.any():
            print(f"{label}: {kept.sum()} sheets, the estimate within 25 % of the truth on {np.sum(np.abs(ratio[kept] - 1) <= 0.25)} "
                  f"({np.mean(np.abs(ratio[kept] - 1) <= 0.25):.0%}), median ratio {np.median(ratio[kept]):.3f} "
                  f"(10th–90th percentile {np.percentile(ratio[kept], 10):.2f}–{np.percentile(ratio[kept], 90):.2f})")


if __name__ == "__main__":
    main()
