"""nrdepth: dense depth video of non-rigidly deforming surfaces from ordinary video.

A Rust core (``nrdepth._core``) does the per-pixel and per-triangle work; this
package is its typed Python face.
"""

__version__ = "0.1.0"

import os as _os

# Transparent huge pages for torch's CPU buffers of 2 MB or more: the fine
# pass allocates ~1 GB of activations a tile, and with 4 kB pages their page
# faults cost a fifth of its time (kinect_paper: 21 M faults, network 52.9 s;
# with huge pages 0.96 M, 42.3 s). torch reads this once, at its first large
# allocation; a value the user set is kept.
_os.environ.setdefault("THP_MEM_ALLOC_ENABLE", "1")

from .camera import Camera
from .engine.generate import Clips, GeneratorConfig, generate_clips, image_points, observable_depth
from .engine.render import CAMERA_Z, TEXTURE_FAMILIES, Light, Material, Render, procedural_texture, raycast_depth, render
from .engine.surface import (
    SurfaceConfig,
    SurfaceParams,
    grid_triangles,
    sample_surface_params,
    synthesize_surface,
    synthesize_surfaces,
)
from . import memory  # nrdepth.memory.keep_freed_memory: the CLI's heap, for a caller's own process
from .io import view
from .reconstruct import Reconstruction, ReconstructOptions, SheetDecision, SheetSettings, reconstruct, reconstruct_file, reconstruct_many
from .reconstruct.stitch import PatchLayout, patch_layout, stitch, temporal_align
from .scores.metrics import flat_baseline, gbr_align, grid_contrast, mae_sn, sign_rates

__all__ = [
    "Camera",
    "ReconstructOptions",
    "Reconstruction",
    "SheetDecision",
    "SheetSettings",
    "CAMERA_Z",
    "TEXTURE_FAMILIES",
    "Clips",
    "GeneratorConfig",
    "Light",
    "Material",
    "Render",
    "flat_baseline",
    "generate_clips",
    "image_points",
    "observable_depth",
    "gbr_align",
    "grid_contrast",
    "mae_sn",
    "sign_rates",
    "PatchLayout",
    "patch_layout",
    "reconstruct",
    "reconstruct_file",
    "reconstruct_many",
    "view",
    "stitch",
    "temporal_align",
    "procedural_texture",
    "raycast_depth",
    "render",
    "SurfaceConfig",
    "SurfaceParams",
    "grid_triangles",
    "sample_surface_params",
    "synthesize_surface",
    "synthesize_surfaces",
]
