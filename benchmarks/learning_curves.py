"""Training: the networks' speed, and learning curves of training runs.

``speed``: Cost of each network architecture, measured in one run: FLOPs per
64×64×16 patch (forward, counted by torch's FlopCounterMode), training
samples/s (forward, loss, backward, Adam step) and inference patches/s, on the
CPU and on CUDA when there is one, each beside its ratio to the paper's
``UNet3D(base=16)`` measured in the same run. The clip generator's rate is
printed too: online training needs it to keep up.

    python benchmarks/learning_curves.py speed [--batch 4] [--steps 5] [--loss aligned_both_signed]
    python benchmarks/learning_curves.py speed --arch unet2p1d:width=32 --arch unet3d:base=8

``curves``: Learning curves: held-out MAE-SN (both alignments), sign-correct and flip
rates of training runs against clips seen and against hours of training,
beside the flat baseline and the paper's figures.

Every ``nrdepth train`` run scores its validation clips (a generator seed no
training batch uses) after each epoch into ``metrics.csv``; this script trains
configurations side by side for the same wall-clock time and draws those rows.

    # two configurations, 60 minutes each, side by side, one torch thread each
    python benchmarks/learning_curves.py curves train --minutes 60 \
        runs/a="--arch unet2p1d --loss aligned_both_signed --steps 100" \
        runs/b="--arch unet3d --base 16 --loss aligned_both_signed --steps 25"
    # curves of any runs (resumed runs included): CSV + PNG
    python benchmarks/learning_curves.py curves plot runs/a runs/b -o docs/learning_curves
    # a warm-started run drawn where it continues another: "A@CLIPS+B" (B's
    # --init was A's weights at CLIPS clips seen; B's clips and hours follow A's)
    python benchmarks/learning_curves.py curves plot runs/a@27200+runs/c -o docs/campaign

Runs that watch a real video (``nrdepth train --real``) get a third row:
its MAE-SN per frame and from the first frame, and its sign-correct share.
``paired A B`` compares two runs that saw the same clips epoch by epoch.

``train`` passes ``--batch-size 8 --epochs 100000 --schedule constant
--validation-clips 64 --workers 0 --device cpu --quiet`` unless the
arguments given override them; a run stopped at the budget resumes where it
stopped when started again (same folder).

    python benchmarks/learning_curves.py speed [--help]
    python benchmarks/learning_curves.py curves [--help]
"""

from __future__ import annotations

# ---- speed ------------------------------------------------------------
MAIN_SPEED_DOC = "Cost of each network architecture, measured in one run: FLOPs per\n64×64×16 patch (forward, counted by torch's FlopCounterMode), training\nsamples/s (forward, loss, backward, Adam step) and inference patches/s, on the\nCPU and on CUDA when there is one, each beside its ratio to the paper's\n``UNet3D(base=16)`` measured in the same run. The clip generator's rate is\nprinted too: online training needs it to keep up.\n\n    python benchmarks/learning_curves.py speed [--batch 4] [--steps 5] [--loss aligned_both_signed]\n    python benchmarks/learning_curves.py speed --arch unet2p1d:width=32 --arch unet3d:base=8\n"
import argparse
import time
from typing import Callable, Dict, List, Tuple

import torch
from torch.utils.flop_counter import FlopCounterMode

import nrdepth
from nrdepth.learning.losses import get_loss
from nrdepth.model import build_model, count_parameters

REFERENCE = ("unet3d", {"base": 16})


def rate(fn: Callable[[], None], items: int, repeats: int) -> float:
    fn()  # warm-up
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return items * repeats / (time.perf_counter() - start)


def forward_flops(model: torch.nn.Module) -> int:
    with torch.no_grad(), FlopCounterMode(display=False) as counter:
        model(torch.zeros(1, 1, 16, 64, 64))
    return counter.get_total_flops()


def parse_arch(text: str) -> Tuple[str, Dict[str, int]]:
    name, _, rest = text.partition(":")
    config = {k: int(v) for k, v in (item.split("=") for item in rest.split(",") if item)}
    return name, config


