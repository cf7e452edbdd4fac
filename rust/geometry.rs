//! The camera and the one point-in-triangle test that both the rasteriser and
//! the ray caster use, so their depths agree exactly at pixel centres.
//!
//! Coverage is decided in pixel space (`View::pixel_vertex`).
//!
//! Frames: world x right, y up, z toward the camera, which looks down −z.
//! Pixel (row i, column j) of an H×W image of window (xmin, ymin, xmax, ymax)
//! has its centre at `x = xmin + (j + ½)(xmax − xmin)/W`,
//! `y = ymax − (i + ½)(ymax − ymin)/H` (row 0 at the top). Two cameras:
//! - orthographic (the design's): the ray of a pixel is the vertical line
//!   through its (x, y), from the plane z = `camera_z`; the depth of a point
//!   is `camera_z − z`;
//! - perspective (`View::with_pinhole`): the rays meet at the pinhole
//!   C = (px, py, `camera_z`), and the window is what the image shows of the
//!   plane z = 0 (a ray passes there through its pixel's (x, y)); the depth
//!   of a point is its distance along the optical axis, `camera_z − z`.
//!
//! Both the rasteriser and the ray caster work in a space where every ray is
//! vertical: `View::warp` maps a point by the projective map
//! `(x, y, z) ↦ (px + (x − px)·k, py + (y − py)·k, camera_z·(k − 1))`,
//! `k = camera_z / (camera_z − z)` (identity for the orthographic camera).
//! It fixes the plane z = 0, sends the ray through a point to the vertical
//! line through its image, keeps "nearer" as "higher", and, being
//! projective, keeps a triangle a plane triangle, so the z' interpolated
//! over it in pixel space is exact, and `View::depth` maps it back.
//!
//! Subsample (a, b) of an s×s supersampling grid sits at offsets
//! `((b + ½)/s, (a + ½)/s)` inside the pixel.

use crate::error::{in_range, InvalidArgument, Result};
use crate::lanes::Lanes8;
use crate::params::Range;
use crate::rng::SplitMix64;

/// Default camera plane: the undeformed patch (z = 0) is 2 units in front of it.
pub const CAMERA_Z: f32 = 2.0;
/// Largest image side accepted.
pub const MAX_SIZE: usize = 8192;

/// A view: image size, the world window it covers and the camera (module header).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub height: usize,
    pub width: usize,
    /// (xmin, ymin, xmax, ymax) in world units.
    pub window: [f32; 4],
    /// The orthographic camera's plane, or the pinhole's z.
    pub camera_z: f32,
    /// The pinhole's (x, y) for a perspective camera; None: orthographic.
    pub pinhole: Option<[f32; 2]>,
}

impl View {
    pub fn new(height: usize, width: usize, window: [f32; 4], camera_z: f32) -> Result<Self> {
        if height == 0 || width == 0 || height > MAX_SIZE || width > MAX_SIZE {
            return Err(InvalidArgument::new("size", format!("expected (H, W) with 1 <= H, W <= {MAX_SIZE}, got ({height}, {width})")));
        }
        let [x0, y0, x1, y1] = window;
        if !(window.iter().all(|v| v.is_finite()) && x1 > x0 && y1 > y0) {
            return Err(InvalidArgument::new("window", format!("expected finite (xmin, ymin, xmax, ymax) with xmin < xmax and ymin < ymax, got {window:?}")));
        }
        if !camera_z.is_finite() {
            return Err(InvalidArgument::new("camera_z", format!("expected a finite number, got {camera_z}")));
        }
        Ok(Self { height, width, window, camera_z, pinhole: None })
    }

