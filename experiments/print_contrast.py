"""How much contrast a sheet's texture shows a tracker: generated sheets of
``--families`` against ``kinect_paper``'s print (issue 72's selection set).

The measure: the gray levels' local standard deviation over their local
mean (both in a Gaussian of 5 px, the scale the held points' windows
match at), its median over the region: ``kinect_paper``'s print box
(``KINECT_INNER``) in every 60th frame; the first frame of each generated
sheet (256² × ``--frames`` in ``--phases`` bends, as the selection sets draw them, pinholes of 40–80°, lit from below and from above, seed
``isometric_generated.SEED`` from ``--start``).

    python experiments/print_contrast.py [--families print] [--videos 6] [--start 300]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from nrdepth import GeneratorConfig, generate_clips
from nrdepth.scores.generated import SHEET_FAMILIES
from nrdepth.scores.real import KINECT_INNER, kinect_video

sys.path.insert(0, str(Path(__file__).parent))
from isometric_generated import SEED  # noqa: E402


def local_contrast(frame: np.ndarray) -> float:
    """The median of the local standard deviation over the local mean (gray levels, 5 px Gaussian)."""
    from scipy.ndimage import gaussian_filter

    f = frame.astype(np.float64) * (255.0 if frame.dtype != np.uint8 and frame.max() <= 1.5 else 1.0)
    mean = gaussian_filter(f, 5.0)
    spread = np.sqrt(gaussian_filter((f - mean) ** 2, 5.0))
    return float(np.median(spread / np.maximum(mean, 1.0)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--families", default="print", help="the generated sheets' texture families (comma-separated)")
    parser.add_argument("--videos", type=int, default=6, help="generated sheets per light")
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4)
    parser.add_argument("--start", type=int, default=300, help="the first sheet's index in the held-out seed's draws")
    args = parser.parse_args()
    x, y, w, h = KINECT_INNER
    frames = kinect_video()
    print("kinect_paper's print, frames " + ", ".join(f"{t + 1}: {local_contrast(frames[t, y:y + h, x:x + w]):.3f}" for t in range(0, len(frames), 60)))
    families = tuple(args.families.split(","))
    unknown = set(families) - set(SHEET_FAMILIES)
    if unknown:
        parser.error(f"--families: unknown {sorted(unknown)} (known: {', '.join(SHEET_FAMILIES)})")
    for light, azimuth in (("below", (math.pi - 1.22, math.pi + 1.22)), ("above", None)):
        extra = {} if azimuth is None else {"light_azimuth": azimuth}
        config = GeneratorConfig(frames=args.frames, size=256, grid=128, sheet_probability=1.0, sheet_phases=args.phases, texture_families=families, camera_fov=(0.7, 1.4),
                                 crop_share=(1.0, 1.0), **extra)
        clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start)
        print(f"{args.families} sheets lit from {light}, clips {args.start}–{args.start + args.videos - 1}: "
              + ", ".join(f"{local_contrast(video[0]):.3f}" for video in clips.video))


if __name__ == "__main__":
    main()
