//! Software rasteriser: orthographic z-buffer, smooth normals, textured Phong.
//!
//! Frames and pixel conventions are `geometry.rs`'s. Two passes, both over row
//! bands of the frame buffer (rayon for a single frame, one band inside the
//! per-clip generator):
//! 1. visibility: every triangle is scanned over the subsamples its bounding
//!    box covers; a subsample keeps the highest hit (largest z ≤ camera_z) with
//!    its triangle and barycentric weights. The per-subsample test is
//!    `geometry::vertical_hit` in pixel space, the ray caster's own, so with one
//!    subsample a pixel the z-buffer equals the ray-cast depth bit for bit (and
//!    the centre subsample of an odd s×s grid to rounding).
//! 2. shading (`Shading::Phong` per subsample, or `Shading::Gouraud` at the
//!    vertices and interpolated): smooth per-vertex normals (area-weighted face normals, flipped
//!    toward the camera: lighting is two-sided), texture coordinates
//!    interpolated, albedo sampled bilinearly (clamp to edge), then Phong:
//!    `I = k_a ρ + Σ_l I_l (k_d ρ max(0, n·l) + k_s max(0, r·v)^α)` with
//!    `v = +z` (orthographic view), `r = 2(n·l)n − l`. Subsamples are averaged
//!    (box filter) into pixels; background subsamples contribute 0 and lower
//!    the pixel's coverage. Specular terms `(r·v)^α` below 1e-4 are dropped.
//!
//! Texture coordinates: u along texture columns, v along rows, both in [0, 1];
//! texel (row, col) has its centre at ((row + ½)/H, (col + ½)/W).

use rayon::prelude::*;

use crate::error::{InvalidArgument, Result};
use crate::geometry::{ceil_fast, check_mesh, floor_fast, TriangleSetup, View};

/// Largest supersampling factor per axis.
pub const MAX_SUPERSAMPLE: usize = 8;
const NO_TRIANGLE: u32 = u32::MAX;
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

/// A grayscale albedo image, row-major, values in [0, 1].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texture {
    pub height: usize,
    pub width: usize,
    pub data: Vec<f32>,
}

impl Texture {
    pub fn validate(&self) -> Result<()> {
        if self.height == 0 || self.width == 0 || self.data.len() != self.height * self.width {
            return Err(InvalidArgument::new("texture", format!("expected a non-empty (H, W) image, got {}×{} with {} values", self.height, self.width, self.data.len())));
        }
        if !self.data.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("texture", "expected finite values"));
        }
        Ok(())
    }

    /// Bilinear sample at (u, v), clamped to the edge.
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        let c = (u * self.width as f32 - 0.5).clamp(0.0, (self.width - 1) as f32);
        let r = (v * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (c0, r0) = (c as usize, r as usize);
        let (c1, r1) = ((c0 + 1).min(self.width - 1), (r0 + 1).min(self.height - 1));
        let (fc, fr) = (c - c0 as f32, r - r0 as f32);
        let row0 = &self.data[r0 * self.width..];
        let row1 = &self.data[r1 * self.width..];
        let top = row0[c0] + (row0[c1] - row0[c0]) * fc;
        let bottom = row1[c0] + (row1[c1] - row1[c0]) * fc;
        top + (bottom - top) * fr
    }
}

/// Where the Phong model is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// At every subsample, with the interpolated normal (per-pixel Phong shading).
    Phong,
    /// At the vertices, interpolated (Gouraud): about twice as fast a render,
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

/// Reusable buffers of one renderer; one per thread.
#[derive(Default)]
pub struct Rasterizer {
    normals: Vec<[f32; 3]>,
    lit: Vec<[f32; 2]>,
    screen: Vec<[f32; 3]>,
    triangle: Vec<u32>,
    z: Vec<f32>,
    weights: Vec<[f32; 2]>,
}

