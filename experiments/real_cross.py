"""Which pass carries a model's reading of each real video: ``reconstruct``
with one model's coarse pass and another's fine pass, on both real videos
(``bench_real.py``'s regions): ``phisft_R1`` MAE-SN per frame, from the
first frame and at its border / inside, and ``kinect_paper`` mm on the
whole sheet and on the crop inside it.

``--mix W,...`` instead reads with the first model's fine pass and a coarse
pass that averages the first two models' coarse readings, the second's at
weight W (each 16-frame window's reading standardised first, so W = 0 is
the first model with its windows standardised). Each model is read
without a coarse companion ('default' is the shipped network alone;
``default python/nrdepth/weights/default_coarse.safetensors --mix 0.25``
is the shipped model).

    python experiments/real_cross.py MODEL MODEL [...]                  # 'default': the shipped network
    python experiments/real_cross.py MODEL MODEL --mix 0,0.25,0.5,0.75
    python experiments/real_cross.py MODEL MODEL --mix 0,0.25 --generated 32 [--camera pinhole]
    python experiments/real_cross.py default CANDIDATE --mix 0.25,0.5 --reference python/nrdepth/weights/default_coarse.safetensors:0.25

``--reference COMPANION:W`` adds the reading with COMPANION at weight W in
place of the second model (``python/nrdepth/weights/default_coarse.safetensors:0.25``:
the shipped model), to compare a candidate companion with the shipped one.

``--generated N`` scores the same readings, with ``--mix``, on N generated
videos of 256²×48 (orthographic, and through a pinhole of 40–80° seen
whole) against their observable depth: MAE-SN per frame and from the first
frame, paired against the first model as it is, or against the reference
if one is named (± the standard error).
A video's readings share one fine pass, which does not depend on the
coarse one (the same bytes as separate runs; three readings in 19 s, not 42).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np
import torch

from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_score, kinect_truth, phisft_at_bin, phisft_regions, region_errors
from coarse_chain import CAMERAS  # noqa: E402  (a sibling script: experiments/ is on the path when one runs)

import nrdepth  # noqa: E402
from nrdepth.learning.evaluate import TEST_SEED  # noqa: E402
from nrdepth.engine.generate import observable_depth  # noqa: E402
from nrdepth.scores.metrics import mae_sn  # noqa: E402
from nrdepth.io import read_video  # noqa: E402
from nrdepth.reconstruct import inference_model  # noqa: E402

# The stand-ins go into the modules that call the two passes (the package's names are only re-exports).
pipeline, stitching = sys.modules["nrdepth.reconstruct.pipeline"], sys.modules["nrdepth.reconstruct.stitching"]
original_coarse_half, original_field_windows = pipeline.coarse_half, stitching.field_windows


def coarse_reading(coarse_net, other=None, weight: float = 0.0):
    """A stand-in for ``coarse_half`` that reads with ``coarse_net``, or with
    ``other`` as its coarse companion at ``weight`` (both readings'
    windows standardised, as ``coarse_half`` blends a companion)."""
    def read(small, net, *args, **kw):
        if other is None:
            return original_coarse_half(small, coarse_net, *args, **kw)
        own, coarse_net.coarse_companion = getattr(coarse_net, "coarse_companion", None), (other, weight)
        try:
            return original_coarse_half(small, coarse_net, *args, **kw)
        finally:
            coarse_net.coarse_companion = own

    return read


def scores(coarse, fine_model, cloth: tuple, paper: tuple) -> str:
    """One table row: both videos reconstructed with the coarse pass ``coarse``."""
    pipeline.coarse_half = coarse
    try:
        video, truth, regions = cloth
        depth = nrdepth.reconstruct(video, fine_model, sheet_stage=False)
        scored, r = np.isfinite(truth), region_errors(depth, truth, regions)
        row = f"{mae_sn(depth, truth, 'frame', mask=scored):8.4f}{mae_sn(depth, truth, 'first', mask=scored):8.4f}{r['border']:8.4f}{r['inside']:8.4f}"
        frames, points = paper
        for x, y, w, h in (KINECT_ROI, KINECT_INNER):
            row += f"{kinect_score(nrdepth.reconstruct(frames[:, y : y + h, x : x + w], fine_model, sheet_stage=False), points, (x, y, w, h)):8.2f}"
        return row
    finally:
        pipeline.coarse_half = original_coarse_half


def fine_pass_once():
    """A stand-in for ``field_windows`` that runs the fine pass on its first
    call and gives copies of those windows on later calls: the fine pass
    does not depend on the coarse one, so the readings of one video share it."""
    kept = []

    def windows(layout, frames, progress=None):
        if not kept:
            kept.extend((origins, depth.copy()) for origins, depth in original_field_windows(layout, frames, progress=progress))
        return ((origins.copy(), depth.copy()) for origins, depth in kept)

    return windows


def generated_scores(readings: dict, fine_model, videos: int, cameras: tuple, against: str) -> None:
    """Each coarse reading of ``readings`` (label: stand-in for coarse_half) on
    generated videos through each of ``cameras`` (``CAMERAS``' names),
    paired against the reading labelled ``against``."""
    for camera, options in (c for c in CAMERAS if c[0] in cameras):
        clips = nrdepth.generate_clips(videos, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256, frames=48, **options))
        scores = {label: [] for label in readings}
        for video, depth, params in zip(clips.video, clips.depth, clips.params):
            truth = observable_depth(depth, params)
            stitching.field_windows = fine_pass_once()
            try:
                for label, coarse in readings.items():
                    pipeline.coarse_half = coarse
                    reading = nrdepth.reconstruct(video, fine_model, sheet_stage=False)
                    scores[label].append([mae_sn(reading, truth, a) for a in ("frame", "first")])
            finally:
                pipeline.coarse_half, stitching.field_windows = original_coarse_half, original_field_windows
        scores = {label: np.array(s) for label, s in scores.items()}
        print(f"{videos} generated 256²×48 videos, {camera}: per frame / from the first frame, paired against {against}")
        for label, s in scores.items():
            diff = s - scores[against]
            se = diff.std(axis=0, ddof=1) / math.sqrt(len(diff))
            print(f"  {label:44s}{s[:, 0].mean():8.4f}{s[:, 1].mean():8.4f}   {diff[:, 0].mean():+.4f} ± {se[0]:.4f} / {diff[:, 1].mean():+.4f} ± {se[1]:.4f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="model.safetensors or run folder; 'default' for the shipped network (its coarse pass without the companion)")
    parser.add_argument("--mix", default=None, help="weights of the second model's coarse reading, comma-separated")
    parser.add_argument("--generated", type=int, default=0, metavar="N", help="with --mix: score on N generated videos instead of the real ones")
    parser.add_argument("--reference", default=None, metavar="COMPANION:W", help="with --mix: also read the first model with COMPANION at weight W, and pair the generated scores against it")
    parser.add_argument("--camera", choices=[name for name, _ in CAMERAS], action="append", help="with --generated: this camera only (default: each)")
    args = parser.parse_args()
    if len(args.models) < 2:
        parser.error("name two or more models")
    cpu = torch.device("cpu")
    path = {m: None if m == "default" else m for m in args.models}
    nets = {m: inference_model(path[m], cpu) for m in args.models}
    for net in nets.values():  # each network's own coarse pass: --mix names the companion
        net.coarse_companion = None
    first, second = args.models[:2]
    mixes = {}  # label: the first model's coarse pass with a companion
    if args.reference is not None:
        if args.mix is None:
            parser.error("--reference needs --mix")
        companion, _, weight = args.reference.rpartition(":")
        try:
            weight = float(weight)
        except ValueError:
            weight = math.nan
        if not os.path.isfile(companion) or not 0 < weight <= 1:
            parser.error(f"--reference: expected COMPANION:W, an existing file and a weight in (0, 1], got {args.reference!r}")
        reference = inference_model(companion, cpu)
        reference.coarse_companion = None
        mixes[f"reference: {weight:g} × {companion[-22:]}"] = coarse_reading(nets[first], reference, weight)
    if args.mix is not None:
        mixes.update((f"{first[-20:]} + {w:g} × {second[-16:]}", coarse_reading(nets[first], nets[second], w))
                     for w in (float(w) for w in args.mix.split(",")))
    if args.generated:
        if args.mix is None:
            parser.error("--generated needs --mix")
        readings = {"as it is": coarse_reading(nets[first]), **mixes}
        against = next(iter(mixes)) if args.reference is not None else "as it is"
        generated_scores(readings, path[first], args.generated, tuple(args.camera or (name for name, _ in CAMERAS)), against)
        return
    video, truth = phisft_at_bin(4)
    cloth = (video, truth, phisft_regions(video, truth))
    paper = (read_video(DATA / "kinect_paper").frames, kinect_truth())
    print(f"{'coarse pass':44s}{'fine pass':34s}{'frame':>8s}{'first':>8s}{'border':>8s}{'inside':>8s}{'whole':>8s}{'inner':>8s}")
    if args.mix is None:
        for c in args.models:
            for f in args.models:
                print(f"{c[-43:]:44s}{f[-33:]:34s}" + scores(coarse_reading(nets[c]), path[f], cloth, paper), flush=True)
        return
    for label, coarse in mixes.items():
        print(f"{label[-43:]:44s}{first[-33:]:34s}" + scores(coarse, path[first], cloth, paper), flush=True)


if __name__ == "__main__":
    main()
