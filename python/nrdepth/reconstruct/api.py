"""The main job's two entry points: :func:`reconstruct` (an array in, its
depth out) and :func:`reconstruct_file` (a file to a folder, streamed).
Each checks everything it can before any work, then chains the stages:
:class:`~.pipeline.Pipeline` (reading, statistic, coarse pass),
:func:`~.stitching.stitched` (fine pass and stitch), the sheet stage
(:mod:`.sheet`: a sheet's shape where the video shows one, its points
read in a second thread beside the fine pass) and :mod:`.export` (units, resolution).
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import Any, Callable, ContextManager, Iterable, NamedTuple, Optional, Union

import numpy as np

from ..checks import option_error
from ..interrupt import sigint_remembered
from ..io.decode import open_video, select, to_gray
from ..io.folder import ReconstructionWriter, check_output_folder
from ..io.writers import PLY_RELIEF
from .export import final, units_of
from .frames import CHUNK, DiskFrames
from .mask import file_mask, video_mask
from .network import fine_precision, load_net
from .options import FILE_ONLY, STAGE_OPTIONS, ReconstructOptions
from .pipeline import Pipeline
from .decision import SheetDecision
from .sheet import SheetStage, read_beside, sheet_depth, stage_of
from .stitching import stitched

__all__ = ["reconstruct", "reconstruct_file", "Reconstruction", "SheetFallback"]

Model = Union[None, str, "os.PathLike[str]", "torch.nn.Module"]  # noqa: F821
Progress = Optional[Callable[[int, int], None]]


def _options(options: Optional[ReconstructOptions], progress: Progress, settings: dict) -> ReconstructOptions:
    """The options with ``settings`` applied, and ``progress``, checked."""
    if progress is not None and not callable(progress):
        raise TypeError(f"progress: expected a callable progress(done, total) or None, got {type(progress).__name__}")
    return ReconstructOptions.of(options, **settings)


def _network(model: Model, options: ReconstructOptions) -> tuple:
    """The device and the network on it."""
    from ..model.io import resolve_device

    device = resolve_device(options.device)
    return device, load_net(model, options.units, device)


def _said(decision: SheetDecision, options: ReconstructOptions) -> SheetDecision:
    """The sheet stage's decision, said: a warning where it left the network's
    depth alone that ``focal`` or ``sheet`` asked it to shape, and one per
    option of the stage that was set but could not act."""
    if not decision.used and options.sheet_given:
        warnings.warn(decision.line(), SheetFallback, stacklevel=4)
    if decision.motion is None and options.sheet_stage:  # the stage never followed its points: its options did nothing
        for name in STAGE_OPTIONS:
            if name in options.changed():
                warnings.warn(f"{name}: the sheet stage did not read the video, so this option did nothing ({decision.reason})", UserWarning, stacklevel=4)
    return decision


def _stage(options: ReconstructOptions, frame: tuple) -> SheetStage:
    """Where the sheet stage runs (:func:`~.sheet.stage_of`), with a warning
    for ``isometric_hold`` where nothing is given: a sheet found by default is
    always read through its held points."""
    if options.isometric_hold and not options.sheet_given and options.sheet_mode:
        warnings.warn("isometric_hold: with neither focal nor sheet given the sheet is always found among held points; "
                      "this option acts with focal or sheet only", UserWarning, stacklevel=3)
    return stage_of(options, frame)


def _sheet_beside(pipeline: Pipeline, options: ReconstructOptions, stage: SheetStage, whole: Callable[[], Iterable[np.ndarray]]) -> ContextManager:
    """The sheet stage's reading (:func:`~.sheet.read_beside`) while the fine pass runs, where the stage runs; else nothing."""
    return nullcontext() if stage.region is None else read_beside(pipeline.shape[0], options, stage.camera, stage.region, whole)


def _decided(raw, pipeline: Pipeline, options: ReconstructOptions, stage: SheetStage, whole: Callable[[], Iterable[np.ndarray]],
             reading: Any) -> SheetDecision:
    """The sheet stage's decision, ``raw`` fused in place where it used the sheet's shape; said (:func:`_said`)."""
    if stage.region is None:
        return _said(dataclasses.replace(stage.skipped, frames=pipeline.shape[0]), options)
    return _said(sheet_depth(raw, pipeline.work, options, stage.camera, stage.region, whole, reading), options)


class Reconstruction(NamedTuple):
    """:func:`reconstruct`'s answer with ``with_decision=True``: the ``depth``
    and what the sheet stage did (``sheet``; its ``camera``: the one the
    shape was read through)."""

    depth: np.ndarray
    sheet: SheetDecision


