"""The shipped sheet stage, on real paper and on sheets rendered by another renderer.

``kinect``: the stage on ``kinect_paper`` (191 frames, 640×480): for each
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

    python benchmarks/bench_sheet_stage.py kinect --jobs default,whole --settings ",min_contrast=1.5" [--threads 2]

``render``: renders the seeds' scenes (``nrdepth.scores.rendered``: Mitsuba 3's
path tracer, ``pip install mitsuba``) into the cache, skipping those there.
``rendered``: the stage on them, per video and job (``default``: nothing
given; ``focal``: the true focal length; ``box``: the true focal length and
the sheet's box in the first frame), beside the network alone and the flat
plane on the sheet's pixels: MAE-SN per frame, the relief's sign right, the
decision; a CSV a row each, and a summary by set (even seeds select, odd
seeds report: fixed before any score was read).

    python benchmarks/bench_sheet_stage.py render --seeds 0-23 [--frames 64]
    python benchmarks/bench_sheet_stage.py rendered --seeds 0-23 --jobs default,focal,box --csv docs/sheet-stage/rendered.csv

``noise``: what must stay unread: generated coloured-noise videos (the
default generator's stretching surfaces, 256²×64 through pinholes of
40–80°, the evaluation's seed from ``--start``), nothing given, for each
setting: the videos read, and per frame the job against the network alone,
paired.

    python benchmarks/bench_sheet_stage.py noise --videos 16 --start 2100 --settings ",bridge=4"
"""

from __future__ import annotations

import argparse
import csv
import itertools
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


def kinect(argv) -> None:
    parser = argparse.ArgumentParser(prog="bench_sheet_stage.py kinect", description=__doc__.split("\n\n")[1])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--jobs", default="default", help=f"comma-separated, of {', '.join(JOBS)}")
    parser.add_argument("--settings", default="", help="comma-separated settings (--sheet-settings' text each); the empty one: the defaults")
    args = parser.parse_args(argv)
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


def seeds_of(text: str) -> list:
    """``0-23,40,42``: the seeds."""
    out = []
    for part in filter(None, text.split(",")):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def render(argv) -> None:
    from nrdepth.scores.rendered import cache_folder, render_video, scene_of

    parser = argparse.ArgumentParser(prog="bench_sheet_stage.py render")
    parser.add_argument("--seeds", required=True)
    parser.add_argument("--frames", type=int, default=None, help="frames a video (default: the scene's own, 64-128)")
    args = parser.parse_args(argv)
    for seed in seeds_of(args.seeds):
        if (cache_folder() / f"sheet_{seed}.npz").exists():
            continue
        start = time.perf_counter()
        scene = scene_of(seed, frames=args.frames)
        render_video(scene)
        print(f"seed {seed}: {scene.frames} frames of {scene.size[1]}×{scene.size[0]} in {time.perf_counter() - start:.0f} s ({scene})", flush=True)


ROW = ("seed", "set", "job", "setting", "frames", "size", "fov", "print_kind", "finish", "background", "light", "bend", "used", "reason", "points", "held", "strain", "contrast",
       "focal_estimate", "focal", "true_focal", "network", "stage", "plane", "sign_network", "sign_stage", "seconds")


def rendered(argv) -> None:
    import cv2
    import torch

    import nrdepth
    from nrdepth.scores.rendered import load_video, split_of

    parser = argparse.ArgumentParser(prog="bench_sheet_stage.py rendered")
    parser.add_argument("--seeds", required=True)
    parser.add_argument("--jobs", default="default,focal,box")
    parser.add_argument("--settings", default="", help="comma-separated settings (--sheet-settings' text each); the empty one: the defaults")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--csv", default=None)
    parser.add_argument("--from-csv", nargs="+", default=None, help="summarise these CSVs of earlier runs; read no video")
    args = parser.parse_args(argv)
    if args.from_csv:
        rows = [row for path in args.from_csv for row in csv.DictReader(open(path, newline=""))]
        for row in rows:
            row.update({key: float(row[key]) for key in ("network", "stage", "plane", "sign_network", "sign_stage")}, used=int(row["used"]),
                       setting=row.get("setting", ""))
        return summarise(rows, args.jobs.split(","), args.settings.split(","))
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s, {args.threads} threads", flush=True)
    rows = []
    for seed in seeds_of(args.seeds):
        data = load_video(seed)
        video, truth, sheet, scene = data["video"], data["depth"].astype(np.float64), data["sheet"], data["scene"]
        on = sheet & np.isfinite(truth)
        network = nrdepth.reconstruct(video, sheet_stage=False).astype(np.float64)
        ys, xs = np.nonzero(sheet[0])
        box = (int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1))
        given = {"default": {}, "focal": {"focal": float(data["focal"])}, "box": {"focal": float(data["focal"]), "sheet": box}}
        plane = nrdepth.flat_baseline(truth, mask=on)
        for job, setting in itertools.product(args.jobs.split(","), args.settings.split(",")):
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                depth, decision = nrdepth.reconstruct(video, options=job_options(setting, **given[job]), with_decision=True)
            seconds = time.perf_counter() - start
            row = dict(seed=seed, set=split_of(seed), job=job, setting=setting, frames=len(video), size=video.shape[1], fov=round(scene["fov"], 1),
                       print_kind=scene["print_kind"], finish=scene["finish"], background=scene["background"], light=scene["light"],
                       bend=scene["bend"], used=int(decision.used), reason=decision.reason[:160], points=decision.points, held=decision.held,
                       strain=decision.strain, contrast=decision.contrast,
                       focal_estimate=decision.focal_estimate, focal=None if decision.focal is None else round(decision.focal[0], 1),
                       true_focal=round(float(data["focal"]), 1), network=nrdepth.mae_sn(network, truth, mask=on),
                       stage=nrdepth.mae_sn(depth.astype(np.float64), truth, mask=on), plane=plane,
                       sign_network=nrdepth.sign_rates(network, truth, mask=on)["sign_correct"],
                       sign_stage=nrdepth.sign_rates(depth.astype(np.float64), truth, mask=on)["sign_correct"], seconds=round(seconds, 1))
            rows.append(row)
            print(" ".join(f"{key}={value:.4f}" if isinstance(value, float) else f"{key}={value}" for key, value in row.items()), flush=True)
            if args.csv:
                with open(args.csv, "w", newline="") as out:
                    writer = csv.DictWriter(out, ROW)
                    writer.writeheader()
                    writer.writerows(rows)
    summarise(rows, args.jobs.split(","), args.settings.split(","))
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s", flush=True)