/// What a render produces, per pixel unless noted.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    /// Shaded intensity (H·W), background counted as 0.
    pub image: Vec<f32>,
    /// Fraction of a pixel's subsamples that hit the mesh (H·W).
    pub coverage: Vec<f32>,
    /// Depth `camera_z − z` per subsample (H·s × W·s), NaN for background.
    pub depth: Vec<f32>,
}

impl Rasterizer {
    /// Render `vertices` / `triangles` with texture coordinates `uv` into `frame`.
    /// The caller validates the inputs (`check_render_inputs`).
    pub fn render_into(&mut self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], uv: &[[f32; 2]], scene: &Scene, frame: &mut Frame, want_depth: bool) {
        let s = scene.supersample;
        let (rows, cols) = (scene.view.height * s, scene.view.width * s);
        vertex_normals(vertices, triangles, &mut self.normals);
        self.screen.clear();
        self.screen.extend(vertices.iter().map(|&v| scene.view.pixel_vertex(v, s as f32)));
        self.triangle.clear();
        self.triangle.resize(rows * cols, NO_TRIANGLE);
        self.z.clear();
        self.z.resize(rows * cols, f32::NEG_INFINITY);
        self.weights.clear();
        self.weights.resize(rows * cols, [0.0; 2]);
        visibility_band(&self.screen, triangles, &scene.view, s, 0, &mut self.triangle, &mut self.z, &mut self.weights);
        frame.image.resize(scene.view.height * scene.view.width, 0.0);
        frame.coverage.resize(scene.view.height * scene.view.width, 0.0);
        self.lit.clear();
        if scene.shading == Shading::Gouraud {
            vertex_lighting(vertices, &self.normals, scene, &mut self.lit);
        }
        shade_band(vertices, triangles, uv, &self.normals, &self.lit, scene, &self.triangle, &self.weights, &mut frame.image, &mut frame.coverage);
        if want_depth {
            frame.depth.clear();
            frame.depth.extend(self.z.iter().map(|&z| if z.is_finite() { scene.view.camera_z - z } else { f32::NAN }));
        }
    }
}

/// Per-vertex unit normals: area-weighted sums of face normals.
pub fn vertex_normals(vertices: &[[f32; 3]], triangles: &[[u32; 3]], normals: &mut Vec<[f32; 3]>) {
    normals.clear();
    normals.resize(vertices.len(), [0.0; 3]);
    for t in triangles {
        let [a, b, c] = t.map(|k| vertices[k as usize]);
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        for &k in t {
            let m = &mut normals[k as usize];
            m[0] += n[0];
            m[1] += n[1];
            m[2] += n[2];
        }
    }
    for n in normals.iter_mut() {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len > 0.0 {
            n.iter_mut().for_each(|v| *v /= len);
        } else {
            *n = [0.0, 0.0, 1.0];
        }
    }
}

/// Visibility of the subsample rows `row0 ..` covered by the band buffers;
/// `screen` holds the vertices in subsample space (`View::pixel_vertex` with scale s).
#[allow(clippy::too_many_arguments)]
fn visibility_band(screen: &[[f32; 3]], triangles: &[[u32; 3]], view: &View, s: usize, row0: usize, triangle: &mut [u32], zbuf: &mut [f32], weights: &mut [[f32; 2]]) {
    let cols = view.width * s;
    let band_rows = triangle.len() / cols;
    for tri in triangles.iter().enumerate() {
        let (t, &[ia, ib, ic]) = tri;
        let (a, b, c) = (screen[ia as usize], screen[ib as usize], screen[ic as usize]);
        // A small margin absorbs rounding; vertical_hit decides exactly.
        let r_lo = ceil_fast(a[1].min(b[1]).min(c[1]) - 0.5 - MARGIN).max(row0 as f32);
        let r_hi = floor_fast(a[1].max(b[1]).max(c[1]) - 0.5 + MARGIN).min((row0 + band_rows) as f32 - 1.0);
        let c_lo = ceil_fast(a[0].min(b[0]).min(c[0]) - 0.5 - MARGIN).max(0.0);
        let c_hi = floor_fast(a[0].max(b[0]).max(c[0]) - 0.5 + MARGIN).min(cols as f32 - 1.0);
        if !(r_lo <= r_hi && c_lo <= c_hi) {
            continue;
        }
        let (r_lo, r_hi, c_lo, c_hi) = (r_lo as usize, r_hi as usize, c_lo as usize, c_hi as usize);
        let Some(setup) = TriangleSetup::new(a, b, c) else { continue };
        for r in r_lo..=r_hi {
            for col in c_lo..=c_hi {
                if let Some((z, w)) = setup.hit(col as f32 + 0.5, r as f32 + 0.5) {
                    let i = (r - row0) * cols + col;
                    if z > zbuf[i] && z <= view.camera_z {
                        zbuf[i] = z;
                        triangle[i] = t as u32;
                        weights[i] = [w[1], w[2]];
                    }
                }
            }
        }
    }
}

