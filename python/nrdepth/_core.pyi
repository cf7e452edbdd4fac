"""Type stubs of the Rust extension. Use the typed wrappers in ``nrdepth``;
these functions take and return plain dicts."""

import os
from typing import Dict, List, Tuple

import numpy as np
import numpy.typing as npt

FFT_PERIOD: float
W_RADIUS: float
SPECTRUM_CUTOFF: float
MAX_GRID: int
MAX_FRAMES: int

def default_surface_config() -> Dict[str, Tuple[float, float]]: ...
def sample_surface_params(seed: int, config: Dict[str, Tuple[float, float]]) -> Dict[str, object]: ...
def validate_surface_params(params: Dict[str, object]) -> None: ...
def validate_surface_config(config: Dict[str, Tuple[float, float]]) -> None: ...
def synthesize_surface(params: Dict[str, object], frames: int, grid: int) -> npt.NDArray[np.float32]: ...
def synthesize_surfaces(params: List[Dict[str, object]], frames: int, grid: int) -> npt.NDArray[np.float32]: ...
def grid_triangles(grid: int) -> npt.NDArray[np.uint32]: ...
def write_png(path: str | os.PathLike[str], image: npt.NDArray[np.uint8]) -> None: ...
def write_png16(path: str | os.PathLike[str], image: npt.NDArray[np.uint16]) -> None: ...

CAMERA_Z: float

def render(
    vertices: npt.NDArray[np.float32],
    triangles: npt.NDArray[np.uint32],
    uv: npt.NDArray[np.float32],
    texture: npt.NDArray[np.float32],
    size: Tuple[int, int],
    window: Tuple[float, float, float, float],
    lights: List[Dict[str, object]],
    material: Dict[str, float],
    supersample: int,
    camera_z: float,
    shading: str,
    pinhole: Tuple[float, float] | None = None,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...
def raycast_depth(
    vertices: npt.NDArray[np.float32],
    triangles: npt.NDArray[np.uint32],
    size: Tuple[int, int],
    window: Tuple[float, float, float, float],
    camera_z: float,
    pinhole: Tuple[float, float] | None = None,
) -> npt.NDArray[np.float32]: ...
def procedural_texture(family: str, seed: int, size: int) -> npt.NDArray[np.float32]: ...
def texture_families() -> List[str]: ...
def default_generator_config() -> Dict[str, object]: ...
def validate_generator_config(config: Dict[str, object]) -> None: ...
def generate_clips(
    n: int, seed: int, start: int, config: Dict[str, object], textures: str | None = None, vertices: bool = False
) -> Tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32], List[Dict[str, object]], npt.NDArray[np.float32] | None]: ...
def patch_layout(
    shape: Tuple[int, int, int], patch: Tuple[int, int, int]
) -> Tuple[List[int], List[int], List[Tuple[int, int, int]]]: ...
class Stitcher:
    def __init__(
        self,
        coarse: npt.NDArray[np.float32],
        patch: Tuple[int, int, int],
        window: str,
        coarse_weight: float | None = None,
        temporal_weight: float = 0.0,
        frames: int | None = None,
    ) -> None: ...
    def add(self, patches: npt.NDArray[np.float32], origins: npt.NDArray[np.int64]) -> None: ...
    def push_coarse(self, coarse: npt.NDArray[np.float32]) -> None: ...
    def take(self) -> npt.NDArray[np.float32]: ...
    def finish(self) -> npt.NDArray[np.float32]: ...
def temporal_align(depth: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]: ...
def spread(
    points: npt.NDArray[np.float64],
    values: npt.NDArray[np.float64],
    triangles: npt.NDArray[np.uint32],
    size: Tuple[int, int],
) -> npt.NDArray[np.float64]: ...