class SheetFallback(UserWarning):
    """With ``focal`` or ``sheet``, the sheet stage left the network's depth alone (the
    warning says why: :class:`~nrdepth.reconstruct.SheetDecision`)."""


@sigint_remembered()  # a Ctrl-C that a library swallows still stops the job
def reconstruct(video: np.ndarray, model: Model = None, options: Optional[ReconstructOptions] = None, *, progress: Progress = None,
                with_decision: bool = False, **settings: Any) -> Union[np.ndarray, Reconstruction]:
    """The depth video of ``video`` (T, H, W[, 3]; uint8, or float in
    [0, 1]; colour becomes luma): float32 (T', H', W') of the selected
    frames and region.

    ``model``: a path to ``model.safetensors`` or its run folder, a
    ``torch.nn.Module``, or None for the shipped model. ``options``: an
    :class:`~nrdepth.ReconstructOptions`, and/or any of its fields as
    keywords (``roi=``, ``focal=``, ``device="cuda"``, …; they replace the
    options' own). ``progress(done, total)`` is called as frames of the
    fine pass are done. ``with_decision``: return a :class:`Reconstruction`,
    the depth with the sheet stage's decision (``depth, sheet = ...``).

    The job: the selected frames and region at a working resolution
    (``max_side``), the coarse pass (each whole frame through the network
    at the patch size, :mod:`~nrdepth.reconstruct.coarse`), the fine pass
    (:mod:`~nrdepth.reconstruct.fine`), its 16×64×64 windows aligned and
    overlap-added (:mod:`~nrdepth.reconstruct.stitch`), where the video
    shows a sheet the sheet's shape from inextensibility (:mod:`~nrdepth.reconstruct.sheet`:
    by default where its held points keep their lengths, or as ``focal``
    and ``sheet`` ask; ``sheet_stage=False`` leaves it out), then the depth's units and the video's resolution back.

    Depth is defined up to one GBR per frame (one for the video with
    ``temporal``) and returned with zero mean over the video, in
    ``units``: ``"standard"`` (unit standard deviation) or ``"pixels"``
    (depth in pixels of the video, for a model that learnt the relief's
    scale: model.json's ``depth_units`` ``"window"``; without ``model``,
    the shipped one that learnt it, :data:`nrdepth.model.SCALED_MODEL`).
    Its overall sign (convex or concave) follows the training data's light
    from above (within ±70° of image-up, row 0 the top): under an
    orthographic camera a surface and its mirror image under mirrored
    lights make the same video, so a video lit from below reads inverted,
    and ``flip=True`` (or ``-depth``) is the other reading. Where the
    sheet stage reads a sheet, a long video that bends it many ways gets its shape
    and the relief's sign from the sheet instead (docs/reconstruction.md).
    To stream a long video from a file to a folder, see
    :func:`reconstruct_file`."""
    gray = to_gray(video, "video")
    options = _options(options, progress, settings)
    file_only = [name for name in FILE_ONLY if name in options.changed()]
    if file_only:
        raise option_error(file_only[0], "says what reconstruct_file writes; reconstruct returns the depth")
    mask = video_mask(options.mask, gray.shape, options.frames, options.roi)
    stage = _stage(options, gray.shape[1:3])
    video = select(gray, options.frames, options.roi)
    device, net = _network(model, options)
    chunks = lambda: (video[a : a + CHUNK] for a in range(0, len(video), CHUNK))  # noqa: E731
    pipeline = Pipeline(video.shape[1:], chunks, net, device, options, mask)
    whole = lambda: iter(select(gray, options.frames, None))  # noqa: E731
    with _sheet_beside(pipeline, options, stage, whole) as reading:
        raw = np.concatenate(list(stitched(pipeline, progress)))
        decision = _decided(raw, pipeline, options, stage, whole, reading)
    offset, scale = units_of(pipeline, raw, options.temporal, options.units)
    depth = np.empty((len(raw), *pipeline.full), np.float32)
    for a in range(0, len(raw), CHUNK):  # a chunk at a time: the float64 working copy stays small (the same bits)
        depth[a : a + CHUNK] = final(pipeline, raw, a, min(a + CHUNK, len(raw)), offset, -scale if options.flip else scale)
    return Reconstruction(depth, decision) if with_decision else depth


