"""Does a clip lit from below show anything that its mirrored relief lit from above does not?

Under an orthographic camera and directional lights, the relief ``z`` lit
from azimuth ``a`` and the relief ``−z`` lit from ``a + π`` (the light's
``(x, y)`` negated, its elevation kept) have the same normals' dot products
with the light and the viewer, so the same image, border and background
included. Training on lit-from-below clips with a sign-free loss would then
add nothing but the mirrored reliefs' clips, lit from above, which the
signed losses already see. This renders the pairs with nrdepth's own
rasteriser and prints how far apart they are, beside the same relief lit
from above and from below (the difference the light's side makes), for a
directional light and a near point light, orthographic and through a
pinhole whose frame is as wide as the cloth's (25°) and as the training
clips' widest (80°). Intensities in [0, 1]; 32 surfaces by default.

    python experiments/mirror_light.py [--surfaces 32]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from nrdepth.engine.render import CAMERA_Z, Light, Material, procedural_texture, render
from nrdepth.engine.surface import grid_triangles, sample_surface_params, synthesize_surface

GRID, SIZE = 64, 64
WINDOW = (-0.8, -0.8, 0.8, 0.8)  # inside the patch [-1, 1]² (a border view would show black on both sides alike)


def light_pair(kind: str, azimuth: float, elevation: float) -> tuple:
    """A light from ``azimuth`` (0: image-up) and the same light mirrored through the optical axis."""
    x, y, z = math.sin(azimuth) * math.cos(elevation), math.cos(azimuth) * math.cos(elevation), math.sin(elevation)
    scale = 1.0 if kind == "directional" else 3.0  # a point light 3 half-widths from the patch centre
    return Light(kind, (scale * x, scale * y, scale * z)), Light(kind, (-scale * x, -scale * y, scale * z))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--surfaces", type=int, default=32)
    args = parser.parse_args()
    triangles = grid_triangles(GRID)
    u = np.linspace(0.0, 1.0, GRID, dtype=np.float32)
    uv = np.stack(np.meshgrid(u, u), -1).reshape(-1, 2)
    material = Material(ambient=0.1, diffuse=0.7, specular=0.3, shininess=20.0)
    rng = np.random.default_rng(0)
    cameras = {"orthographic": None, "pinhole 25°": 25.0, "pinhole 80°": 80.0}
    rows = {(kind, cam): ([], []) for kind in ("directional", "point") for cam in cameras}
    for s in range(args.surfaces):
        v = synthesize_surface(sample_surface_params(s), frames=1, grid=GRID)[0].reshape(-1, 3)
        mirrored = v * np.array([1.0, 1.0, -1.0], dtype=np.float32)
        texture = procedural_texture(("fractal", "stripes", "plaid", "cells", "weave")[s % 5], seed=s)
        azimuth, elevation = rng.uniform(-1.2, 1.2), rng.uniform(0.5, 1.3)
        for kind in ("directional", "point"):
            above, below = light_pair(kind, azimuth, elevation)
            for cam, fov in cameras.items():
                # A pinhole whose frame is the window: camera_z from the field of view across it.
                camera_z = CAMERA_Z if fov is None else (WINDOW[2] - WINDOW[0]) / 2 / math.tan(math.radians(fov) / 2)
                pinhole = None if fov is None else (0.0, 0.0)

                def shot(vertices, light):
                    return render(vertices, triangles, uv, texture, SIZE, WINDOW, [light], material,
                                  camera_z=camera_z, pinhole=pinhole).image

                lit_above = shot(v, above)
                rows[kind, cam][0].append(np.abs(shot(v, below) - lit_above).mean())
                rows[kind, cam][1].append(np.abs(shot(mirrored, below) - lit_above).mean())
    print(f"mean |difference| of intensity over {args.surfaces} surfaces, {SIZE}² (intensities in [0, 1])")
    print("| light | camera | z from above vs z from below | z from above vs −z from below |")
    print("|---|---|---|---|")
    for (kind, cam), (sides, mirrors) in rows.items():
        print(f"| {kind} | {cam} | {np.mean(sides):.4f} | {np.mean(mirrors):.5f} |")


if __name__ == "__main__":
    main()
