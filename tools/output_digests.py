"""SHA-256 digests of what the main job writes, to show that a change which
only moves code leaves every output byte-identical.

Run it before and after the change, on the same machine, and compare:

    python tools/output_digests.py --json before.json
    python tools/output_digests.py --json after.json --compare before.json

It digests, with the shipped model on the CPU under one torch thread:

- the 128 held-out 64×64×16 generated clips (``nrdepth.learning.evaluate.TEST_SEED``):
  each clip's :func:`nrdepth.reconstruct`, and ``nrdepth evaluate``'s
  summary (:func:`nrdepth.learning.evaluate.evaluate`);
- both real videos: ``phisft_R1``'s crop and ``kinect_paper``'s sheet, each
  by default and in sheet mode (the camera's focal length);
- a :func:`nrdepth.reconstruct_file` folder with every output (the
  depth, the viewer page, 16-bit PNGs and PLYs; the MP4s are not
  reproducible run to run) of a 40-frame cut of ``kinect_paper``.

The digests recorded on this project's CPU machine, before the main job
became a package (issue 70), are ``tools/output_digests.json``.

``--quick`` leaves out the slow part (kinect_paper's 191 frames in sheet
mode, ~2 minutes).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch


def digest(array: np.ndarray) -> str:
    array = np.ascontiguousarray(array)
    return hashlib.sha256(f"{array.dtype}{array.shape}".encode() + array.tobytes()).hexdigest()


def folder_digests(folder: Path) -> dict:
    """Every file's digest but the MP4s': libx264 at the writer's preset does
    not give the same bytes twice from the same frames (its macroblock tree;
    docs/findings.md), so they are no evidence either way."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file() and p.suffix != ".mp4"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", type=Path, required=True, help="where the digests go")
    parser.add_argument("--compare", type=Path, default=None, help="digests written before: print what differs, exit 1 if anything does")
    parser.add_argument("--quick", action="store_true", help="leave out kinect_paper's whole video in sheet mode")
    args = parser.parse_args()
    torch.set_num_threads(1)

    import nrdepth
    from nrdepth.learning.evaluate import TEST_SEED, evaluate
    from nrdepth.scores.real import KINECT_ROI, kinect_camera, kinect_video, phisft_crop

    out: dict = {}
    start = time.perf_counter()
    clips = nrdepth.generate_clips(128, seed=TEST_SEED)
    out["held_out_clips"] = digest(np.stack([nrdepth.reconstruct(video) for video in clips.video]))
    with tempfile.TemporaryDirectory() as scratch:
        evaluate(None, out=scratch, clips=128, device="cpu")
        summary = json.loads((Path(scratch) / "summary.json").read_text())
        summary.pop("model", None)
        out["evaluate_summary"] = hashlib.sha256(json.dumps(summary, sort_keys=True).encode()).hexdigest()
        out["evaluate_per_clip"] = hashlib.sha256((Path(scratch) / "per_clip.csv").read_bytes()).hexdigest()
    print(f"held-out clips: {time.perf_counter() - start:.0f} s", flush=True)

    video, _ = phisft_crop()
    out["phisft_default"] = digest(nrdepth.reconstruct(video))
    out["phisft_paper_stitch"] = digest(nrdepth.reconstruct(video, alignment="coarse", window="triangle"))
    x, y, w, h = KINECT_ROI
    frames = kinect_video()
    sheet = frames[:, y : y + h, x : x + w]
    out["kinect_default"] = digest(nrdepth.reconstruct(sheet))
    print(f"real videos by default: {time.perf_counter() - start:.0f} s", flush=True)
    focal, centre = kinect_camera()
    cut = frames[:40]
    out["kinect_40_sheet_mode"] = digest(nrdepth.reconstruct(cut, focal=focal, centre=centre, roi=KINECT_ROI, sheet=(200, 96, 320, 272)))
    out["kinect_40_refined"] = digest(nrdepth.reconstruct(cut, focal=focal, centre=centre, roi=KINECT_ROI, isometric_template="refined",
                                                          isometric_drop=0.3, isometric_scale=0.2))
    if not args.quick:
        out["kinect_sheet_mode"] = digest(nrdepth.reconstruct(frames, focal=focal, centre=centre, roi=KINECT_ROI))
    print(f"sheet mode: {time.perf_counter() - start:.0f} s", flush=True)

    with tempfile.TemporaryDirectory() as scratch:
        source = Path(scratch) / "cut.npy"
        np.save(source, cut)
        folder = nrdepth.reconstruct_file(source, Path(scratch) / "out", roi=KINECT_ROI, png16=True, ply=True)
        out["reconstruct_file"] = folder_digests(folder)
        folder = nrdepth.reconstruct_file(source, Path(scratch) / "flipped", roi=KINECT_ROI, flip=True, focal=focal[0], max_side=256, viewer=False)
        out["reconstruct_file_sheet_mode"] = folder_digests(folder)
    print(f"reconstruct_file: {time.perf_counter() - start:.0f} s", flush=True)

    args.json.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.json}")
    if args.compare is not None:
        before = json.loads(args.compare.read_text())
        differ = [k for k in sorted(set(before) | set(out)) if before.get(k) != out.get(k) and not (args.quick and k not in out)]
        print("identical" if not differ else f"differ: {', '.join(differ)}")
        sys.exit(1 if differ else 0)


if __name__ == "__main__":
    main()
