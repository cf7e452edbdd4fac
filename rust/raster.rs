//! Software rasteriser: z-buffer (orthographic or perspective camera,
//! `geometry`), smooth normals, textured Phong.
//!
//! Frames and pixel conventions are `geometry.rs`'s. Two passes over a band of
//! pixel rows (rayon over bands for a single frame, one band a frame inside
//! the per-clip generator):
//! 1. visibility: every triangle is scanned over the sample points its
//!    bounding box covers, on two grids: the s×s subsamples of each pixel and
//!    the pixel centres. A sample keeps the highest hit (largest z ≤ `View::z_max`; for a
//!    perspective camera z is the warped height, `View::warp`)
//!    with its triangle and its texture coordinates (subsamples) or
//!    barycentric weights (centres). The test is `geometry::TriangleSetup`'s
//!    in subsample space, the ray caster's own arithmetic, so the centre depth
//!    equals `bvh::raycast_depth` bit for bit when s is a power of two
//!    (scaling by 2^k is exact) and to rounding otherwise: the renderer gives
//!    the depth video as well as the images. Four samples of a row are tested
//!    and kept at once, branch-free (SIMD lanes: the same IEEE operations
//!    lane by lane, so the results do not depend on the instruction set;
//!    both passes are compiled for the baseline and for AVX2, chosen at run
//!    time, with the same bits).
//! 2. shading: albedo sampled bilinearly (clamp to edge, by a repeated last
//!    row and column; four subsamples at once) at every covered subsample's
//!    texture coordinates and averaged (box filter;
//!    background subsamples contribute 0 and lower the pixel's coverage); the
//!    light terms once per pixel at its centre, as multisampling renderers do
//!    (lighting varies over a ~2 px² triangle far more slowly than texture):
//!    `Shading::Phong` interpolates the smooth normal there (area-weighted face
//!    normals, flipped toward the camera: lighting is two-sided),
//!    `Shading::Gouraud` interpolates lighting computed at the vertices. Phong:
//!    `I = k_a ρ + Σ_l I_l (k_d ρ max(0, n·l) + k_s max(0, r·v)^α)` with
//!    `v` toward the camera (+z for the orthographic one, toward the
//!    pinhole from the surface point for a perspective one; the point is
//!    interpolated with the pixel-space weights, whose error on a grid's
//!    pixel-sized triangles is negligible), `r = 2(n·l)n − l`; specular terms
//!    `(r·v)^α` below 1e-4 are dropped, the power is `pow4`'s (polynomial
//!    log₂ and exp₂ in plain f32 operations: no libm).
//!
//! Texture coordinates: u along texture columns, v along rows, both in [0, 1];
//! texel (row, col) has its centre at ((row + ½)/H, (col + ½)/W).

use rayon::prelude::*;
use wide::{f32x4, i32x4, u32x4};

use crate::error::{InvalidArgument, Result};
use crate::geometry::{check_mesh, TriangleSetup, View};
use crate::lanes::{with_avx2, Lanes8, Pair4, HALF};
#[cfg(target_arch = "x86_64")]
use crate::lanes::Avx8;

/// Sample points of a row processed at once (SIMD lanes): a visibility
/// test's half, the shading's four-lane vectors.
const LANES: usize = HALF;
/// Largest supersampling factor per axis.
pub const MAX_SUPERSAMPLE: usize = 8;
/// Most subsamples one render may hold (H·W·s²): 2²⁸, whose buffers take a few GiB.
pub const MAX_SAMPLES: usize = 1 << 28;
/// Relative size below which a specular term is dropped.
const SPECULAR_FLOOR: f32 = 1e-4;
/// Slack, in subsamples, of a triangle's bounding box.
const MARGIN: f32 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// `vector` is the direction toward the light (normalised on use).
    Directional,
    /// `vector` is the light's position; no distance fall-off.
    Point,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub kind: LightKind,
    pub vector: [f32; 3],
    pub intensity: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
}

impl Material {
    pub fn validate(&self) -> Result<()> {
        for (name, v, hi) in [
            ("material.ambient", self.ambient, 10.0),
            ("material.diffuse", self.diffuse, 10.0),
            ("material.specular", self.specular, 10.0),
            ("material.shininess", self.shininess, 10_000.0),
        ] {
            if !(v.is_finite() && (0.0..=hi).contains(&v)) {
                return Err(InvalidArgument::new(name, format!("expected a value in [0, {hi}], got {v}")));
            }
        }
        Ok(())
    }
}

pub fn check_lights(lights: &[Light]) -> Result<()> {
    for (i, l) in lights.iter().enumerate() {
        let norm = l.vector.iter().map(|v| v * v).sum::<f32>();
        if !l.vector.iter().all(|v| v.is_finite()) || (l.kind == LightKind::Directional && norm == 0.0) {
            return Err(InvalidArgument::new(format!("lights[{i}]"), format!("expected a finite, non-zero vector, got {:?}", l.vector)));
        }
        if !(l.intensity.is_finite() && l.intensity >= 0.0) {
            return Err(InvalidArgument::new(format!("lights[{i}]"), format!("expected a finite intensity >= 0, got {}", l.intensity)));
        }
    }
    Ok(())
}

/// A grayscale albedo image (values finite, normally in [0, 1]), stored with
/// its last column and last row repeated once past the edge: a bilinear
/// footprint is then two contiguous texel pairs wherever it lies, and reading
/// the repeated texel gives what clamping the index to the edge gives.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texture {
    height: usize,
    width: usize,
    /// (height + 1) × (width + 1) texels, row-major.
    padded: Vec<f32>,
}

impl Texture {
    /// `height × width` texels, row-major.
    pub fn new(height: usize, width: usize, texels: &[f32]) -> Result<Self> {
        // Texel indices are computed in i32 lanes.
        if height == 0 || width == 0 || texels.len() != height * width || (height + 1).saturating_mul(width + 1) > i32::MAX as usize {
            return Err(InvalidArgument::new("texture", format!("expected a non-empty (H, W) image with (H + 1)(W + 1) < 2^31, got {height}×{width} with {} values", texels.len())));
        }
        if !texels.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("texture", "expected finite values"));
        }
        let mut texture = Self::default();
        texture.reset(height, width);
        for (r, row) in texels.chunks_exact(width).enumerate() {
            texture.row_mut(r).copy_from_slice(row);
        }
        texture.repeat_edges();
        Ok(texture)
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Row `r` (`width` texels).
    pub fn row(&self, r: usize) -> &[f32] {
        &self.padded[r * (self.width + 1)..][..self.width]
    }

    /// The texels, row-major, without the repeated edges.
    pub fn to_vec(&self) -> Vec<f32> {
        (0..self.height).flat_map(|r| self.row(r).iter().copied()).collect()
    }

    /// Refill in place: `height × width` zeros; write rows with
    /// [`row_mut`](Self::row_mut), then call [`repeat_edges`](Self::repeat_edges).
    pub(crate) fn reset(&mut self, height: usize, width: usize) {
        (self.height, self.width) = (height, width);
        self.padded.clear();
        self.padded.resize((height + 1) * (width + 1), 0.0);
    }

    pub(crate) fn row_mut(&mut self, r: usize) -> &mut [f32] {
        &mut self.padded[r * (self.width + 1)..][..self.width]
    }

    /// Copy the last column and row past the edge.
    pub(crate) fn repeat_edges(&mut self) {
        let stride = self.width + 1;
        for row in self.padded.chunks_exact_mut(stride) {
            row[stride - 1] = row[stride - 2];
        }
        let last = self.height * stride;
        self.padded.copy_within(last - stride..last, last);
    }

    /// Bilinear sample at (u, v), clamped to the edge.
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        let c = (u * self.width as f32 - 0.5).clamp(0.0, (self.width - 1) as f32);
        let r = (v * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        // In range after the clamp: the cheap conversion.
        let (c0, r0) = (c as i32 as usize, r as i32 as usize);
        let (c1, r1) = ((c0 + 1).min(self.width - 1), (r0 + 1).min(self.height - 1));
        let (fc, fr) = (c - c0 as f32, r - r0 as f32);
        let (row0, row1) = (self.row(r0), self.row(r1));
        let top = row0[c0] + (row0[c1] - row0[c0]) * fc;
        let bottom = row1[c0] + (row1[c1] - row1[c0]) * fc;
        top + (bottom - top) * fr
    }

    /// [`sample`](Self::sample) at four points at once: the same arithmetic
    /// lane by lane (SIMD, texel fetches scalar).
    #[inline]
    pub fn sample4(&self, u: f32x4, v: f32x4) -> f32x4 {
        self.sampler().sample4(u, v)
    }

    /// The texture with its sizes prepared for many [`Sampler::sample4`] calls.
    #[inline]
    pub fn sampler(&self) -> Sampler<'_> {
        let (width, height) = (self.width as f32, self.height as f32);
        Sampler {
            padded: &self.padded,
            stride: i32x4::splat(self.width as i32 + 1),
            size: [f32x4::splat(width), f32x4::splat(height)],
            last: [f32x4::splat(width - 1.0), f32x4::splat(height - 1.0)],
        }
    }
}