/// Lights with directional vectors normalised once.
fn prepared_lights(lights: &[Light]) -> Vec<Light> {
    lights.iter().map(|l| if l.kind == LightKind::Directional { Light { vector: normalize(l.vector), ..*l } } else { *l }).collect()
}

/// Phong terms at a point `p` with unit normal `n` (facing the camera):
/// `(k_a + Σ I_l k_d max(0, n·l), Σ I_l k_s max(0, r·v)^α)`, so that the
/// intensity is `albedo · first + second`. `min_rdv`: (r·v)^α below
/// SPECULAR_FLOOR is dropped, which skips the powf for most points.
#[inline]
fn lighting(n: [f32; 3], p: [f32; 3], lights: &[Light], m: &Material, min_rdv: f32) -> (f32, f32) {
    let (mut diffuse, mut specular) = (m.ambient, 0.0);
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
        let rdv = 2.0 * ndl * n[2] - l[2];
        if rdv > min_rdv && m.specular > 0.0 {
            specular += light.intensity * m.specular * rdv.powf(m.shininess);
        }
    }
    (diffuse, specular)
}

fn specular_cutoff(m: &Material) -> f32 {
    SPECULAR_FLOOR.powf(1.0 / m.shininess.max(1e-3))
}

#[inline]
fn facing_camera(n: [f32; 3]) -> [f32; 3] {
    if n[2] < 0.0 {
        [-n[0], -n[1], -n[2]]
    } else {
        n
    }
}

/// Gouraud: the Phong terms of every vertex, for `Shading::Gouraud`.
pub fn vertex_lighting(vertices: &[[f32; 3]], normals: &[[f32; 3]], scene: &Scene, lit: &mut Vec<[f32; 2]>) {
    let lights = prepared_lights(scene.lights);
    let min_rdv = specular_cutoff(&scene.material);
    lit.clear();
    lit.extend(vertices.iter().zip(normals).map(|(&p, &n)| {
        let (d, s) = lighting(facing_camera(n), p, &lights, &scene.material, min_rdv);
        [d, s]
    }));
}

