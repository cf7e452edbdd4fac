"""Should the coarse pass's 16-frame windows be chained? ``reconstruct``
reads the small video in windows that do not overlap, each with its own
depth offset: the network re-centres every window. Here the windows overlap
by ``--overlap`` frames and each is shifted onto the frames already read
(``offset``: its mean over the overlap; ``plane``: a plane a·x + b·y + c
fitted there), cross-fading over the overlap, so that motion along the
optical axis can build up over the video. Scored:

- ``phisft_R1`` (``bench_real.py``'s crop) as it is and turned 180° (lit
  from the other side, so its relief's sign reads the other way): MAE-SN
  per frame and from the first frame;
- ``--videos N`` generated videos of ``--frames`` frames, orthographic and
  through a pinhole (40–80°, whole frames), against their observable
  depth, paired against the plain windows (mean difference ± its standard
  error). The generator spreads a clip's motion over its frames, so a
  48-frame video moves a third as fast as a 16-frame training clip;
  ``--paced`` scales its motion (deformation speed, tilt, spin and drift
  rates) by frames / 16, so that each window moves as a training clip does;
- whether the network's offset trend could carry the relief's sign: on the
  cloth the trend of its coarse windows, read with the relief's sign, is the
  recession in both orientations. On ``--videos`` × 2 generated videos
  through a pinhole with lights from every side (128²), the share whose
  trend over the windows, times the sign its relief is read with, has the
  sign of the true trend of the mean depth: 1 would make motion along the
  optical axis a sign cue.

    python experiments/coarse_chain.py [--model M] [--videos 32] [--size 256] [--frames 48] [--paced]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys

import numpy as np

from nrdepth.scores.real import phisft_at_bin

import nrdepth  # noqa: E402
from nrdepth.learning.evaluate import TEST_SEED  # noqa: E402
from nrdepth.engine.generate import observable_depth  # noqa: E402
from nrdepth.scores.metrics import flat_baseline, mae_sn  # noqa: E402
from nrdepth.model.io import predict_depth  # noqa: E402

pipeline = sys.modules["nrdepth.reconstruct.pipeline"]  # the module that calls coarse_half: its stand-in goes there
windows_half = pipeline.coarse_half
SIDE, LENGTH = 32, 16  # a coarse reading's side and a window's frames
# The generated videos' two cameras: orthographic, and a pinhole of 40–80° whose whole frame is the video (real_cross.py's too).
CAMERAS = (("orthographic", {}), ("pinhole", {"camera_fov": (math.radians(40), math.radians(80)), "crop_share": (1.0, 1.0)}))


def chained_half(small, net, batch_size, device, readings=2, overlap=8, fit="offset"):
    """``coarse_half`` over windows that overlap by ``overlap`` frames, each
    shifted onto the frames before it by the ``fit`` over the overlap."""
    t = len(small)
    if t <= LENGTH:
        return windows_half(small, net, batch_size, device, readings)
    starts = list(range(0, t - LENGTH, LENGTH - overlap)) + [t - LENGTH]
    depth = predict_depth(net, np.stack([small[s : s + LENGTH] for s in starts]), batch_size, device, readings=readings).astype(np.float64)
    y, x = np.mgrid[0:SIDE, 0:SIDE].astype(np.float64)
    basis = np.stack([np.ones_like(x)] if fit == "offset" else [x, y, np.ones_like(x)], axis=-1)  # (h, w, k)
    out = np.zeros((t, SIDE, SIDE))
    out[:LENGTH] = depth[0]
    end = LENGTH
    for s, window in zip(starts[1:], depth[1:]):
        n = end - s
        shared = np.broadcast_to(basis, (n, SIDE, SIDE, basis.shape[-1])).reshape(-1, basis.shape[-1])
        coef = np.linalg.lstsq(shared, (out[s:end] - window[:n]).ravel(), rcond=None)[0]
        window = window + basis @ coef
        ramp = ((np.arange(n) + 1.0) / (n + 1.0))[:, None, None]
        out[s:end] = (1 - ramp) * out[s:end] + ramp * window[:n]
        out[end : s + LENGTH] = window[n:]
        end = s + LENGTH
    return out.astype(np.float32)


READINGS = ("windows", "offset", "plane")


def reconstruct_with(kind: str, video: np.ndarray, model, overlap: int) -> np.ndarray:
    pipeline.coarse_half = windows_half if kind == "windows" else (
        lambda small, net, bs, dev, readings=2: chained_half(small, net, bs, dev, readings, overlap, kind))
    try:
        return nrdepth.reconstruct(video, model, sheet_stage=False)
    finally:
        pipeline.coarse_half = windows_half


def trend_coupling(model, videos: int, frames: int) -> None:
    """:func:`main`'s last part: does the coarse windows' offset trend know the relief's sign?"""
    import torch

    from nrdepth.scores.metrics import sign_rates
    from nrdepth.reconstruct import inference_model
    from nrdepth.reconstruct.frames import as_unit_float, resize

    cpu = torch.device("cpu")
    net = inference_model(model, cpu)
    config = nrdepth.GeneratorConfig(size=128, frames=frames, camera_fov=(math.radians(40), math.radians(80)), crop_share=(1.0, 1.0),
                                     light_azimuth=(-math.pi, math.pi))
    clips = nrdepth.generate_clips(videos, seed=TEST_SEED, config=config)
    agree, signs = [], []
    for video, depth in zip(clips.video, clips.depth):
        half = windows_half(resize(as_unit_float(video), (2 * SIDE, 2 * SIDE)), net, 8, cpu).astype(np.float64)
        slope = [np.polyfit(np.arange(LENGTH), d[a : a + LENGTH].mean(axis=(1, 2)), 1)[0] for a in range(0, frames - LENGTH + 1, LENGTH) for d in (half, depth)]
        read_right = sign_rates(resize(half, depth.shape[1:]), depth)["sign_correct"] > 0.5
        signs.append(read_right)
        agree.append(np.sign(np.sum(slope[0::2])) * (1 if read_right else -1) == np.sign(np.sum(slope[1::2])))
    print(f"{videos} generated 128²×{frames} videos through a pinhole, lights from every side: relief read right in {np.mean(signs):.2f} of them; "
          f"the windows' offset trend, with that sign, has the true trend's sign in {np.mean(agree):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--videos", type=int, default=32)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--overlap", type=int, default=8)
    parser.add_argument("--paced", action="store_true", help="motion scaled by frames / 16: each window moves as a training clip")
    args = parser.parse_args()
    video, truth = phisft_at_bin(4)
    for label, (v, g) in (("phisft_R1", (video, truth)), ("phisft_R1 turned 180°", (video[:, ::-1, ::-1], truth[:, ::-1, ::-1]))):
        v, g = np.ascontiguousarray(v), np.ascontiguousarray(g)
        m = np.isfinite(g)
        print(f"{label}: plane {flat_baseline(g, 'frame', mask=m):.4f} / {flat_baseline(g, 'first', mask=m):.4f} (per frame / from the first frame)")
        for kind in READINGS:
            d = reconstruct_with(kind, v, args.model, args.overlap)
            print(f"  {kind:8s}{mae_sn(d, g, 'frame', mask=m):8.4f}{mae_sn(d, g, 'first', mask=m):8.4f}", flush=True)
    surface = nrdepth.GeneratorConfig().surface
    if args.paced:
        pace = args.frames / LENGTH
        surface = dataclasses.replace(surface, **{k: tuple(pace * v for v in getattr(surface, k)) for k in ("speed", "tilt_rate", "spin_rate", "drift_xy", "drift_z")})
    for camera, options in CAMERAS:
        config = nrdepth.GeneratorConfig(size=args.size, frames=args.frames, surface=surface, **options)
        clips = nrdepth.generate_clips(args.videos, seed=TEST_SEED, config=config)
        truths = [observable_depth(d, p) for d, p in zip(clips.depth, clips.params)]
        scores = {kind: np.array([[mae_sn(reconstruct_with(kind, v, args.model, args.overlap), g, a) for a in ("frame", "first")]
                                  for v, g in zip(clips.video, truths)]) for kind in READINGS}
        plane = np.mean([[flat_baseline(g, a) for a in ("frame", "first")] for g in truths], axis=0)
        print(f"{args.videos} generated {args.size}²×{args.frames} videos{', paced' if args.paced else ''}, {camera}: plane {plane[0]:.4f} / {plane[1]:.4f}")
        for kind in READINGS:
            diff = scores[kind] - scores["windows"]
            se = diff.std(axis=0, ddof=1) / math.sqrt(len(diff))
            print(f"  {kind:8s}{scores[kind][:, 0].mean():8.4f}{scores[kind][:, 1].mean():8.4f}   paired {diff[:, 0].mean():+.4f} ± {se[0]:.4f} / "
                  f"{diff[:, 1].mean():+.4f} ± {se[1]:.4f}", flush=True)
    trend_coupling(args.model, 2 * args.videos, args.frames)


if __name__ == "__main__":
    main()