/// A texture and its sizes as SIMD constants, built once per render band
/// rather than converted again at every texture fetch.
#[derive(Clone, Copy)]
pub struct Sampler<'a> {
    padded: &'a [f32],
    /// Texels per padded row.
    stride: i32x4,
    /// Width and height.
    size: [f32x4; 2],
    /// Last column and row.
    last: [f32x4; 2],
}

impl Sampler<'_> {
    /// [`Texture::sample`] at four points at once: the same arithmetic lane
    /// by lane (SIMD, texel fetches scalar). Where a footprint's first texel
    /// is on the last column (or row), its weight there is exactly 1 and the
    /// repeated texel beside it is the one `sample` clamps to: the same bits.
    #[inline(always)]
    pub fn sample4(&self, u: f32x4, v: f32x4) -> f32x4 {
        let half = f32x4::splat(0.5);
        // Clamped as `f32::clamp` clamps finite values (a NaN lane reads texel 0).
        let clamp = |x: f32x4, hi: f32x4| x.fast_max(f32x4::ZERO).fast_min(hi);
        let c = clamp(u * self.size[0] - half, self.last[0]);
        let r = clamp(v * self.size[1] - half, self.last[1]);
        let (c0, r0) = (c.fast_trunc_int(), r.fast_trunc_int());
        let (fc, fr) = (c - f32x4::from_i32x4(c0), r - f32x4::from_i32x4(r0));
        let first = (r0 * self.stride + c0).to_array();
        // u32 indices: one bounds check a lane, no overflow check.
        let stride = self.stride.to_array()[0] as u32 as usize;
        let footprints: [[f32; 4]; LANES] = std::array::from_fn(|k| {
            let i = first[k] as u32 as usize;
            let texels = &self.padded[i..i + stride + 2];
            [texels[0], texels[1], texels[stride], texels[stride + 1]]
        });
        let [t00, t01, t10, t11] = std::array::from_fn(|q| f32x4::new(footprints.map(|f| f[q])));
        let top = t00 + (t01 - t00) * fc;
        let bottom = t10 + (t11 - t10) * fc;
        top + (bottom - top) * fr
    }
}

/// Where the Phong model is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// At every pixel centre, with the interpolated normal (Phong shading).
    Phong,
    /// At the vertices, interpolated to the pixel centres (Gouraud):
    /// highlights smaller than a triangle are blurred.
    Gouraud,
}

impl Shading {
    pub fn name(self) -> &'static str {
        match self {
            Self::Phong => "phong",
            Self::Gouraud => "gouraud",
        }
    }

    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "phong" => Ok(Self::Phong),
            "gouraud" => Ok(Self::Gouraud),
            other => Err(InvalidArgument::new("shading", format!("expected 'phong' or 'gouraud', got {other:?}"))),
        }
    }
}

/// Everything that describes a render apart from the mesh.
#[derive(Clone, Debug)]
pub struct Scene<'a> {
    pub view: View,
    pub supersample: usize,
    pub lights: &'a [Light],
    pub material: Material,
    pub texture: &'a Texture,
    pub shading: Shading,
}

/// The highest hit of every sample point of a grid: its z (−∞ where nothing
/// was hit), triangle and a two-component attribute interpolated there: the
/// texture coordinates (u, v) on the subsample grid, the barycentric weights
/// (λb, λc) on the pixel-centre grid. Only z is reset: the rest is read only
/// where z is finite. Sample (row, col) is at `row · stride + col`: each row
/// is padded with `LANES − 1` samples, so that a group of lanes can start at
/// any sample of it, and a padding row below the last lets a scan test the
/// row below its last one.
#[derive(Default)]
struct Samples {
    rows: usize,
    cols: usize,
    stride: usize,
    z: Vec<f32>,
    triangle: Vec<u32>,
    attribute: [Vec<f32>; 2],
}

impl Samples {
    fn reset(&mut self, rows: usize, cols: usize) {
        (self.rows, self.cols, self.stride) = (rows, cols, cols + LANES - 1);
        let padded = (rows + 1) * self.stride;
        self.z.clear();
        self.z.resize(padded, f32::NEG_INFINITY);
        self.triangle.resize(padded, 0);
        self.attribute.iter_mut().for_each(|a| a.resize(padded, 0.0));
    }

    #[inline(always)]
    fn index(&self, row: usize, col: usize) -> usize {
        row * self.stride + col
    }

    #[inline(always)]
    fn is_hit(&self, i: usize) -> bool {
        self.z[i] > f32::NEG_INFINITY
    }

    /// The `groups` consecutive groups of `HALF` samples from (`row`, `col`),
    /// each with the group below it: the row pair's bounds are checked once
    /// a buffer, and a group needs one index check (the compiler keeps one).
    #[inline(always)]
    fn row_pair(&mut self, row: usize, col: usize, groups: usize) -> RowPair<'_> {
        let (start, stride, n) = (self.index(row, col), self.stride, groups * HALF);
        fn halves<T>(values: &mut [T], start: usize, stride: usize, n: usize) -> [&mut [[T; HALF]]; 2] {
            let (upper, lower) = values[start..start + stride + n].split_at_mut(stride);
            [upper[..n].as_chunks_mut().0, lower.as_chunks_mut().0]
        }
        let [u, v] = &mut self.attribute;
        let (z, triangle) = (halves(&mut self.z, start, stride, n), halves(&mut self.triangle, start, stride, n));
        RowPair { z, triangle, attribute: [halves(u, start, stride, n), halves(v, start, stride, n)] }
    }
}

/// Groups of `HALF` consecutive samples of a grid row and the `HALF` below
/// them, as many in every slice.
struct RowPair<'a> {
    z: [&'a mut [[f32; HALF]]; 2],
    triangle: [&'a mut [[u32; HALF]]; 2],
    attribute: [[&'a mut [[f32; HALF]]; 2]; 2],
}

impl RowPair<'_> {
    /// Group `g` (indexing, not iterator adaptors: a zip of eight chunk
    /// iterators cost ~40 instructions a group).
    #[inline(always)]
    fn group(&mut self, g: usize) -> PairGroup<'_> {
        let [zu, zl] = &mut self.z;
        let [tu, tl] = &mut self.triangle;
        let [[uu, ul], [vu, vl]] = &mut self.attribute;
        PairGroup { z: [&mut zu[g], &mut zl[g]], triangle: [&mut tu[g], &mut tl[g]], attribute: [[&mut uu[g], &mut ul[g]], [&mut vu[g], &mut vl[g]]] }
    }
}

/// `HALF` consecutive samples of a grid row and the `HALF` below them.
struct PairGroup<'a> {
    z: [&'a mut [f32; HALF]; 2],
    triangle: [&'a mut [u32; HALF]; 2],
    attribute: [[&'a mut [f32; HALF]; 2]; 2],
}

impl PairGroup<'_> {
    /// Keep triangle `t`'s hits (z, attribute) in the lanes `inside` where
    /// they are the highest so far (and not behind the camera); lanes
    /// `0..HALF` are the upper row's samples. The other lanes are written
    /// back unchanged.
    #[inline(always)]
    fn keep<L: Lanes8>(self, t: u32, inside: L, z: L, z_max: f32, attribute: impl FnOnce() -> [L; 2]) {
        let [z_upper, z_lower] = self.z;
        let old = L::load(z_upper, z_lower);
        // Branch-free: a lane that keeps nothing is rewritten with its own value.
        let higher = inside & z.simd_gt(old) & z.simd_le(L::splat(z_max));
        higher.select(z, old).store(z_upper, z_lower);
        let [t_upper, t_lower] = self.triangle;
        higher.select(L::splat_bits(t), L::load_bits(t_upper, t_lower)).store_bits(t_upper, t_lower);
        for ([upper, lower], new) in self.attribute.into_iter().zip(attribute()) {
            higher.select(new, L::load(upper, lower)).store(upper, lower);
        }
    }
}

/// The `LANES` values from `i`.
#[inline(always)]
fn lanes<T: Copy>(values: &[T], i: usize) -> [T; LANES] {
    // One bounds check and one unaligned load, not four of each.
    values[i..i + LANES].try_into().expect("a slice of LANES values")
}

/// Buffers of one band of pixel rows: the visibility of the s×s subsamples
/// of its pixels and of its pixel centres (two grids even at s = 1, where
/// they coincide), and one subsample row's texture samples and hit flags.
#[derive(Default)]
struct Band {
    /// Per vertex, the sides of the band it lies beyond (`visibility_band`).
    outside: Vec<u8>,
    /// Per vertex, whether it is a corner of a triangle `visibility_band`
    /// scanned: a superset of those whose normals `shade_band` reads (the
    /// triangles that won a sample).
    scanned: Vec<bool>,
    subsamples: Samples,
    centres: Samples,
    /// Albedo at each subsample of a row, 0 where it is background.
    texels: Vec<f32>,
    /// 1 where a subsample of the row is hit, 0 where it is background.
    covered: Vec<f32>,
}

/// Reusable buffers of one renderer; one per thread.
#[derive(Default)]
pub struct Rasterizer {
    normals: Vec<[f32; 3]>,
    lit: Vec<[f32; 2]>,
    screen: Vec<[f32; 3]>,
    band: Band,
}

/// What a render produces, per pixel.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    /// Shaded intensity (H·W), background counted as 0.
    pub image: Vec<f32>,
    /// Fraction of a pixel's subsamples that hit the mesh (H·W).
    pub coverage: Vec<f32>,
    /// Depth (`View::depth`) of the highest hit at the pixel centre (H·W), NaN
    /// for background: the ray caster's depth (bit for bit when s is a power of two).
    pub depth: Vec<f32>,
}

/// The per-render inputs every band reads.
#[derive(Clone, Copy)]
struct Prepared<'a> {
    vertices: &'a [[f32; 3]],
    triangles: &'a [[u32; 3]],
    uv: &'a [[f32; 2]],
    normals: &'a [[f32; 3]],
    /// Vertex lighting for `Shading::Gouraud`, empty for Phong.
    lit: &'a [[f32; 2]],
    /// Vertices in subsample space (`View::pixel_vertex` with scale s).
    screen: &'a [[f32; 3]],
    scene: &'a Scene<'a>,
}

impl Rasterizer {
    /// Render `vertices` / `triangles` with texture coordinates `uv` into `frame`,
    /// on this thread. The caller validates the inputs (`check_render_inputs`).
    /// Normals (and Gouraud's vertex lighting) are computed after visibility,
    /// only at the corners of the triangles it scanned: the same sums in the
    /// same order, so the same bits as `render`.
    pub fn render_into(&mut self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], uv: &[[f32; 2]], scene: &Scene, frame: &mut Frame) {
        let s = scene.supersample;
        self.screen.clear();
        self.screen.extend(vertices.iter().map(|&v| scene.view.pixel_vertex(v, s as f32)));
        let (height, width) = (scene.view.height, scene.view.width);
        for buffer in [&mut frame.image, &mut frame.coverage, &mut frame.depth] {
            buffer.resize(height * width, 0.0);
        }
        let band = &mut self.band;
        let visible = Prepared { vertices, triangles, uv, normals: &[], lit: &[], screen: &self.screen, scene };
        band.centres.reset(height, width);
        band.subsamples.reset(height * s, width * s);
        visibility_band(&visible, 0, height, band);
        vertex_normals(vertices, triangles, Some(&band.scanned), &mut self.normals);
        self.lit.clear();
        if scene.shading == Shading::Gouraud {
            vertex_lighting(vertices, &self.normals, Some(&band.scanned), scene, &mut self.lit);
        }
        let prepared = Prepared { normals: &self.normals, lit: &self.lit, ..visible };
        shade_band(&prepared, 0, band, &mut frame.image, &mut frame.coverage);
        write_depth(&band.centres, &scene.view, &mut frame.depth);
    }
}

