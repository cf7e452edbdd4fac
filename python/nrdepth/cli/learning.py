"""``nrdepth train``, ``evaluate`` and ``average``: the learning commands."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from .data import add_generator_options, generator_config

__all__ = ["add_commands"]


def _train(args: argparse.Namespace) -> int:
    from ..learning.config import PAPER, RECOMMENDED, TrainConfig
    from ..learning.train import train

    recipe = {k: v if getattr(args, k) is None else getattr(args, k) for k, v in (PAPER if args.paper else RECOMMENDED).items()}
    config = TrainConfig(
        **recipe, base=args.base, schedule=args.schedule, amplitude=args.amplitude, init=args.init, batch_size=args.batch_size, steps_per_epoch=args.steps, epochs=args.epochs,
        seed=args.seed, data=args.data, generator=generator_config(args),
        validation_clips=args.validation_clips, workers=args.workers, device=args.device, compile=args.compile,
        real=(args.real[0] if len(args.real) == 1 else args.real) if args.real else None, keep_every=args.keep_every, ema=args.ema,
        anchor=args.anchor, rehearsal=args.rehearse,
    )
    summary = train(args.out, config, progress=not args.quiet, max_epochs=args.max_epochs)
    if summary:
        print(json.dumps(summary, indent=2))
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from ..learning.evaluate import evaluate, format_summary

    summary = evaluate(args.model, args.data, args.out, clips=args.clips, config=generator_config(args), device=args.device, readings=args.readings)
    print(format_summary(summary))
    return 0


def _average(args: argparse.Namespace) -> int:
    from ..model import average_models, save_model

    out = Path(args.out)
    path = out if out.suffix == ".safetensors" else out / "model.safetensors"
    if path.exists() and not args.overwrite:
        raise ValueError(f"out: {path} exists; --overwrite replaces it")
    if out.suffix != ".safetensors" and out.exists() and not out.is_dir():
        raise ValueError(f"out: expected a folder or a path ending in .safetensors, got the file {out}")
    model = average_models(args.models, args.weights)
    shares = args.weights or [1.0] * len(args.models)
    recipe = {"models": [str(m) for m in args.models], "weights": [w / sum(shares) for w in shares]}
    extra = {"average": recipe, **({"depth_units": model.depth_units} if model.depth_units else {})}
    path.parent.mkdir(parents=True, exist_ok=True)
    save_model(model, path, extra)
    print(f"wrote {path} (and {path.with_suffix('.json').name}): "
          + " + ".join(f"{w:.4g} × {m}" for w, m in zip(recipe["weights"], recipe["models"])))
    return 0


def _weights(text: str) -> list:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train the depth network (online generation or a dataset); resumes in OUT")
    p.add_argument("out", help="run folder: config, checkpoints, weights, metrics")
    p.add_argument("--paper", action="store_true",
                   help="the paper's recipe: --arch unet3d --loss gbr --target depth --lr 1e-3 (default: the recommended one, "
                        "--arch unet2p1d_deep --loss aligned_both_signed --target observable --lr 3e-4); the options below override either")
    p.add_argument("--loss", default=None, help="gbr | tr_sc | aligned | aligned_clip | aligned_signed | aligned_clip_signed | aligned_both_signed | "
                   "aligned_clip_offsets_signed | aligned_both_offsets_signed | aligned_first | aligned_signed_first (default: aligned_both_signed; see nrdepth.learning.losses)")
    p.add_argument("--arch", default=None, help="unet3d (the paper's) | unet2p1d (factorised, ~15x cheaper) | unet2p1d_global (unet2p1d whose coarsest level sees the whole clip in time) | unet2p1d_deep (unet2p1d with 4 more residual blocks on its coarsest level) (default: unet2p1d_deep)")
    p.add_argument("--schedule", default="cosine", help="cosine | constant (a campaign: --epochs may grow on resume) (default: cosine)")
    p.add_argument("--target", default=None,
                   help="depth (the rendered depth, the paper's) | observable (without the motion along the optical axis that no frame shows) (default: observable)")
    p.add_argument("--amplitude", type=float, default=0.0,
                   help="weight of the relief-amplitude term (targets in window widths; the model learns the relief's scale)")
    p.add_argument("--init", default=None, help="model.safetensors or run folder whose weights start a new run (a warm start)")
    p.add_argument("--epochs", type=int, default=20, help="epochs in the run")
    p.add_argument("--steps", type=int, default=500, help="steps per epoch")
    p.add_argument("--max-epochs", type=int, default=None, help="epochs to run in this call (resume later)")
    p.add_argument("--batch-size", type=int, default=8, help="clips per step")
    p.add_argument("--lr", type=float, default=None, help="Adam's learning rate (default: 3e-4; 1e-3 with --paper)")
    p.add_argument("--base", type=int, default=None, help="width of the first network stage (default: the architecture's, 16 / 24)")
    p.add_argument("--data", default=None, help="dataset folder; default: fresh clips every step")
    p.add_argument("--validation-clips", type=int, default=64, help="held-out clips scored after every epoch")
    p.add_argument("--real", default=None, metavar="NPZ", action="append",
                   help="a real video with ground truth, reconstructed and scored after every epoch (metrics.csv's real_* columns; it does not "
                        "choose the best weights); give it again for several (real_STEM_* columns). Dense: video uint8 (T, H, W), depth (T, H, W), "
                        "NaN where none (benchmarks/bench_real.py --write-phisft); sparse: video, frames, uv, z (benchmarks/bench_real.py --write-kinect)")
    p.add_argument("--ema", type=float, default=0.0, metavar="DECAY",
                   help="score and save an exponential moving average of the weights with this decay per step, e.g. 0.999 (default: 0, the weights themselves)")
    p.add_argument("--anchor", type=float, default=0.0, metavar="RATE",
                   help="with --init: after every step pull the weights back toward the warm start's by lr × RATE of the way "
                        "(L2-SP, decoupled; e.g. 100 at lr 5e-5 is 0.5 %% a step; default: 0, no pull)")
    p.add_argument("--rehearse", type=float, default=0.0, metavar="SHARE",
                   help="share of each batch drawn by the default generator (orthographic coloured noise, the clips the cloth was learnt on), "
                        "the rest by the options below; e.g. 0.5 (default: 0, none)")
    p.add_argument("--keep-every", type=int, default=0, metavar="N",
                   help="also keep every N-th epoch's weights as epochs/epoch_E.safetensors (default: 0, none)")
    p.add_argument("--workers", type=int, default=2, help="DataLoader worker processes")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--compile", action="store_true", help="torch.compile the network")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_generator_options(p)
    p.set_defaults(run=_train)

    p = sub.add_parser("evaluate", help="held-out MAE-SN of a model beside the flat baseline")
    p.add_argument("model", help="model.safetensors or a run folder")
    p.add_argument("data", nargs="?", default=None, help="dataset folder (its test split); default: fresh held-out clips")
    p.add_argument("-o", "--out", default=None, help="folder for per_clip.csv and summary.json")
    p.add_argument("--clips", type=int, default=256, help="clips to score")
    p.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N")
    p.add_argument("--readings", type=int, choices=(1, 2, 4), default=1,
                   help="readings of each clip averaged: 2 adds it mirrored left-right, 4 also upside down (nrdepth.predict_depth)")
    add_generator_options(p)
    p.set_defaults(run=_evaluate)

    p = sub.add_parser("average", help="average the weights of models of one lineage (a model soup)")
    p.add_argument("out", help="output: a path ending in .safetensors, or a folder to write model.safetensors into (model.json beside it)")
    p.add_argument("models", nargs="+", help="two or more model.safetensors files or run folders")
    p.add_argument("--weights", type=_weights, default=None, metavar="W1,W2,...",
                   help="one weight per model, scaled to sum to 1 (default: equal)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output model")
    p.set_defaults(run=_average)
