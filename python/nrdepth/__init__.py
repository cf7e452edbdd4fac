"""nrdepth: dense depth video of non-rigidly deforming surfaces from ordinary video.

A Rust core (``nrdepth._core``) does the per-pixel and per-triangle work; this
package is its typed Python face.
"""

__version__ = "0.1.0"

from .generate import Clips, GeneratorConfig, generate_clips, observable_depth
from .metrics import flat_baseline, gbr_align, grid_contrast, mae_sn, sign_rates
from .stitch import PatchLayout, patch_layout, reconstruct, stitch, temporal_align
from .render import CAMERA_Z, TEXTURE_FAMILIES, Light, Material, Render, procedural_texture, raycast_depth, render
from .surface import (
    SurfaceConfig,
    SurfaceParams,
    grid_triangles,
    sample_surface_params,
    synthesize_surface,
    synthesize_surfaces,
)

__all__ = [
    "CAMERA_Z",
    "TEXTURE_FAMILIES",
    "Clips",
    "GeneratorConfig",
    "Light",
    "Material",
    "Render",
    "flat_baseline",
    "generate_clips",
    "observable_depth",
    "gbr_align",
    "grid_contrast",
    "mae_sn",
    "sign_rates",
    "PatchLayout",
    "patch_layout",
    "reconstruct",
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
