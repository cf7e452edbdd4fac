"""The shipped sheet stage on ``kinect_paper`` (191 frames, 640×480): for each
setting and each job, the whole ``nrdepth.reconstruct`` timed, its error on
the Kinect's sparse truth (mm, per-frame GBR) and its decision's line, beside
the rest of the job (the network alone over the roi) and a 2048² sgemm
measured before and after (machines here differ by 1.5×).

A setting is the stage's :class:`~nrdepth.SheetSettings` as the command
line's ``--sheet-settings`` takes it: ``key=value`` pairs joined by ``:``
(``min_contrast=1.5:read_smooth=0``; ``""``: the defaults). The jobs:
``whole`` (nothing given, the whole frame, scored on the sheet's points),
``default`` (the roi alone), ``focal`` (the roi and the Kinect's focal
length), ``true`` (the roi, the focal length and the print's box) and
``guessed`` (the roi and the print's box, through the guessed pinhole).
Every setting runs the stage the job ships (:func:`job_options`): there is
no other implementation of it to drift from.

    python benchmarks/bench_sheet_stage.py --jobs default,whole --settings ",min_contrast=1.5" [--threads 2]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

JOBS = ("whole", "default", "focal", "true", "guessed")


def sgemm() -> float:
    import torch

    a = torch.randn(2048, 2048)
    a @ a
    start, n = time.perf_counter(), 0
    while time.perf_counter() - start < 1.0:
        a @ a
        n += 1
    return 2 * 2048**3 * n / (time.perf_counter() - start) / 1e9


def job_options(setting: str, **given):
    """The job's :class:`~nrdepth.ReconstructOptions`: ``given`` (roi, focal,
    sheet, …) and the stage's settings ``setting`` (``--sheet-settings``'s text)."""
    import nrdepth

    return nrdepth.ReconstructOptions.of(sheet_settings=nrdepth.SheetSettings.parse(setting), **given)


def kinect_jobs() -> dict:
    """Each job's options on ``kinect_paper`` but the settings."""
    import nrdepth
    from nrdepth.scores.real import KINECT_INNER, KINECT_ROI, data_folder

    camera = nrdepth.Camera.from_matrix(np.load(data_folder("kinect_paper") / "gt_mdh.npz")["K"].astype(np.float64))
    return {"whole": {}, "default": dict(roi=KINECT_ROI), "focal": dict(roi=KINECT_ROI, focal=camera),
            "true": dict(roi=KINECT_ROI, focal=camera, sheet=KINECT_INNER), "guessed": dict(roi=KINECT_ROI, sheet=KINECT_INNER)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--jobs", default="default", help=f"comma-separated, of {', '.join(JOBS)}")
    parser.add_argument("--settings", default="", help="comma-separated settings (--sheet-settings' text each); the empty one: the defaults")
    args = parser.parse_args()
    jobs = args.jobs.split(",")
    if not set(jobs) <= set(JOBS):
        raise SystemExit(f"--jobs: expected some of {', '.join(JOBS)}, got {args.jobs!r}")
    settings = args.settings.split(",")
    for setting in settings:  # refused before the network's minutes
        job_options(setting)

    import cv2
    import torch

    import nrdepth
    from nrdepth.scores.real import KINECT_ROI, kinect_references, kinect_score, kinect_truth, kinect_video

    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s, {args.threads} threads", flush=True)
    frames, truth, given = kinect_video(), kinect_truth(), kinect_jobs()
    start = time.perf_counter()
    network = nrdepth.reconstruct(frames, roi=KINECT_ROI, sheet_stage=False).astype(np.float64)
    rest = time.perf_counter() - start
    print(f"the rest of the job (the roi, --no-sheet): {rest:.1f} s; network alone {kinect_score(network, truth):.2f} mm, "
          f"fixed bowl {kinect_references(truth, KINECT_ROI)['bowl']:.2f} mm", flush=True)
    for setting in settings:
        for job in jobs:
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a fallback is printed below
                depth, decision = nrdepth.reconstruct(frames, options=job_options(setting, **given[job]), with_decision=True)
            seconds = time.perf_counter() - start
            read = given[job].get("roi", (0, 0, frames.shape[2], frames.shape[1]))
            print(f"{setting or 'defaults':30s} {job:8s} {seconds:5.1f} s (the stage {(seconds - rest) / rest:.2f}× the rest): "
                  f"{kinect_score(depth.astype(np.float64), truth, roi=read):.2f} mm (bowl {kinect_references(truth, read)['bowl']:.2f}); "
                  f"{decision.line()}", flush=True)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s", flush=True)


if __name__ == "__main__":
    main()