def summarise(rows: list, jobs: list, settings: list) -> None:
    """Each set, job and setting: the videos read, per frame against the plane, the relief's sign right; then by bend."""
    for split, job, setting in itertools.product(("selection", "report"), jobs, settings):
        chosen = [r for r in rows if r["set"] == split and r["job"] == job and r["setting"] == setting]
        if not chosen:
            continue
        mean = lambda key, rs=chosen: float(np.mean([r[key] for r in rs]))  # noqa: E731
        print(f"{split} {job}{f' [{setting}]' if setting else ''}: {len(chosen)} videos, read {sum(r['used'] for r in chosen)}; per frame the stage {mean('stage'):.4f} "
              f"({mean('stage') / mean('plane'):.2f}× the plane), the network {mean('network'):.4f} ({mean('network') / mean('plane'):.2f}×), "
              f"the plane {mean('plane'):.4f}; sign right {mean('sign_stage'):.0%} (the network {mean('sign_network'):.0%})", flush=True)
        for bend in ("away", "toward", "turning"):
            some = [r for r in chosen if r["bend"] == bend]
            if some:
                print(f"    bent {bend}: {len(some)} videos, read {sum(r['used'] for r in some)}, the stage {mean('stage', some) / mean('plane', some):.2f}× "
                      f"the plane (the network {mean('network', some) / mean('plane', some):.2f}×), sign right {mean('sign_stage', some):.0%} "
                      f"(the network {mean('sign_network', some):.0%})", flush=True)


def noise(argv) -> None:
    import cv2
    import torch

    import nrdepth
    from nrdepth.learning.evaluate import TEST_SEED

    parser = argparse.ArgumentParser(prog="bench_sheet_stage.py noise")
    parser.add_argument("--videos", type=int, default=16)
    parser.add_argument("--start", type=int, default=2100, help="the first clip's index at the evaluation's seed")
    parser.add_argument("--settings", default="", help="comma-separated settings (--sheet-settings' text each); the empty one: the defaults")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s, {args.threads} threads", flush=True)
    config = nrdepth.GeneratorConfig(frames=64, size=256, grid=128, camera_fov=(0.7, 1.4), crop_share=(1.0, 1.0))
    settings = args.settings.split(",")
    read, gaps = {s: 0 for s in settings}, {s: [] for s in settings}
    for clip in range(args.start, args.start + args.videos):
        clips = nrdepth.generate_clips(1, seed=TEST_SEED, config=config, start=clip)
        video, truth = clips.video[0], clips.depth[0].astype(np.float64)
        network = nrdepth.mae_sn(nrdepth.reconstruct(video, sheet_stage=False).astype(np.float64), truth)
        line = [f"clip {clip}: the network {network:.4f}"]
        for setting in settings:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                depth, decision = nrdepth.reconstruct(video, options=job_options(setting), with_decision=True)
            read[setting] += int(decision.used)
            gaps[setting].append(nrdepth.mae_sn(depth.astype(np.float64), truth) - network)
            line.append(f"[{setting or 'defaults'}] {'read' if decision.used else 'not read'} {gaps[setting][-1]:+.4f}: {decision.reason[:90]}")
        print("; ".join(line), flush=True)
    for setting in settings:
        g = np.array(gaps[setting])
        print(f"{setting or 'defaults'}: read {read[setting]} of {args.videos}; per frame against the network "
              f"{g.mean():+.4f} ± {g.std(ddof=1) / np.sqrt(len(g)) if len(g) > 1 else 0:.4f} (mean ± SE, paired)", flush=True)


COMMANDS = {"kinect": kinect, "render": render, "rendered": rendered, "noise": noise}


if __name__ == "__main__":
    import sys

    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        raise SystemExit(f"usage: python {sys.argv[0]} {{{'|'.join(COMMANDS)}}} [options]")
    COMMANDS[sys.argv[1]](sys.argv[2:])
