"""End-to-end clip generation: nrdepth.generate_clips against a straightforward
numpy reference pipeline doing the same work, both timed in this run.

The reference synthesises the same surface model with numpy's FFT, finds the
nearest hit at every pixel centre (depth, Phong light terms) and at 2×2
subsamples (texture) with vectorised numpy (candidate samples of every
triangle's bounding box, barycentric tests, nearest hit by sorting), builds a
fractal texture and adds noise: the work `generate_clips` does, written the
way one would in numpy.

    python benchmarks/bench_generate.py [--clips 256] [--reference-clips 3]
        [--repeats 1] [--set KEY=VALUE ...]

`--repeats N` times N calls and reports their median (and range): this
machine's speed swings from one call to the next. `--set` changes a field of
nrdepth's GeneratorConfig (e.g. `--set supersample=1`); the reference pipeline
always does the default work.
"""

from __future__ import annotations

import argparse
import ast
import os
import statistics
import time

import numpy as np

import nrdepth


def reference_surface(p: nrdepth.SurfaceParams, frames: int, grid: int) -> np.ndarray:
    m = 2 * (grid - 1)
    k = np.fft.fftfreq(m, 1.0 / m)
    kx, ky = np.meshgrid(k, k)
    ux, uy = kx / 4.0, ky / 4.0
    r2 = ux**2 + uy**2
    sxx, sxy, syy = p.orientation
    s = (1 - np.exp(-r2 / 0.0625)) * np.exp(-r2 / (2 * p.flexibility**2) - (sxx * ux**2 + 2 * sxy * ux * uy + syy * uy**2))
    s[m // 2, :] = s[:, m // 2] = 0
    s /= np.sqrt((s**2).sum() / 2) + 1e-30
    rng = np.random.default_rng(p.phase_seed % 2**63)
    theta, psi, rho = rng.uniform(0, 2 * np.pi, (3, 3, m, m)), rng.uniform(0, 2 * np.pi, (3, m, m)), rng.uniform(0.5, 1.5, (3, m, m))
    theta = theta[0]
    c = np.linspace(-1, 1, grid)
    x, y = np.meshgrid(c, c)
    envelope = p.intensity * np.exp(-p.constraint * (x**2 + y**2))
    out = np.empty((frames, grid, grid, 3))
    for f in range(frames):
        t = f / max(frames - 1, 1)
        for ch in range(3):
            spec = s * np.cos(t * np.asarray(p.speeds)[ch] * rho[ch] + theta[ch]) * np.exp(1j * psi[ch])
            field = np.real(np.fft.ifft2(spec) * m * m)[:grid, :grid]
            scale = p.folding if ch < 2 else 1.0
            out[f, ..., ch] = envelope * scale * field
        out[f, ..., 0] += x
        out[f, ..., 1] += y
    return out


def reference_texture(seed: int, size: int = 256) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tex = np.zeros((size, size))
    for octave in range(5):
        cells = 4 << octave
        lattice = rng.random((cells + 1, cells + 1))
        pos = (np.arange(size) + 0.5) / size * cells
        i, f = pos.astype(int), pos - pos.astype(int)
        f = f * f * (3 - 2 * f)
        top = lattice[i][:, i] * (1 - f)[None, :] + lattice[i][:, i + 1] * f[None, :]
        bottom = lattice[i + 1][:, i] * (1 - f)[None, :] + lattice[i + 1][:, i + 1] * f[None, :]
        tex += 0.5**octave * (top * (1 - f)[:, None] + bottom * f[:, None])
    return (tex - tex.min()) / np.ptp(tex)


def reference_visibility(screen: np.ndarray, tris: np.ndarray, rows: int, cols: int):
    """Nearest triangle and barycentrics per sample of a (rows, cols) grid; screen is (V, 3) [col, row, z]."""
    a, b, c = screen[tris[:, 0]], screen[tris[:, 1]], screen[tris[:, 2]]
    lo = np.floor(np.minimum(np.minimum(a, b), c)[:, :2] - 0.5).astype(int)
    cand_t, cand_r, cand_c = [], [], []
    for dr in range(5):
        for dc in range(5):
            cand_t.append(np.arange(len(tris)))
            cand_c.append(lo[:, 0] + dc)
            cand_r.append(lo[:, 1] + dr)
    t, r, cc = np.concatenate(cand_t), np.concatenate(cand_r), np.concatenate(cand_c)
    px, py = cc + 0.5, r + 0.5
    A, B, C = a[t], b[t], c[t]
    area = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    w0 = ((B[:, 0] - px) * (C[:, 1] - py) - (B[:, 1] - py) * (C[:, 0] - px)) / area
    w1 = ((C[:, 0] - px) * (A[:, 1] - py) - (C[:, 1] - py) * (A[:, 0] - px)) / area
    w2 = 1 - w0 - w1
    ok = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (r >= 0) & (r < rows) & (cc >= 0) & (cc < cols) & (area != 0)
    t, r, cc, w0, w1, w2 = t[ok], r[ok], cc[ok], w0[ok], w1[ok], w2[ok]
    z = w0 * A[ok, 2] + w1 * B[ok, 2] + w2 * C[ok, 2]
    pixel = r * cols + cc
    order = np.lexsort((z, pixel))
    last = np.r_[pixel[order][1:] != pixel[order][:-1], True]
    keep = order[last]
    tri = np.full(rows * cols, -1)
    weights = np.zeros((rows * cols, 3))
    zbuf = np.full(rows * cols, np.nan)
    tri[pixel[keep]] = t[keep]
    weights[pixel[keep]] = np.stack([w0[keep], w1[keep], w2[keep]], -1)
    zbuf[pixel[keep]] = z[keep]
    return tri, weights, zbuf


def reference_clip(seed: int, frames: int = 16, size: int = 64, grid: int = 64) -> tuple:
    p = nrdepth.sample_surface_params(seed)
    positions = reference_surface(p, frames, grid)
    tris = nrdepth.grid_triangles(grid).astype(int)
    texture = reference_texture(seed)
    c = np.linspace(0, 1, grid)
    u, v = np.meshgrid(c, 1 - c)
    uv = np.stack([u, v], -1).reshape(-1, 2)
    light = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    window = (-0.5, -0.5, 0.5, 0.5)
    video = np.empty((frames, size, size), np.uint8)
    depth = np.empty((frames, size, size), np.float32)
    rng = np.random.default_rng(seed)
    for f in range(frames):
        verts = positions[f].reshape(-1, 3)
        normals = np.zeros_like(verts)
        fn = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
        for k in range(3):
            np.add.at(normals, tris[:, k], fn)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        # Pixel centres: depth and the light terms; 2×2 subsamples: albedo.
        diffuse, specular = np.zeros(size * size), np.zeros(size * size)
        for s in (1, 2):
            screen = np.column_stack([(verts[:, 0] - window[0]) / (window[2] - window[0]) * size * s, (window[3] - verts[:, 1]) / (window[3] - window[1]) * size * s, verts[:, 2]])
            tri, w, zbuf = reference_visibility(screen, tris, size * s, size * s)
            hit = tri >= 0
            idx = tris[tri[hit]]
            if s == 1:
                depth[f] = (nrdepth.CAMERA_Z - zbuf).reshape(size, size)
                n = np.einsum("sk,skc->sc", w[hit], normals[idx])
                n /= np.linalg.norm(n, axis=1, keepdims=True)
                ndl = np.clip(n @ light, 0, None)
                rdv = np.clip(2 * ndl * n[:, 2] - light[2], 0, None)
                diffuse[hit], specular[hit] = 0.1 + 0.8 * ndl, 0.3 * rdv**20
                continue
            uvs = np.einsum("sk,skc->sc", w[hit], uv[idx])
            albedo = np.zeros(size * s * size * s)
            albedo[hit] = texture[(uvs[:, 1] * 255).astype(int), (uvs[:, 0] * 255).astype(int)]
            image = albedo.reshape(size, 2, size, 2).mean(axis=(1, 3)) * diffuse.reshape(size, size) + specular.reshape(size, size)
            video[f] = (np.clip(image + rng.normal(0, 0.01, image.shape), 0, 1) * 255).round()
    return video, depth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=256)
    parser.add_argument("--reference-clips", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=1, help="timed calls of generate_clips (median reported)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a GeneratorConfig field for nrdepth's side")
    args = parser.parse_args()
    if args.clips < 1 or args.reference_clips < 1 or args.repeats < 1:
        parser.error("--clips, --reference-clips and --repeats must be >= 1")
    overrides = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            parser.error(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            overrides[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            overrides[key] = value  # a bare word, e.g. shading=gouraud
    try:
        config = nrdepth.GeneratorConfig(**overrides)
    except (TypeError, ValueError) as error:
        parser.error(f"--set: {error}")

    # Warm up with a call of the timed size: the thread pool, and the
    # process's first touch of that much fresh memory, which a virtual
    # machine backs page by page (here up to ~3 ms a MB the first time, a
    # cost a long generation job pays once). The timed calls are the steady state.
    nrdepth.generate_clips(args.clips, seed=0, config=config)
    rates, redraws = [], 0
    for repeat in range(args.repeats):
        start = time.perf_counter()
        clips = nrdepth.generate_clips(args.clips, seed=1 + repeat, config=config)
        rates.append(args.clips / (time.perf_counter() - start))
        redraws += sum(p["redraws"] for p in clips.params)
    ours = statistics.median(rates)

    start = time.perf_counter()
    for seed in range(args.reference_clips):
        reference_clip(seed)
    reference = args.reference_clips / (time.perf_counter() - start)

    threads = os.environ.get("RAYON_NUM_THREADS", str(os.cpu_count()))
    changed = ", ".join(f"{k}={v!r}" for k, v in overrides.items()) or "none"
    print(f"default config: 16 frames, 64×64, grid 64, supersample 2; changed for nrdepth: {changed}; threads: {threads}")
    spread = f", median of {args.repeats} calls, {min(rates):.1f}–{max(rates):.1f}" if args.repeats > 1 else ""
    print(f"nrdepth.generate_clips     {ours:9.1f} clips/s  ({args.clips} clips{spread}, {redraws} redraws)")
    print(f"numpy reference pipeline   {reference:9.2f} clips/s  ({args.reference_clips} clips)")
    print(f"ratio                      {ours / reference:9.1f}×")
    print(f"153,600 clips (the paper's database) would take {153600 / ours / 60:.1f} min")


if __name__ == "__main__":
    main()