    /// This view seen by a perspective camera with its pinhole at
    /// (x, y, `camera_z`); `camera_z` must be positive (the plane z = 0 in front).
    pub fn with_pinhole(self, pinhole: [f32; 2]) -> Result<Self> {
        if !pinhole.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("pinhole", format!("expected finite (x, y), got {pinhole:?}")));
        }
        if self.camera_z <= 0.0 {
            return Err(InvalidArgument::new("camera_z", format!("expected a pinhole above the plane z = 0 (camera_z > 0), got {}", self.camera_z)));
        }
        Ok(Self { pinhole: Some(pinhole), ..self })
    }

    /// A point in the space where rays are vertical (module header).
    #[inline]
    pub fn warp(&self, v: [f32; 3]) -> [f32; 3] {
        match self.pinhole {
            None => v,
            Some([px, py]) => {
                let k = self.camera_z / (self.camera_z - v[2]);
                [px + (v[0] - px) * k, py + (v[1] - py) * k, self.camera_z * (k - 1.0)]
            }
        }
    }

    /// The depth of a hit at warped height `z` (the inverse of `warp`'s z).
    #[inline]
    pub fn depth(&self, z: f32) -> f32 {
        match self.pinhole {
            None => self.camera_z - z,
            Some(_) => self.camera_z * self.camera_z / (z + self.camera_z),
        }
    }

    /// The highest warped z a hit may have: the camera's plane, or any
    /// height in front of the pinhole (points behind it are refused, `check_in_front`).
    #[inline]
    pub fn z_max(&self) -> f32 {
        if self.pinhole.is_some() { f32::INFINITY } else { self.camera_z }
    }

    /// Unit vector from world point `p` toward the camera.
    #[inline]
    pub fn toward_camera(&self, p: [f32; 3]) -> [f32; 3] {
        match self.pinhole {
            None => [0.0, 0.0, 1.0],
            Some([px, py]) => {
                let d = [px - p[0], py - p[1], self.camera_z - p[2]];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [d[0] / len, d[1] / len, d[2] / len]
            }
        }
    }

    /// With a pinhole, every vertex must lie in front of it (z < `camera_z`).
    pub fn check_in_front(&self, vertices: &[[f32; 3]]) -> Result<()> {
        if self.pinhole.is_some() {
            if let Some(i) = vertices.iter().position(|v| v[2] >= self.camera_z) {
                return Err(InvalidArgument::new("vertices", format!("expected every vertex in front of the pinhole (z < camera_z = {}), vertex {i} is {:?}", self.camera_z, vertices[i])));
            }
        }
        Ok(())
    }

    /// World (x, y) of a point at fractional pixel coordinates (row `r`, column `c`),
    /// where (i + ½, j + ½) is the centre of pixel (i, j).
    #[inline]
    pub fn world(&self, r: f32, c: f32) -> (f32, f32) {
        let [x0, y0, x1, y1] = self.window;
        (x0 + c * (x1 - x0) / self.width as f32, y1 - r * (y1 - y0) / self.height as f32)
    }

    /// A vertex in pixel space `[column, row, z']`, pixel coordinates times
    /// `scale` (the supersampling factor) and the warped height (`warp`).
    /// Rasteriser and ray caster both test coverage in this space, at sample
    /// centres (k + ½) — the same arithmetic, so their depths agree.
    #[inline]
    pub fn pixel_vertex(&self, v: [f32; 3], scale: f32) -> [f32; 3] {
        self.screen(self.warp(v), scale)
    }

    /// [`pixel_vertex`](Self::pixel_vertex) of a point already warped.
    #[inline]
    pub fn screen(&self, w: [f32; 3], scale: f32) -> [f32; 3] {
        let (r, c) = self.pixel(w[0], w[1]);
        [c * scale, r * scale, w[2]]
    }

    /// Fractional pixel coordinates (row, column) of world (x, y); inverse of `world`.
    #[inline]
    pub fn pixel(&self, x: f32, y: f32) -> (f32, f32) {
        let [x0, y0, x1, y1] = self.window;
        ((y1 - y) * self.height as f32 / (y1 - y0), (x - x0) * self.width as f32 / (x1 - x0))
    }
}

/// The ranges a clip's camera is drawn from: a square crop of a perspective
/// frame. The frame sees `fov` (radians) across its width; the clip's window
/// is `crop_share` of that width, at a uniform place inside the frame, so
/// the clip's own rays spread over about `fov · crop_share`, as in a patch
/// a reconstruction cuts from a real frame (or its whole frame, at share 1).
/// `probability` of the clips are seen so, the others orthographically.
/// `fov` (0, 0), the default, is the orthographic camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraConfig {
    pub fov: Range,
    pub crop_share: Range,
    pub probability: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self { fov: Range::new(0.0, 0.0), crop_share: Range::new(1.0, 1.0), probability: 1.0 }
    }
}

/// The pinhole drawn for a clip: its (x, y) and height `camera_z` over the plane z = 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    pub xy: [f32; 2],
    pub camera_z: f32,
}

impl CameraConfig {
    pub fn validate(&self) -> Result<()> {
        self.fov.check("config.camera_fov", 0.0, 2.8)?;
        self.crop_share.check("config.crop_share", 0.01, 1.0)?;
        in_range("config.camera_probability", self.probability, 0.0, 1.0).map(|_| ())
    }

