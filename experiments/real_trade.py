"""The cloth-for-paper trade: every checkpoint read by ``bench_sheets.py``
in the given CSVs as one point, the real cloth's error against the real
paper's, beside issue 41's targets and the shape-blind references.

Left: ``phisft_R1`` MAE-SN per frame against ``kinect_paper``'s whole
sheet (mm); right: the cloth from the first frame against the crop inside
the paper. Each CSV is one experiment (one colour); its rows named
``shipped``, ``earlier`` or ``network`` (the models runs started from)
are black stars; a reading found in several CSVs is drawn once, in the
first one's colour (``--label STEM=TEXT`` names a CSV in the legend).
Readings must come from the same benchmark (``bench_sheets.py`` since
issue 41's sheets: the earlier model reads the same in all of them).

    python experiments/real_trade.py docs/campaign/sheets41.csv docs/campaign/persp48.csv ... -o docs/campaign/real_trade.png [--label persp48=TEXT]
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STARTS = ("shipped", "earlier", "network")
# x and y columns, their targets (issue 41's), the y reference, the axes' labels.
PANELS = (
    ("phisft_frame", "kinect_mm", 0.200, 5.3, "kinect_bowl", "phisft_R1, MAE-SN per frame", "kinect_paper, whole sheet (mm)"),
    ("phisft_first", "kinect_inner_mm", 0.804, None, "kinect_inner_bowl", "phisft_R1, MAE-SN from the first frame", "kinect_paper, crop inside (mm)"),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csvs", nargs="+", type=Path, help="bench_sheets.py CSVs, each with its .references.json beside it")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the picture (PNG)")
    parser.add_argument("--label", action="append", default=[], metavar="STEM=TEXT", help="a CSV's name in the legend")
    args = parser.parse_args()
    labels = dict(item.split("=", 1) for item in args.label)
    seen, families = set(), {}
    for path in args.csvs:
        with open(path) as f:
            for row in csv.DictReader(f):
                values = tuple(round(float(row[key]), 6) for panel in PANELS for key in panel[:2])
                key = (row["run"], row["epoch"], values)  # a checkpoint read again reads the same
                if key in seen:
                    continue
                seen.add(key)
                family = "start" if row["run"] in STARTS else path.stem
                families.setdefault(family, []).append(values)
    references = json.loads(args.csvs[0].with_suffix(".references.json").read_text())
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    colours = plt.get_cmap("tab10")
    for i, (ax, (_, _, xtarget, ytarget, yref, xlabel, ylabel)) in enumerate(zip(axes, PANELS)):
        for j, (family, points) in enumerate(sorted(families.items(), key=lambda kv: kv[0] == "start")):
            xs, ys = [p[2 * i] for p in points], [p[2 * i + 1] for p in points]
            if family == "start":
                ax.scatter(xs, ys, marker="*", s=160, color="black", zorder=3, label="models the runs started from; the shipped model")
            else:
                ax.scatter(xs, ys, s=18, color=colours(j % 10), marker="o^sD"[j // 10 % 4], label=labels.get(family, family))
        ax.axhline(references[yref], color="grey", linestyle=":", label="fixed bowl (the crop inside's target: below it)")
        ax.axvline(xtarget, color="red", linestyle="--", label="issue 41's target")
        if ytarget is not None:
            ax.axhline(ytarget, color="red", linestyle="--")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
    fig.suptitle("Every checkpoint read on both real videos (lower is better; targets: better than the red lines)")
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    print(f"wrote {args.output}: {sum(map(len, families.values()))} readings from {len(args.csvs)} CSVs")


if __name__ == "__main__":
    main()