/// Shade the pixel rows covered by the band buffers; `lit` holds the vertex
/// lighting for `Shading::Gouraud` (empty for Phong).
#[allow(clippy::too_many_arguments)]
fn shade_band(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
    uv: &[[f32; 2]],
    normals: &[[f32; 3]],
    lit: &[[f32; 2]],
    scene: &Scene,
    triangle: &[u32],
    weights: &[[f32; 2]],
    image: &mut [f32],
    coverage: &mut [f32],
) {
    let s = scene.supersample;
    let (width, cols) = (scene.view.width, scene.view.width * s);
    let per_pixel = 1.0 / (s * s) as f32;
    let lights = prepared_lights(scene.lights);
    let min_rdv = specular_cutoff(&scene.material);
    let point_lights = lights.iter().any(|l| l.kind == LightKind::Point);
    for (pi, (img_row, cov_row)) in image.chunks_exact_mut(width).zip(coverage.chunks_exact_mut(width)).enumerate() {
        for (pj, (out, cov)) in img_row.iter_mut().zip(cov_row.iter_mut()).enumerate() {
            let (mut sum, mut hits) = (0.0f32, 0u32);
            for a in 0..s {
                let base = (pi * s + a) * cols + pj * s;
                for b in 0..s {
                    let t = triangle[base + b];
                    if t == NO_TRIANGLE {
                        continue;
                    }
                    hits += 1;
                    let [w1, w2] = weights[base + b];
                    let w0 = 1.0 - w1 - w2;
                    let [i0, i1, i2] = triangles[t as usize].map(|k| k as usize);
                    let lerp = |p: &[[f32; 3]]| {
                        let (p, q, r) = (p[i0], p[i1], p[i2]);
                        [w0 * p[0] + w1 * q[0] + w2 * r[0], w0 * p[1] + w1 * q[1] + w2 * r[1], w0 * p[2] + w1 * q[2] + w2 * r[2]]
                    };
                    let (u, v) = (w0 * uv[i0][0] + w1 * uv[i1][0] + w2 * uv[i2][0], w0 * uv[i0][1] + w1 * uv[i1][1] + w2 * uv[i2][1]);
                    let albedo = scene.texture.sample(u, v);
                    let (diffuse, specular) = match scene.shading {
                        Shading::Phong => {
                            // The surface point matters only to point lights.
                            let p = if point_lights { lerp(vertices) } else { [0.0; 3] };
                            lighting(facing_camera(normalize(lerp(normals))), p, &lights, &scene.material, min_rdv)
                        }
                        Shading::Gouraud => (
                            w0 * lit[i0][0] + w1 * lit[i1][0] + w2 * lit[i2][0],
                            w0 * lit[i0][1] + w1 * lit[i1][1] + w2 * lit[i2][1],
                        ),
                    };
                    sum += albedo * diffuse + specular;
                }
            }
            *out = sum * per_pixel;
            *cov = hits as f32 * per_pixel;
        }
    }
}

#[inline]
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
    if uv.len() != vertices.len() {
        return Err(InvalidArgument::new("uv", format!("expected one (u, v) per vertex: {} rows, got {}", vertices.len(), uv.len())));
    }
    if !uv.iter().all(|p| p[0].is_finite() && p[1].is_finite()) {
        return Err(InvalidArgument::new("uv", "expected finite texture coordinates"));
    }
    if !(1..=MAX_SUPERSAMPLE).contains(&scene.supersample) {
        return Err(InvalidArgument::new("supersample", format!("expected 1..={MAX_SUPERSAMPLE}, got {}", scene.supersample)));
    }
    scene.texture.validate()?;
    scene.material.validate()?;
    check_lights(scene.lights)
}

