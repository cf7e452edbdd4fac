"""Sheets: checkpoints along training runs scored on what issue 41 decides
with, each beside the shape-blind references.

For every model (the shipped one, and ``--run FOLDER`` runs' kept epochs,
``epochs/epoch_E.safetensors``), one row of ``--csv``:

- ``heldout_frame`` / ``heldout_first``: MAE-SN on the 128 held-out clips
  (``nrdepth evaluate``'s seed, the default generator);
- ``backdrops_frame``: the same sheets seen whole (``backdrop_probability=1``:
  the border and a background in view), MAE-SN per frame on the sheet;
  references ``backdrops_plane`` / ``backdrops_bowl``;
- ``sheets_frame``: generated sheets, the new family (``GeneratorConfig``'s
  ``sheet_probability=1`` and the print textures among the others), 32
  videos of 256²×16 at a held-out seed, stitched as ``reconstruct`` does,
  MAE-SN per frame; references ``sheets_plane`` / ``sheets_bowl``;
- ``phisft_frame`` / ``phisft_first`` / ``phisft_sign``: the real cloth
  (``bench_real.phisft``'s crop); ``phisft_border`` / ``phisft_inside``:
  its per-frame error within ``nrdepth.scores.real.PHISFT_BORDER`` pixels of the
  background and further in (``nrdepth.scores.real.region_errors``);
- ``kinect_mm`` / ``kinect_sign`` (the whole sheet) and ``kinect_inner_mm``
  (``nrdepth.scores.real.KINECT_INNER``): the real bending paper on ``gt_mdh.npz``.

A picture (``--plot``) draws each score against the clips a run has seen,
the references as horizontal lines; at 0 clips, the row named by
``--start`` (default ``shipped``): the model the runs started from.

    python benchmarks/bench_sheets.py --run campaign/sheets41 --run campaign/sheets41_control \\
        --epochs 3,6,9,12,15 --csv docs/campaign/sheets41.csv --plot docs/campaign/sheets41.png \
        --label "sheets41=half the clips sheets, print textures" --label "sheets41_control=control"
    python benchmarks/bench_sheets.py --model soup=avg.safetensors --csv soups.csv     # any model besides the shipped one
    python benchmarks/bench_sheets.py --plot docs/campaign/sheets41.png --csv docs/campaign/sheets41.csv --replot --label ...
    python benchmarks/bench_sheets.py --csv docs/campaign/sheets41.csv --replot --pair sheets41=sheets41_control   # paired differences
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
import torch

import nrdepth
from nrdepth.learning.evaluate import TEST_SEED, evaluate
from nrdepth.engine.generate import GeneratorConfig, generate_clips
from nrdepth.scores.metrics import dense_baselines, flat_baseline, mae_sn, sign_rates
from nrdepth.model.io import DEFAULT_MODEL
from nrdepth.reconstruct import inference_model
from nrdepth.io import read_video

from nrdepth.scores.generated import SHEET_FAMILIES
from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_references, kinect_score, kinect_truth, phisft_regions, region_errors

SHEETS_SEED = TEST_SEED + 41
PHISFT_CROP = (110, 218, 106, 214)
FAMILIES = SHEET_FAMILIES


def sheet_config(backdrops: bool = False) -> GeneratorConfig:
    return GeneratorConfig(size=256, grid=128, sheet_probability=1.0, texture_families=FAMILIES, backdrop_probability=float(backdrops))


class Scorer:
    """The fixed inputs (generated sheets, both real videos), loaded once."""

    def __init__(self, sheets: int) -> None:
        clips = generate_clips(sheets, seed=SHEETS_SEED, config=sheet_config())
        self.sheets = (clips.video, clips.depth)
        clips = generate_clips(sheets, seed=SHEETS_SEED, config=sheet_config(backdrops=True))
        self.backdrops = (clips.video, clips.depth)
        data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
        top, bottom, left, right = PHISFT_CROP
        self.cloth = data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
        self.cloth_regions = phisft_regions(*self.cloth)
        self.truth = kinect_truth()
        frames = read_video(DATA / "kinect_paper").frames
        self.kinect = {region: frames[:, region[1] : region[1] + region[3], region[0] : region[0] + region[2]] for region in (KINECT_ROI, KINECT_INNER)}

    def references(self) -> dict:
        video, depth = self.sheets
        bases = [dense_baselines(d) for d in depth]
        cloth = dense_baselines(self.cloth[1], mask=np.isfinite(self.cloth[1]))
        framed = [dense_baselines(d, mask=np.isfinite(d)) for d in self.backdrops[1]]
        return {
            "sheets_plane": np.mean([b["plane"] for b in bases]), "sheets_bowl": np.mean([b["bowl"] for b in bases]),
            "sheets_quadratic": np.mean([b["quadratic"] for b in bases]),
            "backdrops_plane": np.mean([b["plane"] for b in framed]), "backdrops_bowl": np.mean([b["bowl"] for b in framed]),
            "phisft_plane": cloth["plane"], "phisft_bowl": cloth["bowl"], "phisft_quadratic": cloth["quadratic"],
            "phisft_plane_first": flat_baseline(self.cloth[1], "first", mask=np.isfinite(self.cloth[1])),
            **{f"phisft_plane_{k}": v for k, v in region_errors(np.zeros_like(self.cloth[1]), self.cloth[1], self.cloth_regions).items()},
            **{f"kinect{tag}_{k}": v for tag, region in (("", KINECT_ROI), ("_inner", KINECT_INNER)) for k, v in kinect_references(self.truth, region).items()},
        }

    def score(self, path) -> dict:
        model = inference_model(path, torch.device("cpu"))
        row = {}
        held = evaluate(path, clips=128, device="cpu")
        row["heldout_frame"], row["heldout_first"] = held["mae_sn_frame"]["mean"], held["mae_sn_first"]["mean"]
        video, depth = self.sheets
        row["sheets_frame"] = float(np.mean([mae_sn(nrdepth.reconstruct(v, model, sheet_stage=False), d) for v, d in zip(video, depth)]))
        video, depth = self.backdrops
        row["backdrops_frame"] = float(np.mean([mae_sn(nrdepth.reconstruct(v, model, sheet_stage=False), d, mask=np.isfinite(d)) for v, d in zip(video, depth)]))
        gray, truth = self.cloth
        mask = np.isfinite(truth)
        pred = nrdepth.reconstruct(gray, model, sheet_stage=False)
        row["phisft_frame"], row["phisft_first"] = mae_sn(pred, truth, "frame", mask=mask), mae_sn(pred, truth, "first", mask=mask)
        row["phisft_sign"] = sign_rates(pred, truth, mask=mask)["sign_correct"]
        row.update({f"phisft_{k}": v for k, v in region_errors(pred, truth, self.cloth_regions).items()})
        for tag, region in (("", KINECT_ROI), ("_inner", KINECT_INNER)):
            pred = nrdepth.reconstruct(self.kinect[region], model, sheet_stage=False)
            row[f"kinect{tag}_mm"] = kinect_score(pred, self.truth, region)
            row[f"kinect{tag}_sign"] = kinect_score(pred, self.truth, region, signs=True)
        return row


def clips_seen(run: Path, epoch: int) -> int:
    with open(run / "metrics.csv") as f:
        return next(int(r["clips_seen"]) for r in csv.DictReader(f) if int(r["epoch"]) == epoch)


PANELS = (
    ("kinect_mm", "kinect_paper, whole sheet (mm)", ("kinect_plane", "kinect_bowl")),
    ("kinect_inner_mm", "kinect_paper, crop inside (mm)", ("kinect_inner_plane", "kinect_inner_bowl")),
    ("phisft_frame", "phisft_R1, MAE-SN per frame", ("phisft_plane", "phisft_bowl")),
    ("phisft_first", "phisft_R1, MAE-SN from the first frame", ("phisft_plane_first",)),
    ("phisft_border", "phisft_R1, per frame, ≤ 10 px from the border", ("phisft_plane_border",)),
    ("phisft_inside", "phisft_R1, per frame, further inside", ("phisft_plane_inside",)),
    ("sheets_frame", "generated sheets, MAE-SN per frame", ("sheets_plane", "sheets_bowl")),
    ("backdrops_frame", "generated sheets seen whole, on the sheet", ("backdrops_plane", "backdrops_bowl")),
    ("heldout_frame", "held-out clips, MAE-SN per frame", ()),
)


TITLE = "Warm starts (at 0 clips: the model they started from), each against a control with the same seed, clips and steps"


def plot(rows: list, references: dict, path: Path, labels: dict, start: str = "shipped", suptitle: str = TITLE) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [p for p in PANELS if any(p[0] in r for r in rows)]  # rows written before a score was added lack it
    fig, axes = plt.subplots(2, (len(panels) + 1) // 2, figsize=(4.4 * ((len(panels) + 1) // 2), 7), constrained_layout=True, squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.axis("off")
    runs = sorted({r["run"] for r in rows if r["run"] != start and r["clips_seen"] > 0})
    start_row = next((r for r in rows if r["run"] == start), None)
    if start_row is None:
        raise SystemExit(f"--start {start}: expected a row of that name in the CSV, the model the runs started from")
    for ax, (key, title, refs) in zip(axes.flat, panels):
        for run in runs:
            points = sorted((r["clips_seen"], r[key]) for r in rows if r["run"] == run and key in r)
            points = ([(0, start_row[key])] if key in start_row else []) + points
            if not points:
                continue
            x, y = zip(*points)
            ax.plot(np.array(x) / 1000, y, marker="o", label=labels.get(run, run))
        for ref, style in zip([r for r in refs if r in references], ("--", ":")):
            ax.axhline(references[ref], color="grey", linestyle=style, label="plane" if "_plane" in ref else ref.split("_")[-1])
        ax.set_title(title)
        ax.set_xlabel("clips seen after the warm start (thousands)")
        ax.legend(fontsize=8)
    fig.suptitle(suptitle)
    fig.savefig(path, dpi=90)


def paired(rows: list, run: str, control: str) -> str:
    """A markdown table: each score's mean over the epochs both runs kept,
    and the run minus the control paired by epoch (mean ± standard error)."""
    by_epoch = lambda name: {int(r["epoch"]): r for r in rows if r["run"] == name}  # noqa: E731
    mine, theirs = by_epoch(run), by_epoch(control)
    epochs = sorted(set(mine) & set(theirs))
    if len(epochs) < 2:
        raise SystemExit(f"--pair {run}={control}: expected at least 2 epochs both kept, got {epochs}")
    lines = [f"{run} against {control}, epochs {', '.join(map(str, epochs))}:", "", f"| | {control} | {run} | difference |", "|---|---|---|---|"]
    for key, title, _ in PANELS:
        if any(key not in row[e] for row in (mine, theirs) for e in epochs):
            continue
        a, b = np.array([theirs[e][key] for e in epochs]), np.array([mine[e][key] for e in epochs])
        d = b - a
        lines.append(f"| {title} | {a.mean():.4f} | {b.mean():.4f} | {d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--run", action="append", type=Path, default=[], help="a run folder with epochs/ (again for several)")
    parser.add_argument("--epochs", default="3,6,9,12,15", help="kept epochs to score")
    parser.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                        help="another model to score, e.g. a weight average (again for several)")
    parser.add_argument("--sheets", type=int, default=32, help="generated sheet videos")
    parser.add_argument("--csv", type=Path, default=Path("sheets.csv"))
    parser.add_argument("--plot", type=Path, default=None)
    parser.add_argument("--replot", action="store_true", help="only draw --plot from --csv")
    parser.add_argument("--start", default="shipped", metavar="RUN",
                        help="with --replot, the row drawn at 0 clips: the model the runs started from")
    parser.add_argument("--title", default=TITLE, help="with --replot, the plot's title")
    parser.add_argument("--label", action="append", default=[], metavar="RUN=TEXT", help="a run's name in the plot's legend")
    parser.add_argument("--pair", action="append", default=[], metavar="RUN=CONTROL",
                        help="print RUN minus CONTROL paired by epoch, over the epochs both kept (again for several)")
    args = parser.parse_args()
    labels = dict(item.split("=", 1) for item in args.label)
    refs_path = args.csv.with_suffix(".references.json")
    if args.replot:
        with open(args.csv) as f:
            rows = [{k: (v if k == "run" else float(v)) for k, v in r.items() if v != ""} for r in csv.DictReader(f)]
        if args.plot:
            plot(rows, json.loads(refs_path.read_text()), args.plot, labels, args.start, args.title)
        for pair in args.pair:
            print(paired(rows, *pair.split("=", 1)), end="\n\n")
        return
    scorer = Scorer(args.sheets)
    references = {k: float(v) for k, v in scorer.references().items()}
    refs_path.write_text(json.dumps(references, indent=1))
    print("references:", ", ".join(f"{k} {v:.4f}" for k, v in references.items()), flush=True)
    models = [("shipped", 0, 0, DEFAULT_MODEL)]
    for run in args.run:
        models += [(run.name, e, clips_seen(run, e), run / "epochs" / f"epoch_{e}.safetensors") for e in map(int, args.epochs.split(","))]
    models += [(name, 0, 0, Path(path)) for name, path in (m.split("=", 1) for m in args.model)]
    rows = []
    for run, epoch, seen, path in models:
        start = time.perf_counter()
        rows.append({"run": run, "epoch": epoch, "clips_seen": seen, **scorer.score(path)})
        print(", ".join(f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}" for k, v in rows[-1].items()), f"({time.perf_counter() - start:.0f} s)", flush=True)
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    if args.plot:
        plot(rows, references, args.plot, labels)
    for pair in args.pair:
        print(paired(rows, *pair.split("=", 1)), end="\n\n")


if __name__ == "__main__":
    main()