    /// The pinhole for a clip with `window`, or None (orthographic) when the
    /// fov range is (0, 0); draws nothing then, so such clips stay as they were.
    /// The orthographic share is drawn after the pinhole, and only when
    /// `probability` < 1, so the clips seen through it are those a
    /// probability of 1 draws.
    pub fn sample(&self, window: [f32; 4], rng: &mut SplitMix64) -> Option<Pinhole> {
        if self.fov.hi == 0.0 {
            return None;
        }
        let fov = rng.uniform(self.fov.lo, self.fov.hi).max(1e-3);
        let share = rng.uniform(self.crop_share.lo, self.crop_share.hi);
        let width = f64::from(window[2] - window[0]);
        let frame = width / share;
        let centre = [f64::from(window[0] + window[2]) / 2.0, f64::from(window[1] + window[3]) / 2.0];
        // The frame's centre (its principal point) lies where the window sits inside it: uniform.
        let spread = (frame - width) / 2.0;
        let xy = centre.map(|c| (c + rng.uniform(-spread, spread)) as f32);
        let pinhole = Pinhole { xy, camera_z: (frame / 2.0 / (fov / 2.0).tan()) as f32 };
        (self.probability == 1.0 || rng.unit() < self.probability).then_some(pinhole)
    }
}

/// A triangle prepared for many vertical-line tests: the per-triangle part of
/// `vertical_hit` computed once. `hit` and `hits` perform exactly the
/// arithmetic of `vertical_hit`, so results are bit-identical.
#[derive(Clone, Copy, Debug)]
pub struct TriangleSetup {
    a: [f32; 3],
    b: [f32; 3],
    c: [f32; 3],
    // Edge vectors, negated for a clockwise projection so that "inside" is
    // every edge function >= 0 for either winding. Negation is exact, and
    // `inv_area` is negated with them, so the weights are unchanged.
    ca: [f32; 2],
    ab: [f32; 2],
    bc: [f32; 2],
    inv_area: f32,
}

