"""Flat in, flat out: the flat textured sheets of the test suite
(``tests/test_reconstruct.py``: tilted, turning, lit from above, vertices
fixed in the image) reconstructed in pixels, and the same sheets with bumps
whose RMS is 3 % of the frame's width. Prints, per texture family, the
largest over frames of the reconstruction's residual about its best plane
over the true depth's standard deviation (the test asks for < 0.2 on the
flat sheet), and the bumps' reconstructed relief over their true relief
(geometric mean over frames; 1 is right).

    python benchmarks/bench_flat_sheet.py [--model PATH] [--families fractal,weave,plaid,stripes,cells]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import nrdepth
import nrdepth.model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_reconstruct import FLAT_SHEET_WINDOW, flat_sheet_residual, flat_sheet_video, plane_residuals  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="a model with a depth scale (default: the shipped nrdepth.model.SCALED_MODEL)")
    parser.add_argument("--families", default="fractal,weave,plaid,stripes,cells")
    args = parser.parse_args()
    model = nrdepth.model.load_model(args.model or nrdepth.model.SCALED_MODEL)
    print(f"{'texture':10s}{'flat: residual / depth std':>28s}{'bumps: relief / true':>24s}")
    for family in args.families.split(","):
        flat_video, flat_depth = flat_sheet_video(family)
        bumps_video, bumps_depth = flat_sheet_video(family, relief=0.08)
        to_pixels = flat_video.shape[2] / FLAT_SHEET_WINDOW
        flat = flat_sheet_residual(nrdepth.reconstruct(flat_video, model, device="cpu", units="pixels"), flat_depth * to_pixels)
        ratio = plane_residuals(nrdepth.reconstruct(bumps_video, model, device="cpu", units="pixels")) / plane_residuals(bumps_depth * to_pixels)
        print(f"{family:10s}{flat:>28.3f}{np.exp(np.log(ratio).mean()):>24.3f}")


if __name__ == "__main__":
    main()
