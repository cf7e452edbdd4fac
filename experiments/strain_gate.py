"""The sheet stage's gate on ``refined`` read off ``sheet_levers.py``'s CSVs
(docs/campaign.md, "refined where its lengths hold"): held points in
every frame through ``refined`` (``T``) where their held gate passes and
their keyframes' strain is at most τ, the flow's points through the
joint template (``F``, at 0.3) elsewhere. Without ``--tau``, τ is the
90th percentile of ``T``'s strain over the sheets whose held gate
passes (the rule's selection); with it, that τ is read (the rule's
confirmation). Per frame, for each of ``T``'s scales, the gated stage
paired against ``F`` at 0.3 and the network alone (mean ± standard
error over the sheets). ``--through fov=strain`` reads the settings
through another camera (``sheet_levers.py``'s ``fov``: its columns
``T:fov=...`` and ``F:fov=...``), with each camera's focal length against
the truth (``--fallback``: the camera ``F`` reads through, if another),
and ``--versus fov=40`` pairs the gated stage through it
against the same through that one (the rule in docs/campaign.md, "The
focal length from the strain").

    python experiments/strain_gate.py docs/reconstruction/strain_below.csv docs/reconstruction/strain_above.csv
    python experiments/strain_gate.py docs/reconstruction/strain_check_below.csv docs/reconstruction/strain_check_above.csv --tau 0.0107
    python experiments/strain_gate.py docs/reconstruction/focal_below.csv docs/reconstruction/focal_above.csv --tau 0.0107 --through fov=strain --versus fov=40
    python experiments/strain_gate.py docs/reconstruction/held_focal_below.csv docs/reconstruction/held_focal_above.csv --tau 0.0107 --through fov=strain --fallback fov=held --versus fov=40
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


def named(setting: str, through: str) -> str:
    return setting + (f":{through}" if through else "")


def gated(rows: list, tau: float, min_held: float, held: str, through: str, scale: float) -> tuple:
    """Per sheet: the gated stage's per-frame error through the camera ``through`` with the held setting ``held`` at ``scale``, and whether it holds."""
    t, f = named(held, through), named(F, through)
    holds = (column(rows, f"{t} held") >= min_held) & (column(rows, f"{t} strain") <= tau)
    return np.where(holds, column(rows, per_frame(t, scale)), column(rows, per_frame(f, 0.3))), holds


def paired(a: np.ndarray, b: np.ndarray) -> str:
    d = a - b
    return f"{d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f} (better on {(d < 0).sum()} of {len(d)})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", type=Path, nargs="+", help="sheet_levers.py's CSVs, read as one set")
    parser.add_argument("--tau", type=float, default=None, help="the strain read (default: the 90th percentile of T's over the set)")
    parser.add_argument("--min-held", type=float, default=0.8, help="the held gate (reconstruct.sheet.MIN_HELD)")
    parser.add_argument("--through", default="", help="the camera the settings read through: a fov lever of sheet_levers.py (default: the true one)")
    parser.add_argument("--held", default=T, help="the held setting (default: T, module docstring)")
    parser.add_argument("--versus-held", default=None, help="with --versus: the held setting there (default: --held's)")
    parser.add_argument("--fallback", default=None, help="the camera F reads through (default: --through's)")
    parser.add_argument("--versus", default=None, help="another camera (a fov lever, or 'true'): the gated stage through it, paired")
    args = parser.parse_args()
    rows = [row for path in args.csv for row in csv.DictReader(open(path, newline=""))]
    held, strain = column(rows, f"{named(args.held, args.through)} held"), column(rows, f"{named(args.held, args.through)} strain")
    passes = held >= args.min_held
    tau = float(np.percentile(strain[passes], 90)) if args.tau is None else args.tau
    holds = passes & (strain <= tau)
    fallback = args.through if args.fallback is None else args.fallback
    network, flow = column(rows, "network per frame"), column(rows, per_frame(named(F, fallback), 0.3))
    print(f"{len(rows)} sheets; the held gate passes on {passes.sum()}, their strains {np.sort(strain[passes]).round(4).tolist()}")
    print(f"tau {tau:.6f}{' (the 90th percentile)' if args.tau is None else ''}: T read on {holds.sum()}, F on {len(rows) - holds.sum()}")
    print(f"per frame: the network {network.mean():.4f}, F at 0.3 {flow.mean():.4f}, the bowl {column(rows, 'bowl per frame').mean():.4f}, "
          f"the plane {column(rows, 'plane per frame').mean():.4f}")
    if args.through:
        for setting, through in ((args.held, args.through), (F, fallback)):
            ratio = column(rows, f"{named(setting, through)} focal ratio")
            read = ratio[np.isfinite(ratio)]
            print(f"{named(setting, through)}: the focal length over the truth on {len(read)} sheets: median {np.median(read):.3f}, "
                  f"within 25 % on {np.mean(np.abs(np.log(read)) <= np.log(1.25)):.0%}" + (f" ({np.mean(np.abs(np.log(ratio[passes])) <= np.log(1.25)):.0%} "
                  f"of the {passes.sum()} whose held gate passes)" if setting == args.held else ""))
    for scale in [scale for scale in SCALES if per_frame(named(args.held, args.through), scale) in rows[0]]:  # the scales the run read
        stage = np.where(holds, column(rows, per_frame(named(args.held, args.through), scale)), flow)
        line = f"T at {scale:g}: the gated stage {stage.mean():.4f}, against F at 0.3 {paired(stage, flow)}, against the network {paired(stage, network)}"
        if args.versus is not None:
            other, _ = gated(rows, tau, args.min_held, args.versus_held or args.held, "" if args.versus == "true" else args.versus, scale)
            line += f", against the same through {args.versus} ({other.mean():.4f}) {paired(stage, other)}"
        print(line)


if __name__ == "__main__":
    main()