with_avx2! {
    /// [`visibility_pass`], AVX2 where available.
    fn visibility_band(p: &Prepared, row0: usize, rows: usize, band: &mut Band) => visibility_pass::<Avx8>, visibility_pass::<Pair4>
}

with_avx2! {
    /// [`shade_pass`], AVX2 where available.
    fn shade_band(p: &Prepared, row0: usize, band: &mut Band, image: &mut [f32], coverage: &mut [f32]) => shade_pass, shade_pass
}

/// Render the pixel rows `row0 ..` that `image` / `coverage` / `depth` cover.
fn render_band(p: &Prepared, row0: usize, band: &mut Band, image: &mut [f32], coverage: &mut [f32], depth: &mut [f32]) {
    let s = p.scene.supersample;
    let width = p.scene.view.width;
    let rows = image.len() / width;
    band.centres.reset(rows, width);
    band.subsamples.reset(rows * s, width * s);
    visibility_band(p, row0, rows, band);
    shade_band(p, row0, band, image, coverage);
    write_depth(&band.centres, &p.scene.view, depth);
}

/// Depth (`View::depth`) of the pixel centres, NaN where nothing was hit.
fn write_depth(centres: &Samples, view: &View, depth: &mut [f32]) {
    for (depth, z) in depth.chunks_exact_mut(centres.cols).zip(centres.z.chunks(centres.stride)) {
        depth.iter_mut().zip(z).for_each(|(d, &z)| *d = if z.is_finite() { view.depth(z) } else { f32::NAN });
    }
}

/// Per-vertex unit normals: area-weighted sums of face normals, in triangle
/// order. With `wanted`, only at the vertices it flags (the others are left
/// unspecified): skipping the triangles with no wanted corner leaves the
/// wanted sums, and so their bits, unchanged.
pub fn vertex_normals(vertices: &[[f32; 3]], triangles: &[[u32; 3]], wanted: Option<&[bool]>, normals: &mut Vec<[f32; 3]>) {
    let is_wanted = |k: usize| wanted.is_none_or(|w| w[k]);
    normals.clear();
    normals.resize(vertices.len(), [0.0; 3]);
    for &t in triangles.iter().filter(|t| t.iter().any(|&k| is_wanted(k as usize))) {
        let [a, b, c] = t.map(|k| vertices[k as usize]);
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        for k in t {
            let m = &mut normals[k as usize];
            m[0] += n[0];
            m[1] += n[1];
            m[2] += n[2];
        }
    }
    for (k, n) in normals.iter_mut().enumerate() {
        if !is_wanted(k) {
            continue;
        }
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len > 0.0 {
            n.iter_mut().for_each(|v| *v /= len);
        } else {
            *n = [0.0, 0.0, 1.0];
        }
    }
}

/// Visibility of the pixel rows `row0 .. row0 + rows` at their subsamples
/// and pixel centres. `p.screen` holds the vertices in subsample space, where
/// the centre of pixel (i, j) is ((j + ½)s, (i + ½)s).
#[inline(always)]
fn visibility_pass<L: Lanes8>(p: &Prepared, row0: usize, rows: usize, band: &mut Band) {
    let view = &p.scene.view;
    let (s, z_max) = (p.scene.supersample, view.z_max());
    let (cols, sf) = (view.width * s, s as f32);
    let (sub_lo, sub_hi) = ((row0 * s) as f32, ((row0 + rows) * s) as f32 - 1.0);
    // Most triangles of a grid lie outside the view: one bit per side of the
    // band (one pixel of slack) a vertex lies beyond, and a triangle whose
    // three corners share a bit is out before any rounding.
    let beyond = [sub_lo - sf, sub_hi + sf, -sf, cols as f32 + sf];
    band.scanned.clear();
    band.scanned.resize(p.screen.len(), false);
    band.outside.clear();
    band.outside.extend(p.screen.iter().map(|v| u8::from(v[1] < beyond[0]) | u8::from(v[1] > beyond[1]) << 1 | u8::from(v[0] < beyond[2]) << 2 | u8::from(v[0] > beyond[3]) << 3));
    let grids = Grids {
        spacing: f32x4::new([1.0, 1.0, sf, sf]),
        first: f32x4::new([sub_lo, 0.0, row0 as f32, 0.0]),
        last: f32x4::new([sub_hi, cols as f32 - 1.0, (row0 + rows) as f32 - 1.0, view.width as f32 - 1.0]),
    };
    for (t, &corners) in p.triangles.iter().enumerate() {
        if corners.iter().fold(u8::MAX, |out, &k| out & band.outside[k as usize]) != 0 {
            continue;
        }
        let [a, b, c] = corners.map(|k| p.screen[k as usize]);
        let ([row_lo, col_lo, centre_row_lo, centre_col_lo], [row_hi, col_hi, centre_row_hi, centre_col_hi]) = grids.spans([a, b, c]);
        // The two grids are tested independently: a sliver can hold pixel
        // centres between two rows (or columns) of subsamples, or the reverse.
        let subsamples = row_lo <= row_hi && col_lo <= col_hi;
        let centres = centre_row_lo <= centre_row_hi && centre_col_lo <= centre_col_hi;
        if !(subsamples || centres) {
            continue;
        }
        let Some(setup) = TriangleSetup::new(a, b, c) else { continue };
        corners.iter().for_each(|&k| band.scanned[k as usize] = true);
        if subsamples {
            let [ta, tb, tc] = corners.map(|k| p.uv[k as usize]);
            let texcoords = |lb: L, lc: L| {
                let la = L::splat(1.0) - lb - lc;
                let splat = L::splat;
                std::array::from_fn(|k| la * splat(ta[k]) + lb * splat(tb[k]) + lc * splat(tc[k]))
            };
            let (rows, columns) = ((row_lo as usize, row_hi as usize), (col_lo as usize, col_hi as usize));
            scan_box(&setup, rows, columns, 1.0, row0 * s, &mut band.subsamples, t as u32, z_max, texcoords);
        }
        if centres {
            let (rows, columns) = ((centre_row_lo as usize, centre_row_hi as usize), (centre_col_lo as usize, centre_col_hi as usize));
            scan_box(&setup, rows, columns, sf, row0, &mut band.centres, t as u32, z_max, |lb: L, lc: L| [lb, lc]);
        }
    }
}

/// The two sample grids of a band, as lanes [subsample row, subsample
/// column, centre row, centre column]: sample spacing (in subsamples) and
/// the first and last sample index of the band.
struct Grids {
    spacing: f32x4,
    first: f32x4,
    last: f32x4,
}

