"""The sheet stage by default, read off ``sheet_levers.py``'s CSVs
(docs/campaign.md, "The sheet's shape by default"):

1. the held gate on the points read: the given-sheet stage (``T`` at 0.1
   where at least :data:`MIN_READ` of the points asked for are read and their
   strain is at most τ, ``F`` at 0.3 elsewhere) against the stage with
   the gate on the point-frames held (``--min-held``), paired per frame;
2. the default: ``T`` through the 40° guess over the whole frame
   (``$T:fov=40:whole=1``) at 0.1 where the same gate holds, the network
   elsewhere, against the network alone, paired per frame, on the sheets
   and (``--noise``) on videos that are no sheet;
3. (``--versus-stage HELD FLOW``) with the focal length given but no
   sheet: the default's reading where its gate holds, the flow's points
   (FLOW at 0.3) elsewhere (with ``--then-stage``, the stage as it is
   elsewhere), against the stage as it read such a video before (HELD at
   0.1 where its point-frames held and strain pass, FLOW at 0.3 elsewhere);
4. (``--versus-default SETTING``) a lever on the default: ``--default``'s
   reading (its own gates, the network elsewhere) against SETTING's read
   the same way, paired per frame, on the sheets and on ``--noise``; and
   for each, how often the two lights (which share each sheet's geometry)
   agree on reading a sheet.

    python experiments/default_gate.py docs/reconstruction/default_below.csv docs/reconstruction/default_above.csv
    python experiments/default_gate.py docs/reconstruction/moving_below.csv docs/reconstruction/moving_above.csv --default "$T:fov=40:whole=1:moving=1" \
        --noise docs/reconstruction/long_noise_1030.csv docs/reconstruction/long_noise_1046.csv docs/reconstruction/long_noise_1061.csv
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from strain_gate import F, T, column, paired, per_frame  # noqa: E402

DEFAULT = T + ":fov=40:whole=1"
MIN_READ = 0.1
"""The proposal's gate: at least this share of the points asked for read."""


def rows_of(paths: list) -> list:
    return [row for path in paths for row in csv.DictReader(open(path, newline=""))]


def holds(rows: list, setting: str, tau: float, min_read: float, points: int, min_contrast: float = 0.0) -> np.ndarray:
    """Per video: whether ``setting``'s points read (with ``trim``, those it leaves) number at least ``min_read`` of ``points``, their strain is at most
    ``tau`` and, with ``min_contrast``, ``estimate_focal``'s contrast on them at least that (NaN: no program)."""
    number = lambda name: np.array([float(row.get(f"{setting} {name}", "nan") or "nan") for row in rows])  # noqa: E731
    counted = "trimmed" if f"{setting} trimmed" in rows[0] else "points"  # with trim: the points left by it
    read = (number(counted) >= min_read * points) & (number("strain") <= tau)
    return read & (number("contrast") >= min_contrast) if min_contrast else read


def default_reading(rows: list, setting: str, tau: float, min_read: float, points: int, min_contrast: float = 0.0) -> tuple:
    read = holds(rows, setting, tau, min_read, points, min_contrast)
    return np.where(read, column(rows, per_frame(setting, 0.1)), column(rows, "network per frame")), read


def lights_agree(rows: list, read: np.ndarray) -> str:
    """Of the clips read under both lights (which share each sheet's geometry), how many either light reads and how many both."""
    by_clip: dict = {}
    for row, was_read in zip(rows, read):
        by_clip.setdefault(row["clip"], []).append(bool(was_read))
    pairs = [reads for reads in by_clip.values() if len(reads) == 2]
    return f"of {len(pairs)} sheets under both lights, either reads {sum(any(p) for p in pairs)}, both {sum(all(p) for p in pairs)}"


