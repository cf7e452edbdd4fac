"""What an in-clip flip of the relief's sign is made of, on the held-out
clips: does the prediction jump to the mirrored relief, or does it change
smoothly while the truth moves away from it?

For every frame, the relief (the frame minus its least-squares plane) of the
prediction and of the truth; their correlation is the relief correlation (its
sign is that of λ in the frame's GBR fit, which ``sign_rates`` counts). At
every change of that sign inside a clip, the correlation of the predicted
relief with the previous frame's tells a jump (low) from a smooth change
(near 1). Prints, for clips with and without a flip, the mean relief
correlation, and over all sign changes how many are smooth; how fast the
predicted and the true relief change (their mean frame-to-frame
correlations: a prediction that lags behind the surface would change more
slowly than the truth); and how far the truth's relief renews itself over a
clip (the correlation of its first and last frames). Last, the flip rate
against the lights' component along image-up (the unit light directions'
mean, weighted by intensity): the relief's sign is only visible in shading
through that component (a frontal or sideways light renders z and −z alike),
and the generator's elevations (up to 83°) and azimuths (±70° about
image-up) let it fall near zero.

    python benchmarks/flip_anatomy.py [--clips 128] [--model PATH]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth
from first_frame_floor import planes
from nrdepth.evaluate import TEST_SEED
from nrdepth.model import DEFAULT_MODEL, load_model, predict_depth

UP_BINS = (0.0, 0.2, 0.4, 0.6, 1.0)
"""Edges of the bins of the lights' component along image-up."""

SMOOTH = 0.5
"""A sign change counts as smooth when the predicted relief's correlation
with the previous frame's is at least this."""


def relief_correlation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-frame correlation of the reliefs (frame minus its plane) of two
    videos (T, H, W): (T,)."""
    ra, rb = (v - planes(v) for v in (a, b))
    ra, rb = ra.reshape(len(ra), -1), rb.reshape(len(rb), -1)
    return (ra * rb).sum(1) / np.sqrt((ra * ra).sum(1) * (rb * rb).sum(1))


def up_component(lights: list) -> float:
    """The intensity-weighted mean of a clip's unit light directions'
    image-up (+y) component; a point light counts by the direction of its
    position from the surface's centre."""
    up = [light["vector"][1] / np.linalg.norm(light["vector"]) for light in lights]
    return float(np.average(up, weights=[light["intensity"] for light in lights]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=128)
    parser.add_argument("--model", default=str(DEFAULT_MODEL), help="model.safetensors or run folder (default: the shipped model)")
    args = parser.parse_args()
    clips = nrdepth.generate_clips(args.clips, seed=TEST_SEED)
    truth = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth), 2).numpy().astype(np.float64)
    pred = predict_depth(load_model(args.model, device="cpu"), clips.video).astype(np.float64)

    flipped, reading, steps, renewal, pace = [], [], [], [], []
    for p, g in zip(pred, truth):
        corr = relief_correlation(p, g)
        signs = np.sign(corr)
        flipped.append(len(set(signs[signs != 0].tolist())) > 1)
        reading.append(corr.mean())
        step = relief_correlation(p[1:], p[:-1])
        steps.extend(step[signs[1:] * signs[:-1] < 0].tolist())
        renewal.append(relief_correlation(g[:1], g[-1:])[0])
        pace.append((step.mean(), relief_correlation(g[1:], g[:-1]).mean()))
    flipped, reading, steps = np.array(flipped), np.array(reading), np.array(steps)

    print(f"{len(pred)} held-out clips (seed {TEST_SEED}), model {args.model}")
    print(f"clips whose relief sign flips: {flipped.sum()} ({100 * flipped.mean():.1f} %)")
    print(f"mean relief correlation with the truth: {reading[flipped].mean():.2f} in those, {reading[~flipped].mean():.2f} in the others")
    if len(steps):
        print(f"sign changes: {len(steps)}; the predicted relief's correlation with the frame before is ≥ {SMOOTH} at "
              f"{(steps >= SMOOTH).sum()} of them ({100 * (steps >= SMOOTH).mean():.0f} %), median {np.median(steps):.2f}")
    pace = np.array(pace)
    print(f"frame-to-frame relief correlation, mean: prediction {pace[:, 0].mean():.3f}, truth {pace[:, 1].mean():.3f}")
    print(f"the truth's relief, first frame against last: correlation {np.mean(renewal):+.2f} ± {np.std(renewal):.2f} (mean ± std over clips)")
    up = np.array([up_component(p["lights"]) for p in clips.params])
    print("lights' component along image-up   clips   flip rate   mean relief correlation")
    for lo, hi in zip(UP_BINS[:-1], UP_BINS[1:]):
        inside = (up >= lo) & (up < hi)
        if inside.any():
            print(f"  {lo:.1f} to {hi:.1f}{'':22}{inside.sum():5d}   {100 * flipped[inside].mean():7.1f} %   {reading[inside].mean():.2f}")


if __name__ == "__main__":
    main()