def main_speed() -> None:
    parser = argparse.ArgumentParser(description=MAIN_SPEED_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--loss", default="aligned_both_signed")
    parser.add_argument("--arch", action="append", default=None, help="NAME[:key=value,...] (repeatable; default: unet2p1d)")
    args = parser.parse_args()
    archs: List[Tuple[str, Dict[str, int]]] = [REFERENCE] + [parse_arch(a) for a in (args.arch or ["unet2p1d"])]

    clips = nrdepth.generate_clips(args.batch, seed=0)
    generator = rate(lambda: nrdepth.generate_clips(args.batch, seed=1), args.batch, args.steps)
    video = torch.from_numpy(clips.video).float().div(255).unsqueeze(1)
    target = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth), 2)
    loss_fn = get_loss(args.loss)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    print(f"batch {args.batch} of 16×64×64, loss {args.loss}, torch threads {torch.get_num_threads()}; clip generator {generator:.1f} clips/s")
    print(f"{'architecture':54s}{'params':>10s}{'GFLOP/patch':>13s}{'device':>8s}{'train/s':>10s}{'×ref':>7s}{'infer/s':>10s}{'×ref':>7s}")
    for device in devices:
        reference: Dict[str, float] = {}
        for name, config in archs:
            torch.manual_seed(0)
            model = build_model(name, **config)
            flops = forward_flops(model)
            model = model.to(device)
            optimiser = torch.optim.Adam(model.parameters(), 1e-3)
            v, t = video.to(device), target.to(device)

            def step() -> None:
                optimiser.zero_grad()
                loss_fn(model(v)[:, 0], t).backward()
                optimiser.step()
                if device == "cuda":
                    torch.cuda.synchronize()

            @torch.no_grad()
            def infer() -> None:
                model(v)
                if device == "cuda":
                    torch.cuda.synchronize()

            train_rate, infer_rate = rate(step, args.batch, args.steps), rate(infer, args.batch, args.steps)
            if not reference:
                reference = {"train": train_rate, "infer": infer_rate}
            label = f"{name}({', '.join(f'{k}={v}' for k, v in model.config.items())})"
            print(f"{label:54s}{count_parameters(model):>10,}{flops / 1e9:>13.2f}{device:>8s}{train_rate:>10.2f}{train_rate / reference['train']:>6.1f}×"
                  f"{infer_rate:>10.2f}{infer_rate / reference['infer']:>6.1f}×")

# ---- curves ------------------------------------------------------------
MAIN_CURVES_DOC = 'Learning curves: held-out MAE-SN (both alignments), sign-correct and flip\nrates of training runs against clips seen and against hours of training,\nbeside the flat baseline and the paper\'s figures.\n\nEvery ``nrdepth train`` run scores its validation clips (a generator seed no\ntraining batch uses) after each epoch into ``metrics.csv``; this script trains\nconfigurations side by side for the same wall-clock time and draws those rows.\n\n    # two configurations, 60 minutes each, side by side, one torch thread each\n    python benchmarks/learning_curves.py curves train --minutes 60 \\\n        runs/a="--arch unet2p1d --loss aligned_both_signed --steps 100" \\\n        runs/b="--arch unet3d --base 16 --loss aligned_both_signed --steps 25"\n    # curves of any runs (resumed runs included): CSV + PNG\n    python benchmarks/learning_curves.py curves plot runs/a runs/b -o docs/learning_curves\n    # a warm-started run drawn where it continues another: "A@CLIPS+B" (B\'s\n    # --init was A\'s weights at CLIPS clips seen; B\'s clips and hours follow A\'s)\n    python benchmarks/learning_curves.py curves plot runs/a@27200+runs/c -o docs/campaign\n\nRuns that watch a real video (``nrdepth train --real``) get a third row:\nits MAE-SN per frame and from the first frame, and its sign-correct share.\n``paired A B`` compares two runs that saw the same clips epoch by epoch.\n\n``train`` passes ``--batch-size 8 --epochs 100000 --schedule constant\n--validation-clips 64 --workers 0 --device cpu --quiet`` unless the\narguments given override them; a run stopped at the budget resumes where it\nstopped when started again (same folder).\n'
import csv
import json
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path

PAPER = {"frame": 0.3832, "first": 0.6133}
"""The paper's ℓ_GBR network on its held-out synthetic clips (its Table 1)."""