@sigint_remembered()
def reconstruct_file(input: Union[str, "os.PathLike[str]"], out: Union[str, "os.PathLike[str]"], model: Model = None,
                     options: Optional[ReconstructOptions] = None, *, progress: Progress = None, **settings: Any) -> Path:
    """:func:`reconstruct` a video file, image folder or array file
    (:class:`~nrdepth.io.VideoSource`) into the folder ``out``
    (:class:`~nrdepth.io.ReconstructionWriter`: ``depth.npz``,
    ``depth.mp4``, ``side_by_side.mp4``, with ``viewer`` the 3-D page
    ``viewer.html``, with ``png16`` and ``ply`` their frames; all or
    nothing). ``model``, ``options``, ``progress`` and the keywords as
    :func:`reconstruct`'s.

    Streaming: the video is read a few frames at a time (three times:
    statistic and coarse pass, fine pass, writing; four with the sheet
    stage), the stitched depth waits on disk in the output's temporary
    folder at the working resolution, and memory does not grow with the
    video's length, except by its decoded frames up to
    :data:`~nrdepth.io.decode.KEEP_DECODED` (decoded once where they fit),
    the coarse pass's 20 kB a frame and, in sheet mode, the sheet's
    points' 6 kB a frame (and with ``temporal``, which aligns the whole
    video in memory, or ``fine="patches"``, which holds it). ``mask``
    may also be a file: one image (for every frame) or a video, image
    folder or array of the input's frame count, of the input's frame size;
    pixels of 128 or more (of 255) are on the surface. ``ply_relief``: the
    PLYs' depth scale (:func:`~nrdepth.io.write_ply`; default: the training
    surfaces' for standard units, one frame width per pixel for pixel
    units). Returns ``out``."""
    options = _options(options, progress, settings)
    device, net = _network(model, options)
    out = check_output_folder(out, options.overwrite, inputs=(input,))
    source = open_video(input, "input", options.frames, options.roi)
    mask = file_mask(options.mask, source, options.frames, options.roi)
    stage = _stage(options, source.raw_size)
    pipeline = Pipeline(source.frame_size, lambda: source.chunks(CHUNK), net, device, options, mask)
    t = pipeline.shape[0]
    ply_relief = options.ply_relief
    if ply_relief is None:
        ply_relief = 1.0 / source.frame_size[1] if options.units == "pixels" else PLY_RELIEF  # pixels to frame widths, the PLY's x and y unit
    with ReconstructionWriter(out, (t, *source.frame_size), source.fps, png16=options.png16, ply=options.ply, ply_relief=ply_relief,
                              overwrite=options.overwrite, viewer=options.viewer) as writer:
        writer.set_metadata("network", {"device": str(device), "precision": fine_precision(options.precision, device)})
        raw = DiskFrames(writer.scratch("stitched.f32"), pipeline.shape[1:])
        whole = lambda: (frame for chunk in source.chunks(CHUNK, roi=False) for frame in chunk)  # noqa: E731 (streamed)
        with _sheet_beside(pipeline, options, stage, whole) as reading:
            for chunk in stitched(pipeline, progress):
                raw.append(chunk)
            writer.set_metadata("sheet", _decided(raw, pipeline, options, stage, whole, reading).as_dict())
        offset, scale = units_of(pipeline, raw, options.temporal, options.units)
        scale = -scale if options.flip else scale
        # The ranges from the working resolution (bilinear resizing makes no new extremes), a chunk at a time.
        stride = max(1, int(math.sqrt(raw.size / 4e6)))
        sample = np.concatenate([raw[a : a + CHUNK][:, ::stride, ::stride].ravel() for a in range(0, t, CHUNK)])
        lo, hi = np.nanpercentile((sample.astype(np.float64) - offset) * scale, [1.0, 99.0])  # NaN: off the mask
        ends = sorted(((min(float(np.nanmin(raw[a : a + CHUNK])) for a in range(0, t, CHUNK)) - offset) * scale,
                       (max(float(np.nanmax(raw[a : a + CHUNK])) for a in range(0, t, CHUNK)) - offset) * scale))
        writer.set_ranges((float(lo), float(max(hi, lo + 1e-12))), (ends[0], ends[1]))
        # A few frames a write at large sizes: the colour and side-by-side frames take 9 bytes a pixel.
        step = max(1, min(CHUNK, 4_000_000 // (source.frame_size[0] * source.frame_size[1])))
        for start, frames_in in zip(range(0, t, step), source.chunks(step)):
            writer.write(frames_in, final(pipeline, raw, start, start + len(frames_in), offset, scale))
        raw.remove()
    return out
