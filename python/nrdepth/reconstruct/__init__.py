"""The main job: a video in, its depth video out.

One file a stage, in the order they run:

- :mod:`.options`: :class:`ReconstructOptions`, every setting of the job, checked in one place;
- :mod:`.frames`: the frames at the working resolution, their statistic, a video on disk;
- :mod:`.network`: the network, loaded once on its device;
- :mod:`.pipeline`: the video read at the working resolution, with its coarse pass (:mod:`.coarse`);
- :mod:`.fine`: the fine pass, one network pass over the video in tiles (or the paper's patches);
- :mod:`.stitching`: its windows aligned and overlap-added by the streaming stitcher (:mod:`.stitch`);
- :mod:`.sheet`: the sheet's shape from inextensibility, by default where a sheet is found, and what it did (:mod:`.decision`);
- :mod:`.export`: the depth's units and the video's resolution back;
- :mod:`.api`: :func:`reconstruct` and :func:`reconstruct_file`, which chain them;
- :mod:`.batch`: :func:`reconstruct_many`, many videos side by side, here or on a Ray cluster.

Frames flow through in time order: the fine pass computes a span of
frames, the windows it completes go to the stitcher, which gives back the
frames it has solved, and frames no window needs any more are dropped, so
memory does not grow with the video's length. docs/reconstruction.md has
the figures.
"""

from ..camera import Camera
from .api import Reconstruction, SheetFallback, reconstruct, reconstruct_file
from .batch import BatchRow, reconstruct_many
from .coarse import coarse_depth, coarse_half
from .fine import GPU_TILE, MARGIN, TILE, field_frames, field_windows, patch_depths, tile_plan
from .frames import Statistic, working_shape
from .network import inference_model
from .options import FINE_PASSES, ISOMETRIC_DROP, MAX_SIDE, ReconstructOptions
from .sheet.settings import SheetSettings
from .decision import SheetDecision

__all__ = ["reconstruct", "reconstruct_file", "reconstruct_many", "BatchRow", "Reconstruction", "SheetDecision", "SheetSettings", "SheetFallback", "ReconstructOptions", "Camera", "MAX_SIDE", "FINE_PASSES", "ISOMETRIC_DROP",
           "coarse_depth", "coarse_half", "patch_depths", "field_frames", "field_windows", "tile_plan", "inference_model", "working_shape",
           "Statistic", "TILE", "GPU_TILE", "MARGIN"]