impl Grids {
    /// The first and last sample index, in each lane, that the bounding box
    /// of a triangle (in subsample space) covers (none where the first is
    /// past the last). Sample k (spacing d) sits at (k + ½)d; a small margin
    /// absorbs rounding, and `TriangleSetup::hit` decides exactly.
    #[inline(always)]
    fn spans(&self, [a, b, c]: [[f32; 3]; 3]) -> ([i32; LANES], [i32; LANES]) {
        // Plain comparisons: the coordinates are finite (`check_mesh`).
        let (min, max) = (|p: f32, q: f32| if p < q { p } else { q }, |p: f32, q: f32| if p > q { p } else { q });
        let (x_lo, x_hi) = (min(min(a[0], b[0]), c[0]), max(max(a[0], b[0]), c[0]));
        let (y_lo, y_hi) = (min(min(a[1], b[1]), c[1]), max(max(a[1], b[1]), c[1]));
        let (half, margin) = (f32x4::splat(0.5), f32x4::splat(MARGIN));
        let lo = f32x4::new([y_lo, x_lo, y_lo, x_lo]) / self.spacing - half - margin;
        let hi = f32x4::new([y_hi, x_hi, y_hi, x_hi]) / self.spacing - half + margin;
        // Clamped to one sample beyond the band: the same spans, in the range
        // where truncation to i32 is exact, so ceil and floor are too.
        let (below, above) = (self.first - f32x4::ONE, self.last + f32x4::ONE);
        let (lo, hi) = (lo.fast_max(below).fast_min(above), hi.fast_max(below).fast_min(above));
        (ceil4(lo).fast_max(self.first).fast_trunc_int().to_array(), floor4(hi).fast_min(self.last).fast_trunc_int().to_array())
    }
}

/// Floor of four values by truncation, exact for |x| < 2³¹ (the baseline
/// x86-64 target has no rounding instruction).
#[inline(always)]
fn floor4(x: f32x4) -> f32x4 {
    let t = f32x4::from_i32x4(x.fast_trunc_int());
    t.simd_gt(x).bitselect(t - f32x4::ONE, t)
}

/// Ceiling of four values by truncation, exact for |x| < 2³¹.
#[inline(always)]
fn ceil4(x: f32x4) -> f32x4 {
    let t = f32x4::from_i32x4(x.fast_trunc_int());
    t.simd_lt(x).bitselect(t + f32x4::ONE, t)
}

/// Test the samples `rows` × `columns` (inclusive) of the grid of spacing
/// `spacing` against triangle `t`, two rows of `HALF` columns at a time
/// (lanes), and keep its hits where highest; `samples` holds the grid's rows
/// from `first_row`. `attribute(λb, λc)` is the attribute of a hit.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn scan_box<L: Lanes8>(
    setup: &TriangleSetup,
    rows: (usize, usize),
    columns: (usize, usize),
    spacing: f32,
    first_row: usize,
    samples: &mut Samples,
    t: u32,
    z_max: f32,
    attribute: impl Fn(L, L) -> [L; 2],
) {
    // Lane l tests column l % HALF of a group, in the upper row of the pair
    // for l < HALF, in the lower for the others.
    let column = L::new(std::array::from_fn(|l| (l % HALF) as f32));
    let (half, spacing_lanes) = (L::splat(0.5), L::splat(spacing));
    let groups = (columns.1 - columns.0) / HALF + 1;
    for r in (rows.0..=rows.1).step_by(2) {
        // Sample k sits at (k + ½)·spacing: exact in f32 for k < 2²³, as it
        // is for the ray caster, whose arithmetic `hits` repeats lane by lane.
        let [upper, lower] = [r, r + 1].map(|r| setup.row((r as u32 as f32 + 0.5) * spacing));
        let row = [0, 1, 2].map(|k| L::halves(upper[k], lower[k]));
        // Past the box's last row the lower row holds no lane inside and is
        // written back unchanged (the padding row, below the grid's last).
        let rows_in = L::halves(r as u32 as f32, (r + 1) as u32 as f32).simd_le(L::splat(rows.1 as u32 as f32));
        let mut pair = samples.row_pair(r - first_row, columns.0, groups);
        for g in 0..groups {
            let group = pair.group(g);
            let col = columns.0 + g * HALF;
            let px = (L::splat(col as u32 as f32) + column + half) * spacing_lanes;
            let (inside, z, lb, lc) = setup.hits(row, px);
            let in_box = column.simd_le(L::splat((columns.1 - col) as u32 as f32)) & rows_in;
            group.keep(t, inside & in_box, z, z_max, || attribute(lb, lc));
        }
    }
}

/// Lights with directional vectors normalised once.
fn prepared_lights(lights: &[Light]) -> Vec<Light> {
    lights.iter().map(|l| if l.kind == LightKind::Directional { Light { vector: normalize(l.vector), ..*l } } else { *l }).collect()
}

/// Phong terms at a point `p` with unit normal `n` (facing the camera) seen
/// from unit direction `v` (`View::toward_camera`):
/// `(k_a + Σ I_l k_d max(0, n·l), Σ I_l k_s max(0, r·v)^α)`, so that the
/// intensity is `albedo · first + second`. `min_rdv`: (r·v)^α below
/// SPECULAR_FLOOR is dropped, which skips the power for most points.
#[inline(always)]
fn lighting(n: [f32; 3], p: [f32; 3], v: [f32; 3], lights: &[Light], m: &Material, min_rdv: f32) -> (f32, f32) {
    let (mut diffuse, mut specular) = (m.ambient, 0.0);
    let ndv = dot(n, v);
    for light in lights {
        let l = match light.kind {
            LightKind::Directional => light.vector,
            LightKind::Point => normalize([light.vector[0] - p[0], light.vector[1] - p[1], light.vector[2] - p[2]]),
        };
        let ndl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
        if ndl <= 0.0 {
            continue;
        }
        diffuse += light.intensity * m.diffuse * ndl;
        let rdv = 2.0 * ndl * ndv - dot(l, v);
        if rdv > min_rdv && m.specular > 0.0 {
            specular += light.intensity * m.specular * pow4(f32x4::splat(rdv), m.shininess).to_array()[0];
        }
    }
    (diffuse, specular)
}

fn specular_cutoff(m: &Material) -> f32 {
    pow4(f32x4::splat(SPECULAR_FLOOR), 1.0 / m.shininess.max(1e-3)).to_array()[0]
}

/// `x^α` in four lanes, for x > 0: `2^(α log₂ x)`, both with polynomials
/// in plain f32 operations (no libm, no fused multiply-add), so the same
/// bits on every platform and whichever lane a value sits in. Relative
/// error below 2e-7 + 1.5e-7·|α log₂ x| (tested against f64); `α log₂ x`
/// is clamped to [−126, 127], x below f32::MIN_POSITIVE taken as it.
#[inline(always)]
pub(crate) fn pow4(x: f32x4, alpha: f32) -> f32x4 {
    let splat = f32x4::splat;
    // log₂ x = e + ln(m)/ln 2 with x = m·2^e, m in [√½, √2):
    // ln m = 2 atanh s, s = (m − 1)/(m + 1), |s| < 0.172.
    let bits: u32x4 = wide::bytemuck::cast(x.fast_max(splat(f32::MIN_POSITIVE)));
    let m: f32x4 = wide::bytemuck::cast((bits & u32x4::splat(0x007f_ffff)) | u32x4::splat(0x3f80_0000));
    let e = f32x4::from_i32x4(wide::bytemuck::cast::<u32x4, i32x4>(bits >> 23) - i32x4::splat(127));
    let high = m.simd_gt(splat(std::f32::consts::SQRT_2));
    let (m, e) = (high.bitselect(m * splat(0.5), m), high.bitselect(e + f32x4::ONE, e));
    let s = (m - f32x4::ONE) / (m + f32x4::ONE);
    let s2 = s * s;
    let ln_m = s * (splat(2.0) + s2 * (splat(2.0 / 3.0) + s2 * (splat(2.0 / 5.0) + s2 * (splat(2.0 / 7.0) + s2 * splat(2.0 / 9.0)))));
    let y = (splat(alpha) * (e + ln_m * splat(std::f32::consts::LOG2_E))).fast_max(splat(-126.0)).fast_min(splat(127.0));
    // 2^y = 2^k · e^(f ln 2), k = y rounded, |f| <= ½.
    let k = floor4(y + splat(0.5));
    let t = (y - k) * splat(std::f32::consts::LN_2);
    let exp_t = f32x4::ONE + t * (f32x4::ONE + t * (splat(1.0 / 2.0) + t * (splat(1.0 / 6.0) + t * (splat(1.0 / 24.0) + t * (splat(1.0 / 120.0) + t * splat(1.0 / 720.0))))));
    let scale: f32x4 = wide::bytemuck::cast((k.fast_trunc_int() + i32x4::splat(127)) << 23);
    exp_t * scale
}

/// `a·b`; with b = (0, 0, 1) exactly `a[2]` (adding ±0 is exact), so the
/// orthographic camera's shading keeps its bits.
#[inline(always)]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `n`, flipped to face the camera seen along `v` (lighting is two-sided).
#[inline(always)]
fn facing_camera(n: [f32; 3], v: [f32; 3]) -> [f32; 3] {
    if dot(n, v) < 0.0 {
        [-n[0], -n[1], -n[2]]
    } else {
        n
    }
}

