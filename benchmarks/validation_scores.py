"""Score models on another run's validation clips, so that runs with
different seeds (hence different validation clips) can be compared on the
same clips: mean MAE-SN (both alignments), the flat baseline, sign-correct
and flip rates, exactly as training's validation computes them.

    python benchmarks/validation_scores.py campaign/unet2p1d_first MODEL [MODEL ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from nrdepth.model import load_model, predict_depth
from nrdepth.train import TrainConfig, evaluate_depth, validation_set


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", help="run folder whose config.json defines the validation clips")
    parser.add_argument("models", nargs="+", help="model.safetensors or run folders")
    args = parser.parse_args()
    saved = json.loads((Path(args.run) / "config.json").read_text())
    # init only starts a run (and may name a path relative to the run's cwd): it does not change the clips.
    config = TrainConfig(**{k: v for k, v in saved.items() if k in TrainConfig.__dataclass_fields__ and k != "init"})
    video, depth, _ = validation_set(config)
    depth_half = torch.nn.functional.avg_pool2d(torch.from_numpy(depth).float(), 2).numpy()
    print(f"{len(video)} validation clips of {args.run} (seed {config.seed})")
    for model in args.models:
        scores = evaluate_depth(predict_depth(load_model(model), video), depth_half)
        print(f"{model}: " + ", ".join(f"{k} {v:.4f}" for k, v in scores.items()))


if __name__ == "__main__":
    main()