DEFAULTS = {"--batch-size": "8", "--epochs": "100000", "--schedule": "constant", "--validation-clips": "64", "--workers": "0", "--device": "cpu", "--quiet": None}


def train(specs: List[str], minutes: float) -> None:
    procs = []
    for spec in specs:
        out, _, extra = spec.partition("=")
        given = shlex.split(extra)
        defaults = [a for flag, value in DEFAULTS.items() if flag not in given for a in ([flag] if value is None else [flag, value])]
        env = dict(os.environ, OMP_NUM_THREADS="1", RAYON_NUM_THREADS="1")
        Path(out).mkdir(parents=True, exist_ok=True)
        log = open(Path(out) / "train.log", "a")
        procs.append(subprocess.Popen([sys.executable, "-m", "nrdepth", "train", out, *given, *defaults], env=env, stdout=log, stderr=subprocess.STDOUT))
        print(f"started {out}: {' '.join(given + defaults)}")
    deadline = time.monotonic() + 60 * minutes
    while time.monotonic() < deadline and any(p.poll() is None for p in procs):
        time.sleep(5)
    for p in procs:
        if p.poll() is None:
            # SIGTERM, not SIGINT: a background job may have SIGINT ignored. The
            # run resumes from its last complete epoch (checkpoints are atomic).
            p.terminate()
    for p in procs:
        p.wait()


def rows(run: Path) -> List[Dict[str, float]]:
    with (run / "metrics.csv").open(newline="") as f:
        # Columns a run added on resume (--real) are empty in its earlier rows.
        return [{k: float(v) for k, v in r.items() if k != "ranks_in_sync" and v != ""} for r in csv.DictReader(f)]


def lineage(spec: str) -> List[Dict[str, float]]:
    """The rows of a run folder, or of a chain of warm starts ``A@CLIPS+B``
    (B started from A's weights at CLIPS clips seen; more links may follow):
    A's rows up to CLIPS, then B's with A's clips and training seconds added."""
    *links, last = spec.split("+")
    parts = []
    for link in links:
        folder, sep, cut = link.rpartition("@")
        if not sep or not cut.isdigit():
            raise SystemExit(f"{spec}: expected RUN@CLIPS before each '+', got {link!r}")
        parts.append((folder, int(cut)))
    out: List[Dict[str, float]] = []
    for folder, cut in parts + [(last, None)]:
        kept = [r for r in rows(Path(folder)) if cut is None or r["clips_seen"] <= cut]
        if cut is not None and (not kept or kept[-1]["clips_seen"] != cut):
            raise SystemExit(f"{folder}@{cut}: its metrics.csv has no epoch ending at {cut} clips")
        clips, seconds = (out[-1]["clips_seen"], out[-1]["train_seconds"]) if out else (0.0, 0.0)
        out += [{**r, "clips_seen": r["clips_seen"] + clips, "train_seconds": r["train_seconds"] + seconds} for r in kept]
    return out


def validation_counts(runs: List[str]) -> List[int]:
    """The distinct validation-set sizes of the run folders in ``runs`` (chains included)."""
    folders = [link.rpartition("@")[0] or link for spec in runs for link in spec.split("+")]
    return sorted({json.loads((Path(f) / "config.json").read_text())["validation_clips"] for f in folders})


TREND_FROM = 8000
"""Trends are fitted from this many clips seen on (before it, the curves bend)."""


def trend(rs: List[Dict[str, float]], key: str) -> float:
    """Change of ``key`` per doubling of the clips seen: the slope of a
    least-squares line in log₂(clips seen), over the epochs from
    :data:`TREND_FROM` clips on."""
    points = [(math.log2(r["clips_seen"]), r[key]) for r in rs if r["clips_seen"] >= TREND_FROM]
    if len(points) < 2:
        return float("nan")
    x_mean = sum(x for x, _ in points) / len(points)
    y_mean = sum(y for _, y in points) / len(points)
    return sum((x - x_mean) * (y - y_mean) for x, y in points) / sum((x - x_mean) ** 2 for x, _ in points)