/// Gouraud: the Phong terms of every vertex, for `Shading::Gouraud`; with
/// `wanted`, only at the vertices it flags (0 elsewhere).
pub fn vertex_lighting(vertices: &[[f32; 3]], normals: &[[f32; 3]], wanted: Option<&[bool]>, scene: &Scene, lit: &mut Vec<[f32; 2]>) {
    let lights = prepared_lights(scene.lights);
    let min_rdv = specular_cutoff(&scene.material);
    lit.clear();
    lit.extend(vertices.iter().zip(normals).enumerate().map(|(k, (&p, &n))| {
        if !wanted.is_none_or(|w| w[k]) {
            return [0.0; 2];
        }
        let v = scene.view.toward_camera(p);
        let (d, s) = lighting(facing_camera(n, v), p, v, &lights, &scene.material, min_rdv);
        [d, s]
    }));
}

/// Shade the pixels of a band. Albedo is sampled at every covered subsample;
/// the light terms are evaluated once per pixel, at its centre (or at its
/// first covered subsample where the centre is background), as a
/// multisampling renderer does: lighting varies over a triangle far more
/// slowly than a texture does.
#[inline(always)]
fn shade_pass(p: &Prepared, row0: usize, band: &mut Band, image: &mut [f32], coverage: &mut [f32]) {
    let scene = p.scene;
    let s = scene.supersample;
    let (width, cols) = (scene.view.width, scene.view.width * s);
    let per_pixel = 1.0 / (s * s) as f32;
    let lights = prepared_lights(scene.lights);
    let min_rdv = specular_cutoff(&scene.material);
    let point_lights = lights.iter().any(|l| l.kind == LightKind::Point);
    let perspective = scene.view.pinhole.is_some();
    let (subsamples, centres, texels, covered) = (&band.subsamples, &band.centres, &mut band.texels, &mut band.covered);
    texels.resize(cols.next_multiple_of(LANES), 0.0);
    covered.resize(texels.len(), 0.0);
    let [u, v] = &subsamples.attribute;
    let sampler = scene.texture.sampler();
    for (pi, (albedo, hits)) in image.chunks_exact_mut(width).zip(coverage.chunks_exact_mut(width)).enumerate() {
        // Albedo summed over each pixel's covered subsamples, row by row
        // (`hits` counts them), the texture sampled four at a time.
        albedo.fill(0.0);
        hits.fill(0.0);
        for a in 0..s {
            let start = subsamples.index(pi * s + a, 0);
            for (c, (group, flags)) in texels.chunks_exact_mut(LANES).zip(covered.chunks_exact_mut(LANES)).enumerate() {
                let i = start + c * LANES;
                let hit = f32x4::new(lanes(&subsamples.z, i)).simd_gt(f32x4::splat(f32::NEG_INFINITY));
                let albedo = sampler.sample4(f32x4::new(lanes(u, i)), f32x4::new(lanes(v, i)));
                group.copy_from_slice(&hit.bitselect(albedo, f32x4::ZERO).to_array());
                flags.copy_from_slice(&hit.bitselect(f32x4::ONE, f32x4::ZERO).to_array());
            }
            // Branch-free: a background subsample adds +0, which leaves every
            // sum unchanged (sums that start at +0 are never −0). Four
            // pixels at a time, each lane adding its s subsamples in order.
            let whole = width - width % LANES;
            for (g, (albedo, hits)) in albedo[..whole].chunks_exact_mut(LANES).zip(hits[..whole].chunks_exact_mut(LANES)).enumerate() {
                let (texels, covered) = (&texels[g * LANES * s..][..LANES * s], &covered[g * LANES * s..][..LANES * s]);
                let (mut sum, mut count) = (f32x4::new(lanes(albedo, 0)), f32x4::new(lanes(hits, 0)));
                for q in 0..s {
                    let subsample = |values: &[f32]| f32x4::new(std::array::from_fn(|l| values[l * s + q]));
                    sum += subsample(texels);
                    count += subsample(covered);
                }
                albedo.copy_from_slice(&sum.to_array());
                hits.copy_from_slice(&count.to_array());
            }
            for j in whole..width {
                for b in j * s..j * s + s {
                    albedo[j] += texels[b];
                    hits[j] += covered[b];
                }
            }
        }
        // Light terms four pixels at a time where their four centres are hit
        // (every pixel of a training clip), one at a time elsewhere.
        let mut pj = 0;
        while pj < width {
            let k = centres.index(pi, pj);
            if pj + LANES <= width && f32x4::new(lanes(&centres.z, k)).simd_gt(f32x4::splat(f32::NEG_INFINITY)).all() {
                let (diffuse, specular) = lighting4(p, &lights, min_rdv, point_lights, centres, k);
                let (out, cov) = (&mut albedo[pj..pj + LANES], &mut hits[pj..pj + LANES]);
                let (sum, covered) = (f32x4::new(lanes(out, 0)), f32x4::new(lanes(cov, 0)));
                out.copy_from_slice(&((sum * diffuse + covered * specular) * f32x4::splat(per_pixel)).to_array());
                cov.copy_from_slice(&(covered * f32x4::splat(per_pixel)).to_array());
                pj += LANES;
                continue;
            }
            let lit_at = if centres.is_hit(k) {
                Some((centres.triangle[k], [centres.attribute[0][k], centres.attribute[1][k]]))
            } else {
                (0..s * s).map(|q| (pi * s + q / s, pj * s + q % s)).find(|&(row, col)| subsamples.is_hit(subsamples.index(row, col))).map(|(row, col)| {
                    let i = subsamples.index(row, col);
                    // Lit at the first covered subsample, with the visibility pass's own arithmetic: it hits again.
                    let t = subsamples.triangle[i];
                    let [a, b, c] = p.triangles[t as usize].map(|k| p.screen[k as usize]);
                    let hit = TriangleSetup::new(a, b, c).and_then(|setup| setup.hit(col as f32 + 0.5, (row0 * s + row) as f32 + 0.5));
                    (t, hit.map_or([0.0; 2], |(_, l)| [l[1], l[2]]))
                })
            };
            // Background: albedo and coverage stay 0.
            if let Some((t, w)) = lit_at {
                let corners = p.triangles[t as usize];
                let (diffuse, specular) = match scene.shading {
                    Shading::Phong => {
                        // The surface point matters only to point lights and a pinhole.
                        let point = if point_lights || perspective { interpolate(p.vertices, corners, w) } else { [0.0; 3] };
                        let v = scene.view.toward_camera(point);
                        lighting(facing_camera(normalize(interpolate(p.normals, corners, w)), v), point, v, &lights, &scene.material, min_rdv)
                    }
                    Shading::Gouraud => {
                        let [diffuse, specular] = interpolate(p.lit, corners, w);
                        (diffuse, specular)
                    }
                };
                let covered = hits[pj];
                albedo[pj] = (albedo[pj] * diffuse + covered * specular) * per_pixel;
                hits[pj] = covered * per_pixel;
            }
            pj += 1;
        }
    }
}