def main() -> None:
    from nrdepth.reconstruct.sheet import MAX_STRAIN

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs of the sheets (settings F, T and the default), read as one set")
    parser.add_argument("--noise", type=Path, nargs="*", default=[], help="sheet_levers.py's CSVs of videos that are no sheet (the default setting)")
    parser.add_argument("--tau", type=float, default=MAX_STRAIN)
    parser.add_argument("--min-read", type=float, default=MIN_READ)
    parser.add_argument("--min-held", type=float, default=0.8, help="the gate on the point-frames held, before")
    parser.add_argument("--points", type=int, default=400, help="the points asked for (sheet_levers.py's points)")
    parser.add_argument("--min-contrast", type=float, default=0.0, help="also estimate_focal's contrast at least this (sheet_levers.py's contrast lever)")
    parser.add_argument("--default", default=DEFAULT, help="the default's setting (default: T through the guess over the whole frame)")
    parser.add_argument("--versus-stage", nargs=2, metavar=("HELD", "FLOW"), default=None,
                        help="3. a focal length given, no sheet: the default's reading at 0.1 where its gate holds, FLOW at 0.3 elsewhere, against "
                        "the stage as it was: HELD at 0.1 where its point-frames held reach --min-held and its strain τ, FLOW at 0.3 elsewhere")
    parser.add_argument("--then-stage", action="store_true", help="3. where the default's gate does not hold, the stage as it was, not FLOW")
    parser.add_argument("--versus-default", metavar="SETTING", default=None,
                        help="4. --default's reading against SETTING's, each gated as the default gates, the network elsewhere")
    args = parser.parse_args()
    rows = rows_of(args.csv)
    network = column(rows, "network per frame")
    print(f"{len(rows)} sheets; the network {network.mean():.4f}, the bowl {column(rows, 'bowl per frame').mean():.4f}, the plane {column(rows, 'plane per frame').mean():.4f}")
    if per_frame(F, 0.3) in rows[0]:  # the given-sheet stage's two gates
        flow, held = column(rows, per_frame(F, 0.3)), column(rows, per_frame(T, 0.1))
        before = (column(rows, f"{T} held") >= args.min_held) & (column(rows, f"{T} strain") <= args.tau)
        after = holds(rows, T, args.tau, args.min_read, args.points)
        stage_before, stage_after = np.where(before, held, flow), np.where(after, held, flow)
        print(f"1. T read on {before.sum()} with the gate on the point-frames held, on {after.sum()} with the gate on the points read: "
              f"{stage_after.mean():.4f} against {stage_before.mean():.4f}, {paired(stage_after, stage_before)}")
    default, read = default_reading(rows, args.default, args.tau, args.min_read, args.points, args.min_contrast)
    print(f"2. the default reads {read.sum()} of {len(rows)} sheets: {default.mean():.4f} against the network {paired(default, network)}; "
          f"where read, {paired(default[read], network[read])}")
    if args.versus_stage:
        held, flow = args.versus_stage
        fallback = column(rows, per_frame(flow, 0.3))
        before = (column(rows, f"{held} held") >= args.min_held) & (column(rows, f"{held} strain") <= args.tau)
        stage = np.where(before, column(rows, per_frame(held, 0.1)), fallback)
        proposed = np.where(read, column(rows, per_frame(args.default, 0.1)), stage if args.then_stage else fallback)
        elsewhere = "the stage" if args.then_stage else flow
        print(f"3. with the focal length: the default's reading on {read.sum()}, {elsewhere} elsewhere, {proposed.mean():.4f}, against the stage as it was "
              f"(held on {before.sum()}) {stage.mean():.4f}: {paired(proposed, stage)}")
    gates = (args.tau, args.min_read, args.points, args.min_contrast)
    if args.versus_default:
        was, read_was = default_reading(rows, args.versus_default, *gates)
        print(f"4. the default reads {read.sum()} (both {(read & read_was).sum()}), {args.versus_default} {read_was.sum()}: {default.mean():.4f} against "
              f"{was.mean():.4f}, {paired(default, was)}")
        print(f"   the default: {lights_agree(rows, read)}; {args.versus_default}: {lights_agree(rows, read_was)}")
    if args.noise:
        noise = rows_of(args.noise)
        default, read = default_reading(noise, args.default, *gates)
        net = column(noise, "network per frame")
        print(f"   not sheets: the default reads {read.sum()} of {len(noise)}: {default.mean():.4f} against the network {net.mean():.4f}, {paired(default, net)}")
        if args.versus_default:
            was, read_was = default_reading(noise, args.versus_default, *gates)
            print(f"   not sheets, against {args.versus_default} (reads {read_was.sum()}): {paired(default, was)}")


if __name__ == "__main__":
    main()