def plot(runs: List[str], out: Path, labels: List[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.parent.mkdir(parents=True, exist_ok=True)
    table = {label: lineage(run) for label, run in zip(labels, runs)}
    fields = ["run", "epoch", "clips_seen", "train_seconds", "val_mae_sn_frame", "val_mae_sn_first", "val_mae_sn_flat_frame", "val_mae_sn_flat_first", "val_sign_correct", "val_flip"]
    real = [k for k in REAL_COLUMNS if any(k in r for rs in table.values() for r in rs)]
    fields += real
    with out.with_suffix(".csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for label, rs in table.items():
            for r in rs:
                w.writerow({"run": label, **r})
    figure, axes = plt.subplots(3 if real else 2, 3, figsize=(16, 13.5 if real else 9))
    for col, (x_key, x_label, scale) in enumerate([("clips_seen", "clips seen", 1.0), ("train_seconds", "hours of training (on one or two CPU threads, or a GPU, as each run ran)", 1 / 3600)]):
        for row, (align, title) in enumerate([("frame", "MAE-SN, each frame aligned"), ("first", "MAE-SN, alignment from the 1st frame")]):
            ax = axes[row, col]
            for label, rs in table.items():
                ax.plot([r[x_key] * scale for r in rs], [r[f"val_mae_sn_{align}"] for r in rs], marker=".", label=label)
            flat = [r[f"val_mae_sn_flat_{align}"] for rs in table.values() for r in rs]
            ax.axhline(sum(flat) / len(flat), color="gray", linestyle="--", label="flat plane")
            ax.axhline(PAPER[align], color="black", linestyle=":", label="paper (ℓ_GBR, 122,880 clips)")
            ax.set_xlabel(x_label)
            ax.set_title(title)
            if col == 0:
                ax.set_xscale("log")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
    ax = axes[0, 2]
    for label, rs in table.items():
        ax.plot([r["clips_seen"] for r in rs], [100 * r["val_sign_correct"] for r in rs], marker=".", label=label)
    ax.set_xscale("log"), ax.set_xlabel("clips seen"), ax.set_title("relief sign correct, % of frames"), ax.grid(alpha=0.3), ax.legend(fontsize=8)
    ax = axes[1, 2]
    for label, rs in table.items():
        ax.plot([r["clips_seen"] for r in rs], [100 * r["val_flip"] for r in rs], marker=".", label=label)
    ax.set_xscale("log"), ax.set_xlabel("clips seen"), ax.set_title("clips whose relief sign flips, %"), ax.grid(alpha=0.3), ax.legend(fontsize=8)
    if real:
        real_panels(axes[2], table)
    counts = " or ".join(str(n) for n in validation_counts(runs))
    watched = "; bottom row: the real video each run watches (--real)" if real else ""
    figure.suptitle(f"Held-out validation clips ({counts} as each run's config.json says, generator seed + 1,000,003, with the run's own generator settings) after every epoch{watched}")
    figure.tight_layout()
    figure.savefig(out.with_suffix(".png"), dpi=80)
    print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")
    for label, rs in table.items():
        scored = [r for r in rs if "real_mae_sn_frame" in r]
        if scored:
            best_real = min(scored, key=lambda r: r["real_mae_sn_frame"])
            print(f"{label}: real video per frame first {scored[0]['real_mae_sn_frame']:.4f}, last {scored[-1]['real_mae_sn_frame']:.4f}, "
                  f"best {best_real['real_mae_sn_frame']:.4f} at {int(best_real['clips_seen'])} clips (plane {scored[0]['real_flat_frame']:.4f})")
        best = min(rs, key=lambda r: r["val_mae_sn_frame"])
        last = rs[-1]
        print(f"{label}: {len(rs)} epochs, {int(last['clips_seen'])} clips, {last['train_seconds'] / 3600:.2f} h; last {last['val_mae_sn_frame']:.4f} / {last['val_mae_sn_first']:.4f} "
              f"(sign {100 * last['val_sign_correct']:.1f} %, flips {100 * last['val_flip']:.1f} %); best per frame {best['val_mae_sn_frame']:.4f} at {int(best['clips_seen'])} clips")
        print(f"  a doubling of the clips seen (from {TREND_FROM} on): per frame {trend(rs, 'val_mae_sn_frame'):+.4f}, "
              f"from the first frame {trend(rs, 'val_mae_sn_first'):+.4f}, flips {100 * trend(rs, 'val_flip'):+.1f} points")


REAL_COLUMNS = ("real_mae_sn_frame", "real_mae_sn_first", "real_flat_frame", "real_sign_correct")
"""metrics.csv's scores of the real video a run watches (``nrdepth train --real``)."""


def real_panels(axes, table: Dict[str, List[Dict[str, float]]]) -> None:
    """The third row: the watched real video's MAE-SN per frame and from the
    first frame (the flat plane beside them) and its sign-correct share."""
    for ax, key, title in zip(axes, ("real_mae_sn_frame", "real_mae_sn_first", "real_sign_correct"),
                              ("real video (--real): MAE-SN, each frame aligned", "real video: MAE-SN, alignment from the 1st frame",
                               "real video: relief sign correct, % of frames")):
        scale = 100 if key == "real_sign_correct" else 1
        for label, rs in table.items():
            scored = [r for r in rs if key in r]
            ax.plot([r["clips_seen"] for r in scored], [scale * r[key] for r in scored], marker=".", label=label)
        if key == "real_mae_sn_frame":
            flat = [r["real_flat_frame"] for rs in table.values() for r in rs if "real_flat_frame" in r]
            ax.axhline(flat[0], color="gray", linestyle="--", label="flat plane")
        ax.set_xlabel("clips seen"), ax.set_title(title), ax.grid(alpha=0.3), ax.legend(fontsize=8)


def paired(a: str, b: str, key: str) -> None:
    """Two runs that saw the same clips (same seed and batch size) compared
    epoch by epoch: their readings move together, so the mean of the
    per-epoch differences is far less noisy than either curve."""
    x, y = ({int(r["epoch"]): r[key] for r in rows(Path(run)) if key in r} for run in (a, b))
    epochs = sorted(set(x) & set(y))
    if len(epochs) < 2:
        raise SystemExit(f"{key}: fewer than two epochs that both runs scored")
    d = [y[e] - x[e] for e in epochs]
    mean = sum(d) / len(d)
    sd = math.sqrt(sum((v - mean) ** 2 for v in d) / (len(d) - 1))
    print(f"{key}, epochs {epochs[0]}–{epochs[-1]} ({len(d)}): {a} {sum(x[e] for e in epochs) / len(d):.4f}, {b} {sum(y[e] for e in epochs) / len(d):.4f}; "
          f"second − first {mean:+.4f} ± {sd / math.sqrt(len(d)):.4f} (standard error; consecutive epochs are not independent), lower in {sum(v < 0 for v in d)} of {len(d)} epochs")


def main_curves() -> None:
    parser = argparse.ArgumentParser(description=MAIN_CURVES_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train", help="train configurations side by side for the same wall-clock time")
    p.add_argument("specs", nargs="+", metavar="OUT=ARGS", help="run folder and its nrdepth train arguments")
    p.add_argument("--minutes", type=float, required=True)
    p = sub.add_parser("plot", help="CSV and PNG of the runs' validation curves")
    p.add_argument("runs", nargs="+", help="run folders, or chains of warm starts RUN@CLIPS+RUN")
    p.add_argument("-o", "--out", type=Path, default=Path("learning_curves"), help="output path without suffix (.csv and .png are written)")
    p.add_argument("--labels", default=None, help="comma-separated labels (default: the folder names)")
    p = sub.add_parser("paired", help="two runs on the same clips, compared epoch by epoch")
    p.add_argument("runs", nargs=2, help="two run folders")
    p.add_argument("--key", default="real_mae_sn_frame", help="metrics.csv column (default: real_mae_sn_frame)")
    args = parser.parse_args()
    if args.command == "paired":
        paired(*args.runs, args.key)
    elif args.command == "train":
        train(args.specs, args.minutes)
    else:
        labels = args.labels.split(",") if args.labels else [Path(r.split("+")[-1]).name for r in args.runs]
        plot(args.runs, args.out, labels)


COMMANDS = {"speed": main_speed, "curves": main_curves}


if __name__ == "__main__":
    import sys

    command = sys.argv.pop(1) if sys.argv[1:] and sys.argv[1] in COMMANDS else sys.exit(f"usage: {sys.argv[0]} {{{'|'.join(COMMANDS)}}} [--help]")
    COMMANDS[command]()