/// Render one frame, row bands in parallel (rayon).
pub fn render(vertices: &[[f32; 3]], triangles: &[[u32; 3]], uv: &[[f32; 2]], scene: &Scene) -> Result<Frame> {
    check_render_inputs(vertices, triangles, uv, scene)?;
    let s = scene.supersample;
    let (height, width) = (scene.view.height, scene.view.width);
    let cols = width * s;
    let mut normals = Vec::new();
    vertex_normals(vertices, triangles, &mut normals);
    let screen: Vec<[f32; 3]> = vertices.iter().map(|&v| scene.view.pixel_vertex(v, s as f32)).collect();
    let mut lit = Vec::new();
    if scene.shading == Shading::Gouraud {
        vertex_lighting(vertices, &normals, scene, &mut lit);
    }
    let mut triangle = vec![NO_TRIANGLE; height * s * cols];
    let mut zbuf = vec![f32::NEG_INFINITY; height * s * cols];
    let mut weights = vec![[0.0f32; 2]; height * s * cols];
    let mut frame = Frame { image: vec![0.0; height * width], coverage: vec![0.0; height * width], depth: Vec::new() };
    // Bands of whole pixel rows (s subsample rows each), sized to give every thread work.
    let band_pixels = height.div_ceil(4 * rayon::current_num_threads()).max(1);
    let band = band_pixels * s * cols;
    triangle
        .par_chunks_mut(band)
        .zip(zbuf.par_chunks_mut(band))
        .zip(weights.par_chunks_mut(band))
        .zip(frame.image.par_chunks_mut(band_pixels * width))
        .zip(frame.coverage.par_chunks_mut(band_pixels * width))
        .enumerate()
        .for_each(|(k, ((((tri, z), w), img), cov))| {
            visibility_band(&screen, triangles, &scene.view, s, k * band_pixels * s, tri, z, w);
            shade_band(vertices, triangles, uv, &normals, &lit, scene, tri, w, img, cov);
        });
    frame.depth = zbuf.iter().map(|&z| if z.is_finite() { scene.view.camera_z - z } else { f32::NAN }).collect();
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::raycast_depth;
    use crate::geometry::CAMERA_Z;
    use crate::mesh::grid_triangles;
    use crate::params::SurfaceConfig;
    use crate::synthesis::synthesize;

    fn white(n: usize) -> Texture {
        Texture { height: n, width: n, data: vec![1.0; n * n] }
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
            for s in [1usize, 3] {
                let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
                let scene = Scene { view, supersample: s, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
                let frame = render(&vertices, &triangles, &uv, &scene).unwrap();
                for i in 0..48 {
                    for j in 0..40 {
                        let z = frame.depth[(i * s + s / 2) * 40 * s + j * s + s / 2];
                        let d = cast[i * 40 + j];
                        // Identical arithmetic at s = 1; at s = 3 the vertices are scaled by 3 first.
                        let tolerance = if s == 1 { 0.0 } else { 1e-5 };
                        assert!((z - d).abs() <= tolerance || (z.is_nan() && d.is_nan()), "seed {seed} s {s} ({i},{j}): {z} vs {d}");
                    }
                }
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
    fn albedo_is_the_texture_at_the_interpolated_coordinates() {
        // Flat plane facing a light along +z, diffuse only: intensity = albedo.
        let (v, t, uv) = plane(0.0);
        let data: Vec<f32> = (0..32 * 32).map(|i| ((i % 32) as f32 * 0.7 + (i / 32) as f32 * 0.3) / 32.0).collect();
        let texture = Texture { height: 32, width: 32, data };
        let lights = [Light { kind: LightKind::Directional, vector: [0.0, 0.0, 1.0], intensity: 1.0 }];
        let view = View::new(10, 12, [-0.7, -0.6, 0.5, 0.8], CAMERA_Z).unwrap();
        let scene = Scene { view, supersample: 1, lights: &lights, material: matte(), texture: &texture, shading: Shading::Phong };
        let image = render(&v, &t, &uv, &scene).unwrap().image;
        for i in 0..10 {
            for j in 0..12 {
                let (x, y) = view.world(i as f32 + 0.5, j as f32 + 0.5);
                let expected = texture.sample((x + 1.0) / 2.0, (1.0 - y) / 2.0);
                assert!((image[i * 12 + j] - expected).abs() < 1e-5, "({i},{j}): {} vs {expected}", image[i * 12 + j]);
            }
        }
    }

    #[test]
    fn texture_moves_with_the_surface() {
        // Shift the mesh by one pixel: the image shifts by one pixel.
        let (mut v, t, uv) = plane(0.0);
        let data: Vec<f32> = (0..64 * 64).map(|i| ((i % 64) as f32 / 63.0 + (i / 64) as f32 / 90.0).fract()).collect();
        let texture = Texture { height: 64, width: 64, data };
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
        let texture = Texture { height: 16, width: 16, data: (0..256).map(|i| (i % 7) as f32 / 7.0).collect() };
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
    }
}
