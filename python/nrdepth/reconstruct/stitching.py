"""The stitching driver: the fine pass's windows into the streaming
stitcher (:mod:`.stitch`), in time order, so that frames leave as soon as
they are solved and memory does not grow with the video's length."""

from __future__ import annotations

from typing import Callable, Iterator, Optional

import numpy as np

from ..interrupt import raise_if_interrupted
from .fine import counted, field_frames, field_windows, patch_depths
from .pipeline import Pipeline
from .stitch import PATCH, make_stitcher, patch_layout

__all__ = ["stitched"]


def stitched(pipeline: Pipeline, progress: Optional[Callable[[int, int], None]] = None) -> Iterator[np.ndarray]:
    """The stitched depth of ``pipeline``'s video at the working
    resolution, in chunks of frames in order as they are solved (the joint
    alignment; the paper's gives its video at the end): the fine pass's
    windows, aligned and overlap-added with the coarse pass a little ahead
    of them."""
    t = pipeline.shape[0]
    layout = patch_layout(pipeline.shape)
    options = pipeline.options
    alignment = options.alignment
    given = 0 if alignment == "joint" else t
    stitcher = make_stitcher(pipeline.coarse(0, given), layout.patch, alignment, options.coarse_weight, options.window, options.temporal_weight, frames=t)
    if options.fine == "field":
        frames = field_frames((pipeline.shape, pipeline.working()), pipeline.net, pipeline.device, options.tile, statistic=pipeline.statistic,
                              precision=options.precision)
        windows = field_windows(layout, frames, progress=progress)
    else:
        video = np.concatenate(list(pipeline.working()))
        windows = counted(patch_depths(video, pipeline.net, layout, int(options.batch_size), pipeline.device), layout, progress)
    for origins, depth in windows:
        raise_if_interrupted()
        if alignment == "joint":
            # The coarse depth a little ahead of the windows: a span is solved with the one after it.
            want = min(t, int(origins[:, 0].max()) - layout.pad[0] + 2 * PATCH[0])
            if want > given:
                stitcher.push_coarse(pipeline.coarse(given, want))
                given = want
        stitcher.add(depth, origins)
        if alignment == "joint":
            done = stitcher.take()
            if len(done):
                yield done
    if given < t:
        stitcher.push_coarse(pipeline.coarse(given, t))
    rest = stitcher.finish()
    if len(rest):
        yield rest