/// The light terms `(diffuse, specular)` at the four hit pixel centres `k ..
/// k + LANES`: the scalar path's arithmetic lane by lane (the same IEEE
/// operations in the same order, so the same bits); a light's power is
/// computed, in all four lanes, only where some lane's specular term survives.
#[inline(always)]
fn lighting4(p: &Prepared, lights: &[Light], min_rdv: f32, point_lights: bool, centres: &Samples, k: usize) -> (f32x4, f32x4) {
    let corners = lanes(&centres.triangle, k).map(|t| p.triangles[t as usize]);
    let [w1, w2] = centres.attribute.each_ref().map(|a| f32x4::new(lanes(a, k)));
    let m = &p.scene.material;
    if p.scene.shading == Shading::Gouraud {
        let [diffuse, specular] = interpolate4(p.lit, &corners, w1, w2);
        return (diffuse, specular);
    }
    let splat = f32x4::splat;
    // `normalize`, then `facing_camera`.
    let unit = |v: [f32x4; 3]| {
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let positive = len.simd_gt(f32x4::ZERO);
        [positive.bitselect(v[0] / len, f32x4::ZERO), positive.bitselect(v[1] / len, f32x4::ZERO), positive.bitselect(v[2] / len, f32x4::ONE)]
    };
    let n = unit(interpolate4(p.normals, &corners, w1, w2));
    let view = &p.scene.view;
    let point = if point_lights || view.pinhole.is_some() { interpolate4(p.vertices, &corners, w1, w2) } else { [f32x4::ZERO; 3] };
    // `View::toward_camera` lane by lane.
    let v = match view.pinhole {
        None => [f32x4::ZERO, f32x4::ZERO, f32x4::ONE],
        Some([px, py]) => {
            let d = [splat(px) - point[0], splat(py) - point[1], splat(view.camera_z) - point[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            d.map(|c| c / len)
        }
    };
    let dot4 = |a: &[f32x4; 3], b: &[f32x4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let away = dot4(&n, &v).simd_lt(f32x4::ZERO);
    let n = n.map(|c| away.bitselect(-c, c));
    let ndv = dot4(&n, &v);
    let (mut diffuse, mut specular) = (splat(m.ambient), f32x4::ZERO);
    for light in lights {
        let l = match light.kind {
            LightKind::Directional => light.vector.map(splat),
            LightKind::Point => unit([0, 1, 2].map(|c| splat(light.vector[c]) - point[c])),
        };
        let ndl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
        // `lighting` skips a light where n·l <= 0 (and only there: NaN goes on).
        let unlit = ndl.simd_le(f32x4::ZERO);
        diffuse = unlit.bitselect(diffuse, diffuse + splat(light.intensity * m.diffuse) * ndl);
        if m.specular > 0.0 {
            let rdv = splat(2.0) * ndl * ndv - dot4(&l, &v);
            let shiny = rdv.simd_gt(splat(min_rdv)) & !unlit;
            if shiny.any() {
                specular = shiny.bitselect(specular + splat(light.intensity * m.specular) * pow4(rdv, m.shininess), specular);
            }
        }
    }
    (diffuse, specular)
}

/// [`interpolate`] in four lanes, each with its own triangle.
#[inline(always)]
fn interpolate4<const N: usize>(attribute: &[[f32; N]], corners: &[[u32; 3]; LANES], w1: f32x4, w2: f32x4) -> [f32x4; N] {
    let w0 = f32x4::ONE - w1 - w2;
    let corner = |q: usize| corners.map(|c| attribute[c[q] as usize]);
    let (a, b, c) = (corner(0), corner(1), corner(2));
    let lane = |v: &[[f32; N]; LANES], i: usize| f32x4::new(v.map(|v| v[i]));
    std::array::from_fn(|i| w0 * lane(&a, i) + w1 * lane(&b, i) + w2 * lane(&c, i))
}

/// A vertex attribute at barycentric weights (λb, λc) of triangle `corners`.
#[inline(always)]
fn interpolate<const N: usize>(attribute: &[[f32; N]], corners: [u32; 3], [w1, w2]: [f32; 2]) -> [f32; N] {
    let w0 = 1.0 - w1 - w2;
    let [a, b, c] = corners.map(|k| attribute[k as usize]);
    std::array::from_fn(|k| w0 * a[k] + w1 * b[k] + w2 * c[k])
}

#[inline(always)]
fn normalize(v: [f32; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 {
        [v[0] / len, v[1] / len, v[2] / len]
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// Validate everything a render reads.
pub fn check_render_inputs(vertices: &[[f32; 3]], triangles: &[[u32; 3]], uv: &[[f32; 2]], scene: &Scene) -> Result<()> {
    check_mesh(vertices, triangles)?;
    scene.view.check_in_front(vertices)?;
    if uv.len() != vertices.len() {
        return Err(InvalidArgument::new("uv", format!("expected one (u, v) per vertex: {} rows, got {}", vertices.len(), uv.len())));
    }
    if !uv.iter().all(|p| p[0].is_finite() && p[1].is_finite()) {
        return Err(InvalidArgument::new("uv", "expected finite texture coordinates"));
    }
    if !(1..=MAX_SUPERSAMPLE).contains(&scene.supersample) {
        return Err(InvalidArgument::new("supersample", format!("expected 1..={MAX_SUPERSAMPLE}, got {}", scene.supersample)));
    }
    let samples = scene.view.height * scene.view.width * scene.supersample * scene.supersample;
    if samples > MAX_SAMPLES {
        return Err(InvalidArgument::new(
            "size",
            format!("{}×{} pixels × {}² subsamples = {samples} samples exceed {MAX_SAMPLES} (their buffers would need {} GiB); lower size or supersample", scene.view.height, scene.view.width, scene.supersample, samples * 16 >> 30),
        ));
    }
    if scene.texture.height == 0 || scene.texture.width == 0 {
        return Err(InvalidArgument::new("texture", "expected a non-empty image (Texture::new), got an empty one"));
    }
    scene.material.validate()?;
    check_lights(scene.lights)
}

/// Render one frame, row bands in parallel (rayon).
pub fn render(vertices: &[[f32; 3]], triangles: &[[u32; 3]], uv: &[[f32; 2]], scene: &Scene) -> Result<Frame> {
    check_render_inputs(vertices, triangles, uv, scene)?;
    let s = scene.supersample;
    let (height, width) = (scene.view.height, scene.view.width);
    let mut normals = Vec::new();
    vertex_normals(vertices, triangles, None, &mut normals);
    let screen: Vec<[f32; 3]> = vertices.iter().map(|&v| scene.view.pixel_vertex(v, s as f32)).collect();
    let mut lit = Vec::new();
    if scene.shading == Shading::Gouraud {
        vertex_lighting(vertices, &normals, None, scene, &mut lit);
    }
    let prepared = Prepared { vertices, triangles, uv, normals: &normals, lit: &lit, screen: &screen, scene };
    let mut frame = Frame { image: vec![0.0; height * width], coverage: vec![0.0; height * width], depth: vec![0.0; height * width] };
    // Bands of whole pixel rows, sized to give every thread work.
    let band = height.div_ceil(4 * rayon::current_num_threads()).max(1) * width;
    frame
        .image
        .par_chunks_mut(band)
        .zip(frame.coverage.par_chunks_mut(band))
        .zip(frame.depth.par_chunks_mut(band))
        .enumerate()
        .for_each_init(Band::default, |buffers, (k, ((image, coverage), depth))| render_band(&prepared, k * band / width, buffers, image, coverage, depth));
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::raycast_depth;
    use crate::geometry::CAMERA_Z;
    use crate::lanes::tests::both_builds;
    use crate::mesh::grid_triangles;
    use crate::params::SurfaceConfig;
    use crate::synthesis::synthesize;

    fn white(n: usize) -> Texture {
        Texture::new(n, n, &vec![1.0; n * n]).unwrap()
    }

    fn matte() -> Material {
        Material { ambient: 0.0, diffuse: 1.0, specular: 0.0, shininess: 1.0 }
    }

    fn grid_mesh(seed: u64, grid: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 2]>) {
        let params = SurfaceConfig::default().sample(seed).unwrap();
        let flat = synthesize(&params, 1, grid).unwrap();
        let vertices: Vec<[f32; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let triangles: Vec<[u32; 3]> = grid_triangles(grid as i64).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let uv = (0..grid * grid).map(|i| [(i % grid) as f32 / (grid - 1) as f32, 1.0 - (i / grid) as f32 / (grid - 1) as f32]).collect();
        (vertices, triangles, uv)
    }

    #[test]
    fn zbuffer_equals_ray_cast_depth_at_pixel_centres() {
        for seed in 0..6 {
            let (vertices, triangles, uv) = grid_mesh(seed, 40);
            let view = View::new(48, 40, [-0.55, -0.6, 0.5, 0.45], CAMERA_Z).unwrap();
            let cast = raycast_depth(&vertices, &triangles, &view).unwrap();
            let texture = white(4);
            for s in [1usize, 2, 3, 4] {
                let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
                let scene = Scene { view, supersample: s, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
                let frame = render(&vertices, &triangles, &uv, &scene).unwrap();
                for (k, (&z, &d)) in frame.depth.iter().zip(&cast).enumerate() {
                    // Scaling the vertices by a power of two is exact; by 3 it rounds.
                    let tolerance = if s.is_power_of_two() { 0.0 } else { 1e-5 };
                    assert!((z - d).abs() <= tolerance || (z.is_nan() && d.is_nan()), "seed {seed} s {s} pixel {k}: {z} vs {d}");
                }
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Random soups are full of slivers, which can hold pixel centres and
        /// no subsample or the reverse: the depth must still be the ray caster's.
        #[test]
        fn depth_equals_the_ray_casters_on_random_soups(
            // Some corners far outside the view: bounding boxes far beyond
            // every band edge, and slivers whose edge tests round.
            coords in proptest::collection::vec(proptest::prop_oneof![19 => -1.0f32..1.0, 1 => -1e7f32..1e7], 9..300),
            (h, w) in (1usize..24, 1usize..24),
            log_s in 0u32..4,
        ) {
            let vertices: Vec<[f32; 3]> = coords.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let triangles: Vec<[u32; 3]> = (0..vertices.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
            let uv = vec![[0.5f32; 2]; vertices.len()];
            let view = View::new(h, w, [-0.9, -1.0, 1.0, 0.8], CAMERA_Z).unwrap();
            let cast = raycast_depth(&vertices, &triangles, &view).unwrap();
            let (texture, lights) = (white(2), [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }]);
            let scene = Scene { view, supersample: 1 << log_s, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
            let frame = render(&vertices, &triangles, &uv, &scene).unwrap();
            for (k, (z, d)) in frame.depth.iter().zip(&cast).enumerate() {
                proptest::prop_assert!(z.to_bits() == d.to_bits() || (z.is_nan() && d.is_nan()), "pixel {}: {} vs {}", k, z, d);
            }
        }

        /// The subsample z-buffer against brute force: every subsample tested
        /// against every triangle, the highest hit kept (the first of equal
        /// ones), its texture coordinates interpolated and the texture
        /// sampled. Ambient light only, so the image is the mean albedo of the
        /// covered subsamples: image and coverage must agree bit for bit.
        #[test]
        fn image_and_coverage_equal_a_brute_force_z_buffer_on_random_soups(
            coords in proptest::collection::vec(-1.0f32..1.0, 9..150),
            texcoords in proptest::collection::vec(0.0f32..1.0, 200),
            (h, w) in (1usize..16, 1usize..16),
            s in 1usize..4,
        ) {
            let vertices: Vec<[f32; 3]> = coords.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let triangles: Vec<[u32; 3]> = (0..vertices.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
            let uv: Vec<[f32; 2]> = (0..vertices.len()).map(|k| [texcoords[2 * k], texcoords[2 * k + 1]]).collect();
            let texture = Texture::new(5, 7, &(0..35).map(|i| ((i * 13) % 35) as f32 / 35.0).collect::<Vec<f32>>()).unwrap();
            // Triangles reach past every side of the view: rows end inside them.
            let view = View::new(h, w, [-0.7, -0.8, 0.8, 0.6], CAMERA_Z).unwrap();
            let ambient = Material { ambient: 1.0, diffuse: 0.0, specular: 0.0, shininess: 1.0 };
            let scene = Scene { view, supersample: s, lights: &[], material: ambient, texture: &texture, shading: Shading::Phong };
            let frame = render(&vertices, &triangles, &uv, &scene).unwrap();
            let screen: Vec<[f32; 3]> = vertices.iter().map(|&v| view.pixel_vertex(v, s as f32)).collect();
            let per_pixel = 1.0 / (s * s) as f32;
            for k in 0..h * w {
                let (mut albedo, mut hits) = (0.0f32, 0.0f32);
                for (a, b) in (0..s * s).map(|q| (q / s, q % s)) {
                    let (px, py) = (((k % w) * s + b) as f32 + 0.5, ((k / w) * s + a) as f32 + 0.5);
                    let mut best: Option<(f32, usize, [f32; 3])> = None;
                    for (t, corners) in triangles.iter().enumerate() {
                        let [p, q, r] = corners.map(|c| screen[c as usize]);
                        if let Some((z, l)) = crate::geometry::vertical_hit(p, q, r, px, py) {
                            if z <= CAMERA_Z && best.is_none_or(|(top, _, _)| z > top) {
                                best = Some((z, t, l));
                            }
                        }
                    }
                    if let Some((_, t, l)) = best {
                        let [u, v] = interpolate(&uv, triangles[t], [l[1], l[2]]);
                        albedo += texture.sample(u, v);
                        hits += 1.0;
                    }
                }
                proptest::prop_assert_eq!(frame.coverage[k].to_bits(), (hits * per_pixel).to_bits(), "coverage of pixel {}", k);
                proptest::prop_assert_eq!(frame.image[k].to_bits(), ((albedo * 1.0 + hits * 0.0) * per_pixel).to_bits(), "image of pixel {}", k);
            }
        }
    }

    fn plane(normal_tilt: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 2]>) {
        // A square tilted about the y axis by `normal_tilt` radians.
        let (c, s) = (normal_tilt.cos(), normal_tilt.sin());
        let corners = [[-1.0f32, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        let vertices = corners.iter().map(|p| [p[0] * c, p[1], -p[0] * s]).collect();
        let uv = corners.iter().map(|p| [(p[0] + 1.0) / 2.0, (1.0 - p[1]) / 2.0]).collect();
        (vertices, vec![[0, 1, 2], [0, 2, 3]], uv)
    }

    fn mean(v: &[f32]) -> f32 {
        v.iter().sum::<f32>() / v.len() as f32
    }

    #[test]
    fn a_face_toward_the_light_is_brighter_than_a_tilted_one() {
        let view = View::new(8, 8, [-0.3, -0.3, 0.3, 0.3], CAMERA_Z).unwrap();
        let texture = white(2);
        let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
        let scene = Scene { view, supersample: 2, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
        let brightness = |tilt: f32| {
            let (v, t, uv) = plane(tilt);
            mean(&render(&v, &t, &uv, &scene).unwrap().image)
        };
        let (flat, tilted) = (brightness(0.0), brightness(0.6));
        assert!((flat - 1.0).abs() < 1e-5);
        assert!((tilted - 0.6f32.cos()).abs() < 1e-4, "Lambert: {tilted}");
    }

    #[test]
    fn the_specular_highlight_sits_where_the_mirror_direction_meets_the_view() {
        // A sphere cap lit from direction l: the highlight is at the normal
        // halfway between l and the view v = +z.
        let (grid, r) = (81usize, 1.0f32);
        let mut vertices = Vec::new();
        let mut uv = Vec::new();
        for jy in 0..grid {
            for jx in 0..grid {
                let (x, y) = (-0.7 + 1.4 * jx as f32 / 80.0, -0.7 + 1.4 * jy as f32 / 80.0);
                vertices.push([x, y, (r * r - x * x - y * y).sqrt()]);
                uv.push([0.5, 0.5]);
            }
        }
        let triangles: Vec<[u32; 3]> = grid_triangles(grid as i64).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let l = normalize([0.5, 0.3, 1.0]);
        let h = normalize([l[0], l[1], l[2] + 1.0]);
        let view = View::new(96, 96, [-0.6, -0.6, 0.6, 0.6], 5.0).unwrap();
        let texture = white(2);
        let lights = [Light { kind: LightKind::Directional, vector: l, intensity: 1.0 }];
        let material = Material { ambient: 0.0, diffuse: 0.0, specular: 1.0, shininess: 200.0 };
        let scene = Scene { view, supersample: 1, lights: &lights, material, texture: &texture, shading: Shading::Phong };
        let frame = render(&vertices, &triangles, &uv, &scene).unwrap();
        let peak = (0..frame.image.len()).max_by(|&a, &b| frame.image[a].total_cmp(&frame.image[b])).unwrap();
        let (x, y) = view.world((peak / 96) as f32 + 0.5, (peak % 96) as f32 + 0.5);
        // On a unit sphere the point with normal h is at (h.x, h.y).
        let err = ((x - h[0]).powi(2) + (y - h[1]).powi(2)).sqrt();
        assert!(err < 0.03, "highlight at ({x}, {y}), expected ({}, {})", h[0], h[1]);
        assert!(frame.image[peak] > 0.95);
    }

    #[test]
    fn albedo_is_the_mean_texture_over_the_subsamples() {
        // Flat plane facing a light along +z, diffuse only: intensity = albedo.
        let (v, t, uv) = plane(0.0);
        let data: Vec<f32> = (0..32 * 32).map(|i| ((i % 32) as f32 * 0.7 + (i / 32) as f32 * 0.3) / 32.0).collect();
        let texture = Texture::new(32, 32, &data).unwrap();
        let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
        let view = View::new(10, 12, [-0.7, -0.6, 0.5, 0.8], CAMERA_Z).unwrap();
        for s in [1usize, 2, 3] {
            let scene = Scene { view, supersample: s, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
            let image = render(&v, &t, &uv, &scene).unwrap().image;
            for i in 0..10 {
                for j in 0..12 {
                    let mut expected = 0.0;
                    for (a, b) in (0..s * s).map(|k| (k / s, k % s)) {
                        let (x, y) = view.world(i as f32 + (a as f32 + 0.5) / s as f32, j as f32 + (b as f32 + 0.5) / s as f32);
                        expected += texture.sample((x + 1.0) / 2.0, (1.0 - y) / 2.0) / (s * s) as f32;
                    }
                    assert!((image[i * 12 + j] - expected).abs() < 1e-5, "s {s} ({i},{j}): {} vs {expected}", image[i * 12 + j]);
                }
            }
        }
    }

    #[test]
    fn four_lane_texture_samples_equal_the_scalar_ones_bit_for_bit() {
        // Single rows and columns too: there the repeated edge is every footprint's second texel.
        for (height, width) in [(7, 13), (1, 5), (4, 1), (1, 1)] {
            let n = height * width;
            let texture = Texture::new(height, width, &(0..n).map(|i| ((i * 37) % n) as f32 / n as f32 - 0.2).collect::<Vec<f32>>()).unwrap();
            let mut rng = crate::rng::SplitMix64::new(4);
            for _ in 0..2000 {
                // Inside, on and beyond the edges (clamped).
                let (u, v): ([f32; 4], [f32; 4]) = (std::array::from_fn(|_| rng.uniform(-0.3, 1.3) as f32), std::array::from_fn(|_| rng.uniform(-0.3, 1.3) as f32));
                let lanes = texture.sample4(f32x4::new(u), f32x4::new(v)).to_array();
                for k in 0..4 {
                    assert_eq!(lanes[k].to_bits(), texture.sample(u[k], v[k]).to_bits(), "{height}×{width} at ({}, {})", u[k], v[k]);
                }
            }
        }
    }

    #[test]
    fn texture_moves_with_the_surface() {
        // Shift the mesh by one pixel: the image shifts by one pixel.
        let (mut v, t, uv) = plane(0.0);
        let data: Vec<f32> = (0..64 * 64).map(|i| ((i % 64) as f32 / 63.0 + (i / 64) as f32 / 90.0).fract()).collect();
        let texture = Texture::new(64, 64, &data).unwrap();
        let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
        let view = View::new(16, 16, [-0.5, -0.5, 0.5, 0.5], CAMERA_Z).unwrap();
        let scene = Scene { view, supersample: 2, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
        let a = render(&v, &t, &uv, &scene).unwrap().image;
        v.iter_mut().for_each(|p| p[0] += 1.0 / 16.0);
        let b = render(&v, &t, &uv, &scene).unwrap().image;
        for i in 0..16 {
            for j in 1..16 {
                assert!((b[i * 16 + j] - a[i * 16 + j - 1]).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn gouraud_is_phong_on_a_plane_and_close_on_a_smooth_surface() {
        let texture = Texture::new(16, 16, &(0..256).map(|i| (i % 7) as f32 / 7.0).collect::<Vec<f32>>()).unwrap();
        let lights = [Light { kind: LightKind::Directional, vector: [0.3, -0.2, 1.0], intensity: 0.9 }];
        let material = Material { ambient: 0.1, diffuse: 0.8, specular: 0.3, shininess: 10.0 };
        let view = View::new(32, 32, [-0.5, -0.5, 0.5, 0.5], CAMERA_Z).unwrap();
        let phong = Scene { view, supersample: 2, lights: &lights, material, texture: &texture, shading: Shading::Phong };
        let gouraud = Scene { shading: Shading::Gouraud, ..phong.clone() };
        let (v, t, uv) = plane(0.3);
        let (a, b) = (render(&v, &t, &uv, &phong).unwrap().image, render(&v, &t, &uv, &gouraud).unwrap().image);
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5));
        let (v, t, uv) = grid_mesh(2, 64);
        let (a, b) = (render(&v, &t, &uv, &phong).unwrap().image, render(&v, &t, &uv, &gouraud).unwrap().image);
        let mean_diff = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32;
        assert!(mean_diff < 0.01 && mean_diff > 0.0, "{mean_diff}");
    }

    #[test]
    fn four_lane_floor_and_ceil_equal_std() {
        let mut rng = crate::rng::SplitMix64::new(5);
        for _ in 0..5000 {
            // Integers, halves and arbitrary values, up to 2^30 either side.
            let x: [f32; 4] = std::array::from_fn(|k| {
                let v = rng.uniform(-1.0, 1.0) * 2f64.powi((rng.next_u64() % 31) as i32);
                [v, v.round(), v.round() + 0.5, -0.0][k] as f32
            });
            let (floor, ceil) = (floor4(f32x4::new(x)).to_array(), ceil4(f32x4::new(x)).to_array());
            for k in 0..4 {
                assert_eq!((floor[k], ceil[k]), (x[k].floor(), x[k].ceil()), "{}", x[k]);
            }
        }
    }

    #[test]
    fn pow4_is_the_power_to_its_stated_accuracy() {
        let mut rng = crate::rng::SplitMix64::new(9);
        for _ in 0..20_000 {
            let (x, alpha) = (rng.log_uniform(1e-6, 1.01) as f32, rng.log_uniform(1e-3, 1e4) as f32);
            let exact = (x as f64).powf(alpha as f64);
            let y = alpha as f64 * (x as f64).log2();
            if !(-120.0..120.0).contains(&y) {
                continue;
            }
            let got = pow4(f32x4::splat(x), alpha).to_array()[0] as f64;
            let tolerance = 2e-7 + 1.5e-7 * y.abs();
            assert!((got - exact).abs() <= tolerance * exact, "{x}^{alpha}: {got} against {exact}");
        }
    }

    #[test]
    fn four_pixel_lighting_equals_the_scalar_path_bit_for_bit() {
        let (vertices, triangles, uv) = grid_mesh(3, 12);
        let mut normals = Vec::new();
        vertex_normals(&vertices, &triangles, None, &mut normals);
        // A zero normal and one facing away from the camera take their own branches.
        normals[0] = [0.0; 3];
        normals[5] = [0.3, -0.2, -0.9];
        let lights = [
            Light { kind: LightKind::Directional, vector: [0.3, -0.4, 1.0], intensity: 0.8 },
            Light { kind: LightKind::Point, vector: [0.5, 0.2, 1.5], intensity: 0.6 },
            Light { kind: LightKind::Directional, vector: [-0.6, 0.1, -0.4], intensity: 0.5 },
        ];
        let texture = white(4);
        let mut rng = crate::rng::SplitMix64::new(7);
        let mut centres = Samples::default();
        let n = 256;
        centres.reset(1, n);
        for i in 0..n {
            // Some weights outside the triangle: any plane point must agree.
            let w1 = rng.uniform(-0.2, 1.0) as f32;
            centres.z[i] = 0.0;
            centres.triangle[i] = (rng.next_u64() % triangles.len() as u64) as u32;
            centres.attribute[0][i] = w1;
            centres.attribute[1][i] = rng.uniform(-0.2, 1.0 - w1 as f64) as f32;
        }
        let (mut unlit, mut shiny) = (0, 0);
        // All three lights, and the one from below alone (most points unlit).
        let flat = View::new(8, 8, [-1.0, -1.0, 1.0, 1.0], CAMERA_Z).unwrap();
        // The orthographic camera, and a pinhole whose view direction changes from pixel to pixel.
        for (view, (lights, shading)) in [flat, flat.with_pinhole([0.4, -0.3]).unwrap()].into_iter().flat_map(|v| {
            [(&lights[..], Shading::Phong), (&lights[2..], Shading::Phong), (&lights[..], Shading::Gouraud)].map(|l| (v, l))
        }) {
            let prepared = prepared_lights(lights);
            for shininess in [1.0, 7.5, 80.0] {
                let material = Material { ambient: 0.1, diffuse: 0.7, specular: 0.5, shininess };
                let scene = Scene { view, supersample: 2, lights, material, texture: &texture, shading };
                let mut lit = Vec::new();
                vertex_lighting(&vertices, &normals, None, &scene, &mut lit);
                let p = Prepared { vertices: &vertices, triangles: &triangles, uv: &uv, normals: &normals, lit: &lit, screen: &[], scene: &scene };
                let min_rdv = specular_cutoff(&material);
                for k in (0..n).step_by(LANES) {
                    let (diffuse, specular) = lighting4(&p, &prepared, min_rdv, true, &centres, k);
                    for lane in 0..LANES {
                        let i = k + lane;
                        let (corners, w) = (triangles[centres.triangle[i] as usize], [centres.attribute[0][i], centres.attribute[1][i]]);
                        let expected = match shading {
                            Shading::Phong => {
                                let point = interpolate(&vertices, corners, w);
                                let v = scene.view.toward_camera(point);
                                lighting(facing_camera(normalize(interpolate(&normals, corners, w)), v), point, v, &prepared, &material, min_rdv)
                            }
                            Shading::Gouraud => (interpolate(&lit, corners, w)[0], interpolate(&lit, corners, w)[1]),
                        };
                        let got = (diffuse.to_array()[lane], specular.to_array()[lane]);
                        assert_eq!((got.0.to_bits(), got.1.to_bits()), (expected.0.to_bits(), expected.1.to_bits()), "{shading:?} α {shininess} sample {i}: {got:?} vs {expected:?}");
                        unlit += usize::from(expected.0 == material.ambient);
                        shiny += usize::from(expected.1 > 0.0);
                    }
                }
            }
        }
        assert!(unlit > 0 && shiny > 0, "both light branches exercised: {unlit} unlit, {shiny} with a highlight");
    }

    #[test]
    fn baseline_and_avx2_builds_give_the_same_bits() {
        let (vertices, triangles, uv) = grid_mesh(11, 24);
        let texture = Texture::new(16, 16, &(0..256).map(|i| ((i * 7) % 16) as f32 / 16.0).collect::<Vec<f32>>()).unwrap();
        let lights = [
            Light { kind: LightKind::Directional, vector: [0.3, -0.4, 1.0], intensity: 0.8 },
            Light { kind: LightKind::Point, vector: [0.5, 0.2, 1.5], intensity: 0.6 },
        ];
        let material = Material { ambient: 0.1, diffuse: 0.7, specular: 0.5, shininess: 12.0 };
        for (shading, s) in [(Shading::Phong, 2), (Shading::Gouraud, 3)] {
            let view = View::new(21, 19, [-0.6, -0.5, 0.5, 0.6], CAMERA_Z).unwrap();
            let scene = Scene { view, supersample: s, lights: &lights, material, texture: &texture, shading };
            let bits = |frame: &Frame| [&frame.image, &frame.coverage, &frame.depth].map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>());
            let (baseline, dispatched) = both_builds(|| render(&vertices, &triangles, &uv, &scene).unwrap());
            assert!(baseline.coverage.iter().all(|&c| c == 1.0), "the view lies inside the surface");
            assert_eq!(bits(&baseline), bits(&dispatched), "{shading:?}");
        }
    }

    #[test]
    fn bad_inputs_are_named() {
        let (v, t, uv) = plane(0.0);
        let texture = white(2);
        let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 0.0], intensity: 1.0 }];
        let view = View::new(4, 4, [-0.5, -0.5, 0.5, 0.5], CAMERA_Z).unwrap();
        let scene = Scene { view, supersample: 1, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
        assert_eq!(render(&v, &t, &uv, &scene).unwrap_err().name, "lights[0]");
        let scene = Scene { lights: &[], ..scene };
        assert_eq!(render(&v, &t, &uv[..2], &scene).unwrap_err().name, "uv");
        assert_eq!(render(&v, &[[0, 1, 9]], &uv, &scene).unwrap_err().name, "triangles");
        let scene = Scene { supersample: 0, ..scene };
        assert_eq!(render(&v, &t, &uv, &scene).unwrap_err().name, "supersample");
        let empty = Texture::default();
        assert_eq!(render(&v, &t, &uv, &Scene { supersample: 1, texture: &empty, ..scene.clone() }).unwrap_err().name, "texture");
        for (height, width, texels) in [(0, 2, vec![]), (2, 2, vec![0.5; 3]), (1, 2, vec![0.5, f32::NAN])] {
            assert_eq!(Texture::new(height, width, &texels).unwrap_err().name, "texture", "{height}×{width}");
        }
    }
}