impl TriangleSetup {
    /// None when the xy-projection has zero (or non-finite) area: never hit.
    #[inline]
    pub fn new(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Option<Self> {
        let ab = [b[0] - a[0], b[1] - a[1]];
        let area = ab[0] * (c[1] - a[1]) - ab[1] * (c[0] - a[0]);
        if area == 0.0 || !area.is_finite() {
            return None;
        }
        let (ca, bc) = ([a[0] - c[0], a[1] - c[1]], [c[0] - b[0], c[1] - b[1]]);
        let sign = if area > 0.0 { 1.0 } else { -1.0 };
        let oriented = |e: [f32; 2]| [sign * e[0], sign * e[1]];
        Some(Self { a, b, c, ca: oriented(ca), ab: oriented(ab), bc: oriented(bc), inv_area: sign / area })
    }

    /// The part of the three edge functions that depends only on the row y = `py`.
    #[inline(always)]
    pub fn row(&self, py: f32) -> [f32; 3] {
        [self.bc[0] * (py - self.b[1]), self.ca[0] * (py - self.c[1]), self.ab[0] * (py - self.a[1])]
    }

    /// The edge functions at x = `px` of a row from [`row`](Self::row).
    #[inline]
    fn edges(&self, row: [f32; 3], px: f32) -> [f32; 3] {
        [row[0] - self.bc[1] * (px - self.b[0]), row[1] - self.ca[1] * (px - self.c[0]), row[2] - self.ab[1] * (px - self.a[0])]
    }

    /// z and weights at edge functions `w` (any point of the plane).
    #[inline]
    fn interpolate(&self, w: [f32; 3]) -> (f32, [f32; 3]) {
        let l = w.map(|w| w * self.inv_area);
        (l[0] * self.a[2] + l[1] * self.b[2] + l[2] * self.c[2], l)
    }

    /// `(z, [λa, λb, λc])` where the vertical line through (px, py) meets the
    /// triangle, if it does; points on an edge count as inside.
    #[inline]
    pub fn hit(&self, px: f32, py: f32) -> Option<(f32, [f32; 3])> {
        let w = self.edges(self.row(py), px);
        (w[0] >= 0.0 && w[1] >= 0.0 && w[2] >= 0.0).then(|| self.interpolate(w))
    }

    /// [`hit`](Self::hit) at eight points at once (SIMD, the same IEEE
    /// operations lane by lane): lane i at x = `px[i]` on the row whose
    /// [`row`](Self::row) values are `row[k][i]`. Returns `(inside, z, λb,
    /// λc)`, `inside` a lane mask; the other lanes hold the plane's values there.
    #[inline(always)]
    pub(crate) fn hits<L: Lanes8>(&self, row: [L; 3], px: L) -> (L, L, L, L) {
        let splat = L::splat;
        let w0 = row[0] - splat(self.bc[1]) * (px - splat(self.b[0]));
        let w1 = row[1] - splat(self.ca[1]) * (px - splat(self.c[0]));
        let w2 = row[2] - splat(self.ab[1]) * (px - splat(self.a[0]));
        let zero = splat(0.0);
        let inside = w0.simd_ge(zero) & w1.simd_ge(zero) & w2.simd_ge(zero);
        let inv_area = splat(self.inv_area);
        let (l0, l1, l2) = (w0 * inv_area, w1 * inv_area, w2 * inv_area);
        (inside, l0 * splat(self.a[2]) + l1 * splat(self.b[2]) + l2 * splat(self.c[2]), l1, l2)
    }
}

/// `x.floor()` without the libm call the x86-64 baseline makes of it (no
/// SSE4.1 `roundss`); exact for |x| < 2³¹, saturating beyond (callers clamp).
#[inline]
pub fn floor_fast(x: f32) -> f32 {
    let i = x as i32 as f32;
    if i > x { i - 1.0 } else { i }
}

/// `x.ceil()`, as [`floor_fast`].
#[inline]
pub fn ceil_fast(x: f32) -> f32 {
    let i = x as i32 as f32;
    if i < x { i + 1.0 } else { i }
}

/// Where the vertical line through (px, py) meets triangle (a, b, c), if it
/// does: `(z, [λa, λb, λc])` with barycentric weights. Either winding counts
/// (no culling); triangles whose xy-projection has zero area are never hit;
/// points on an edge count as inside.
#[inline]
pub fn vertical_hit(a: [f32; 3], b: [f32; 3], c: [f32; 3], px: f32, py: f32) -> Option<(f32, [f32; 3])> {
    TriangleSetup::new(a, b, c)?.hit(px, py)
}

/// Validate a mesh: vertices (V, 3) finite, triangles (F, 3) indexing into them.
pub fn check_mesh(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<()> {
    if vertices.is_empty() {
        return Err(InvalidArgument::new("vertices", "expected at least one vertex, got an empty array"));
    }
    if triangles.is_empty() {
        return Err(InvalidArgument::new("triangles", "expected at least one triangle, got an empty array"));
    }
    if let Some(i) = vertices.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
        return Err(InvalidArgument::new("vertices", format!("expected finite coordinates, vertex {i} is {:?}", vertices[i])));
    }
    let n = vertices.len() as u32;
    if let Some(i) = triangles.iter().position(|t| t.iter().any(|&k| k >= n)) {
        return Err(InvalidArgument::new("triangles", format!("index out of range: triangle {i} is {:?} but there are {n} vertices", triangles[i])));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_floor_and_ceil_match_std() {
        for k in -40_000..40_000 {
            let x = k as f32 * 0.013_7 - 3.0;
            assert_eq!(floor_fast(x), x.floor(), "{x}");
            assert_eq!(ceil_fast(x), x.ceil(), "{x}");
        }
        for x in [0.0f32, -0.0, 1.0, -1.0, 1e9, -1e9, 0.5, -0.5, 4096.999] {
            assert_eq!(floor_fast(x), x.floor());
            assert_eq!(ceil_fast(x), x.ceil());
        }
        // Beyond i32 the result saturates but keeps its side of any clamp.
        assert!(floor_fast(1e30) > 1e9 && ceil_fast(-1e30) < -1e9);
    }

    #[test]
    fn world_and_pixel_are_inverse_and_row_zero_is_at_the_top() {
        let v = View::new(4, 8, [-1.0, -0.5, 1.0, 0.5], CAMERA_Z).unwrap();
        let (x, y) = v.world(0.5, 0.5);
        assert!((x + 0.875).abs() < 1e-6 && (y - 0.375).abs() < 1e-6);
        let (r, c) = v.pixel(x, y);
        assert!((r - 0.5).abs() < 1e-6 && (c - 0.5).abs() < 1e-6);
        assert_eq!(View::new(0, 4, [0.0, 0.0, 1.0, 1.0], 0.0).unwrap_err().name, "size");
        assert_eq!(View::new(4, 4, [0.0, 0.0, 0.0, 1.0], 0.0).unwrap_err().name, "window");
    }

    #[test]
    fn the_warp_sends_each_ray_to_one_vertical_and_keeps_depth_order() {
        let view = View::new(8, 8, [-1.0, -1.0, 1.0, 1.0], 1.7).unwrap().with_pinhole([0.3, -0.2]).unwrap();
        let c = [0.3f32, -0.2, 1.7];
        for (x, y) in [(0.0f32, 0.0f32), (-0.9, 0.4), (0.7, 0.8)] {
            // Points along the ray from the pinhole through (x, y, 0), nearest first.
            let warped: Vec<[f32; 3]> = [0.2f32, 0.5, 1.0, 1.6].iter().map(|&t| view.warp([c[0] + t * (x - c[0]), c[1] + t * (y - c[1]), c[2] * (1.0 - t)])).collect();
            for (w, t) in warped.iter().zip([0.2f32, 0.5, 1.0, 1.6]) {
                assert!((w[0] - x).abs() < 1e-5 && (w[1] - y).abs() < 1e-5, "{w:?} is not over ({x}, {y})");
                assert!((view.depth(w[2]) - t * c[2]).abs() < 1e-5, "depth {} vs {}", view.depth(w[2]), t * c[2]);
            }
            assert!(warped.windows(2).all(|p| p[0][2] > p[1][2]), "nearer must be higher: {warped:?}");
        }
        // The plane z = 0 stays where it is; the orthographic view warps nothing.
        let w = view.warp([0.4, 0.1, 0.0]);
        assert!((w[0] - 0.4).abs() < 1e-6 && (w[1] - 0.1).abs() < 1e-6 && w[2] == 0.0, "{w:?}");
        let flat = View::new(8, 8, [-1.0, -1.0, 1.0, 1.0], 1.7).unwrap();
        assert_eq!(flat.warp([0.4, 0.1, 0.9]), [0.4, 0.1, 0.9]);
        assert_eq!(flat.depth(0.9), 1.7 - 0.9);
        assert_eq!(View::new(8, 8, [-1.0, -1.0, 1.0, 1.0], -1.0).unwrap().with_pinhole([0.0, 0.0]).unwrap_err().name, "camera_z");
        assert_eq!(flat.with_pinhole([f32::NAN, 0.0]).unwrap_err().name, "pinhole");
    }

    #[test]
    fn a_share_of_perspective_clips_draws_their_pinholes_as_a_share_of_one_does() {
        let window = [-0.8f32, -0.7, 0.9, 1.0];
        let every = CameraConfig { fov: Range::new(0.5, 1.4), crop_share: Range::new(0.1, 1.0), probability: 1.0 };
        let some = CameraConfig { probability: 0.3, ..every };
        let mut seen = 0;
        for seed in 0..2000u64 {
            let full = every.sample(window, &mut SplitMix64::new(seed)).unwrap();
            if let Some(pinhole) = some.sample(window, &mut SplitMix64::new(seed)) {
                assert_eq!(pinhole, full);
                seen += 1;
            }
        }
        // 600 expected; a binomial's standard deviation is 20.5.
        assert!((520..=680).contains(&seen), "{seen} of 2000 through the pinhole at probability 0.3");
        assert!(CameraConfig { probability: 0.0, ..every }.sample(window, &mut SplitMix64::new(1)).is_none());
        assert_eq!(CameraConfig { probability: 1.5, ..every }.validate().unwrap_err().name, "config.camera_probability");
        assert_eq!(CameraConfig { probability: f64::NAN, ..every }.validate().unwrap_err().name, "config.camera_probability");
    }

    #[test]
    fn vertical_hit_interpolates_a_plane_for_either_winding() {
        let (a, b, c) = ([0.0, 0.0, 1.0], [1.0, 0.0, 2.0], [0.0, 1.0, 3.0]);
        for (p, q, r) in [(a, b, c), (a, c, b)] {
            let (z, l) = vertical_hit(p, q, r, 0.25, 0.25).unwrap();
            assert!((z - (1.0 + 0.25 + 0.5)).abs() < 1e-6);
            assert!((l.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        }
        assert!(vertical_hit(a, b, c, 0.6, 0.6).is_none());
        assert!(vertical_hit(a, b, [2.0, 0.0, 0.0], 0.5, 0.0).is_none(), "zero-area projection");
    }
}
