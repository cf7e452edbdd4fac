"""nrdepth: dense depth video of non-rigidly deforming surfaces from ordinary video.

A Rust core (``nrdepth._core``) does the per-pixel and per-triangle work; this
package is its typed Python face.
"""

__version__ = "0.1.0"

from .surface import (
    SurfaceConfig,
    SurfaceParams,
    grid_triangles,
    sample_surface_params,
    synthesize_surface,
    synthesize_surfaces,
)

__all__ = [
    "SurfaceConfig",
    "SurfaceParams",
    "grid_triangles",
    "sample_surface_params",
    "synthesize_surface",
    "synthesize_surfaces",
]
