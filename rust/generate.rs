//! Training clips `(f_render, f_depth)`: a rendered grayscale video of a
//! synthesised deforming surface and its ray-cast depth video.
//!
//! Clip `i` of a run is a pure function of (config, seed, i, texture folder):
//! attempt `a` draws everything from `hash(seed, i, a)`; the first attempt
//! whose view window lies inside the surface at every pixel subsample of every
//! frame (a backdrop clip's: whose every frame shows enough of the sheet,
//! `backdrop`; a perspective clip's: whose surface also stays farther from
//! the pinhole than half the window plane's distance) is kept, and `a` is reported as the clip's redraw count. Clips are
//! independent, so the bytes do not depend on the thread count or batch split.
//!
//! Per clip: surface (`synthesis`), texture (`textures`), then per frame the
//! frame and its depth are rendered in one pass (`raster`: the depth at pixel
//! centres is the ray caster's, `bvh::raycast_depth`, bit for bit at the
//! power-of-two supersampling factors and to rounding otherwise), the
//! camera's blur and response are applied (`camera_response`; none by
//! default), Gaussian noise of the drawn standard deviation is added and the
//! intensity is clamped to [0, 1] and quantised to u8; a backdrop clip's
//! background is composited behind the sheet before the camera's effects.
//! Depth is `camera_z − z` (`geometry`; a perspective clip's camera_z is
//! its pinhole's, `geometry::CameraConfig`), NaN off the sheet.
//! Shapes: video (n, T, H, W) u8, depth (n, T, H, W) f32; H = W = `size`.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::backdrop::{composite, covers, BackdropConfig, BackdropParams};
use crate::error::{in_range, size_in, InvalidArgument, Result};
use crate::geometry::{CameraConfig, Pinhole, View, CAMERA_Z};
use crate::mesh::grid_triangles;
use crate::params::{Range, SurfaceConfig, SurfaceParams};
use crate::raster::{Shading, Frame, Light, LightKind, Material, Rasterizer, Scene, Texture};
use crate::rng::{hash, normals8, SplitMix64};
use crate::sheet::{Bender, SheetConfig, SheetParams};
use crate::synthesis::{clip_len, frame_time, rigid_motion, Synthesizer};
use crate::textures::{procedural_region, TextureBank, TextureFamily, DEFAULT_FAMILIES};

pub const MAX_CLIP_SIZE: usize = 1024;

/// Half-width of the default light-azimuth prior about image-up: 70°.
///
/// Relief z lit from azimuth a renders exactly as −z lit from a + π (normals
/// and lights mirror together under the orthographic camera), so the sign of
/// the relief is observable only if no light set and its mirror are both
/// likely. Any half-width below 90° keeps every mirrored light outside the
/// prior; 70° leaves 40° between the prior and its mirror, so the two
/// readings stay well apart after blur and noise, while covering most of the
/// upper half-plane that ceiling lights and sky come from in real footage.
pub const LIGHT_PRIOR_HALF_WIDTH: f64 = 70.0 * std::f64::consts::PI / 180.0;

/// Every range a clip is drawn from.
#[derive(Clone, Debug, PartialEq)]
pub struct GeneratorConfig {
    pub frames: usize,
    /// Image side H = W in pixels.
    pub size: usize,
    /// Mesh vertices per side.
    pub grid: usize,
    /// Subsamples per pixel side (anti-aliasing).
    pub supersample: usize,
    pub surface: SurfaceConfig,
    /// Side of the square view window, world units (the patch is 2 wide).
    pub window_width: Range,
    /// Offset of the window centre from the patch centre, x and y each.
    pub window_offset: Range,
    /// Number of lights, inclusive.
    pub light_count: (usize, usize),
    /// Azimuth of each light direction in image coordinates, radians: 0 is
    /// image-up (toward row 0, world +y), +π/2 image-right (world +x). The
    /// default, ±70° about image-up, is the light-from-above prior that makes
    /// the relief's sign observable (`LIGHT_PRIOR_HALF_WIDTH`); (−π, π) is
    /// uniform. Any interval of at most 2π inside [−2π, 2π].
    pub light_azimuth: Range,
    /// Elevation of each light direction above the surface plane, radians.
    pub light_elevation: Range,
    /// Sum of the lights' intensities (split at random between them).
    pub light_intensity: Range,
    /// Probability that a light is a point light rather than directional.
    pub point_light_probability: f64,
    /// Distance of a point light from the patch centre.
    pub point_light_distance: Range,
    pub ambient: Range,
    pub diffuse: Range,
    pub specular: Range,
    /// Phong exponent, log-uniform.
    pub shininess: Range,
    /// Where the Phong model is evaluated (per pixel or per vertex).
    pub shading: Shading,
    /// Procedural families drawn from uniformly (ignored with a texture folder).
    pub texture_families: Vec<TextureFamily>,
    pub texture_size: usize,
    /// Standard deviation of the additive Gaussian noise, intensity units ([0, 1] = black to white).
    pub noise_std: Range,
    /// Standard deviation of the camera's Gaussian blur (optics, focus), in
    /// output pixels; 0 is none.
    pub blur: Range,
    /// Exponent of the camera's response, `v ↦ v^gamma` on the blurred
    /// intensity before noise; 1 is linear.
    pub gamma: Range,
    /// Attempts after the first before a clip is given up with an error.
    pub max_redraws: usize,
    /// Isometric bends and folds (`sheet`); none by default.
    pub sheet: SheetConfig,
    /// Views that show the sheet's border and a background (`backdrop`); none by default.
    pub backdrop: BackdropConfig,
    /// A perspective camera (`geometry::CameraConfig`); orthographic by default.
    pub camera: CameraConfig,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        Self {
            frames: 16,
            size: 64,
            grid: 64,
            supersample: 2,
            surface: SurfaceConfig::default(),
            window_width: Range::new(0.8, 1.2),
            window_offset: Range::new(-0.1, 0.1),
            light_count: (1, 3),
            light_azimuth: Range::new(-LIGHT_PRIOR_HALF_WIDTH, LIGHT_PRIOR_HALF_WIDTH),
            light_elevation: Range::new(0.5, 1.45),
            light_intensity: Range::new(0.7, 1.1),
            point_light_probability: 0.3,
            point_light_distance: Range::new(2.0, 6.0),
            ambient: Range::new(0.05, 0.3),
            diffuse: Range::new(0.5, 1.0),
            specular: Range::new(0.0, 0.5),
            shininess: Range::new(4.0, 100.0),
            shading: Shading::Phong,
            texture_families: DEFAULT_FAMILIES.to_vec(),
            texture_size: 256,
            noise_std: Range::new(0.0, 0.03),
            blur: Range::new(0.0, 0.0),
            gamma: Range::new(1.0, 1.0),
            max_redraws: 200,
            sheet: SheetConfig::default(),
            backdrop: BackdropConfig::default(),
            camera: CameraConfig::default(),
        }
    }
}

impl GeneratorConfig {
    pub fn validate(&self) -> Result<()> {
        size_in("config.frames", self.frames as i64, 1, 4096)?;
        size_in("config.size", self.size as i64, 1, MAX_CLIP_SIZE as i64)?;
        size_in("config.grid", self.grid as i64, 2, 2048)?;
        size_in("config.supersample", self.supersample as i64, 1, crate::raster::MAX_SUPERSAMPLE as i64)?;
        size_in("config.texture_size", self.texture_size as i64, 2, 4096)?;
        self.surface.validate()?;
        self.window_width.check("config.window_width", 1e-3, 2.0)?;
        self.window_offset.check("config.window_offset", -1.0, 1.0)?;
        let (lo, hi) = self.light_count;
        if !(1..=16).contains(&lo) || !(lo..=16).contains(&hi) {
            return Err(InvalidArgument::new("config.light_count", format!("expected 1 <= lo <= hi <= 16, got ({lo}, {hi})")));
        }
        // Any interval of at most one turn inside ±2π, so that one around image-down (say (π − w, π + w)) needs no wrap.
        self.light_azimuth.check("config.light_azimuth", -std::f64::consts::TAU, std::f64::consts::TAU)?;
        if self.light_azimuth.hi - self.light_azimuth.lo > std::f64::consts::TAU {
            return Err(InvalidArgument::new("config.light_azimuth", format!("expected an interval of at most 2π, got ({}, {})", self.light_azimuth.lo, self.light_azimuth.hi)));
        }
        self.light_elevation.check("config.light_elevation", 0.0, std::f64::consts::FRAC_PI_2)?;
        self.light_intensity.check("config.light_intensity", 0.0, 100.0)?;
        in_range("config.point_light_probability", self.point_light_probability, 0.0, 1.0)?;
        self.point_light_distance.check("config.point_light_distance", 0.1, 1000.0)?;
        self.ambient.check("config.ambient", 0.0, 10.0)?;
        self.diffuse.check("config.diffuse", 0.0, 10.0)?;
        self.specular.check("config.specular", 0.0, 10.0)?;
        self.shininess.check("config.shininess", 1e-3, 10_000.0)?;
        self.noise_std.check("config.noise_std", 0.0, 1.0)?;
        self.blur.check("config.blur", 0.0, 8.0)?;
        self.gamma.check("config.gamma", 0.1, 10.0)?;
        if self.texture_families.is_empty() {
            return Err(InvalidArgument::new("config.texture_families", "expected at least one family"));
        }
        size_in("config.max_redraws", self.max_redraws as i64, 0, 1_000_000)?;
        self.sheet.validate()?;
        self.backdrop.validate()?;
        self.camera.validate()
    }

    pub fn frame_len(&self) -> usize {
        self.size * self.size
    }

    pub fn clip_pixels(&self) -> usize {
        self.frames * self.frame_len()
    }
}

/// Which texture a clip wears.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureChoice {
    Procedural { family: TextureFamily, seed: u64 },
    /// Crop of image `index` of the texture folder at (top, left).
    Image { index: usize, top: usize, left: usize },
}

/// Everything that was drawn for one clip.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipParams {
    pub surface: SurfaceParams,
    pub window: [f32; 4],
    pub lights: Vec<Light>,
    pub material: Material,
    pub texture: TextureChoice,
    pub noise_std: f64,
    pub noise_seed: u64,
    /// The camera's blur (pixels) and response exponent.
    pub blur: f64,
    pub gamma: f64,
    /// The sheet's bends and folds, if the clip is a sheet.
    pub sheet: Option<SheetParams>,
    /// The background, if the clip shows the sheet's border (its window is then `window`).
    pub backdrop: Option<BackdropParams>,
    /// The perspective camera's pinhole; None: orthographic.
    pub pinhole: Option<Pinhole>,
    /// Attempts rejected before this one: the window showed background (or,
    /// with a backdrop, too little of the sheet).
    pub redraws: usize,
}

fn draw_clip(config: &GeneratorConfig, bank: Option<&TextureBank>, rng: &mut SplitMix64) -> Result<ClipParams> {
    let surface = config.surface.sample(rng.next_u64())?;
    let width = rng.uniform(config.window_width.lo, config.window_width.hi);
    let (cx, cy) = (rng.uniform(config.window_offset.lo, config.window_offset.hi), rng.uniform(config.window_offset.lo, config.window_offset.hi));
    let half = width / 2.0;
    let mut window = [(cx - half) as f32, (cy - half) as f32, (cx + half) as f32, (cy + half) as f32];
    let (lo, hi) = config.light_count;
    let count = lo + (rng.next_u64() % (hi - lo + 1) as u64) as usize;
    let total = rng.uniform(config.light_intensity.lo, config.light_intensity.hi);
    let shares: Vec<f64> = (0..count).map(|_| 0.2 + rng.unit()).collect();
    let share_sum: f64 = shares.iter().sum();
    let lights = shares
        .iter()
        .map(|share| {
            let azimuth = rng.uniform(config.light_azimuth.lo, config.light_azimuth.hi);
            let elevation = rng.uniform(config.light_elevation.lo, config.light_elevation.hi);
            // Azimuth 0 is image-up = world +y, clockwise on screen toward +x.
            let dir = [elevation.cos() * azimuth.sin(), elevation.cos() * azimuth.cos(), elevation.sin()];
            let point = rng.unit() < config.point_light_probability;
            let distance = rng.uniform(config.point_light_distance.lo, config.point_light_distance.hi);
            let (kind, scale) = if point { (LightKind::Point, distance) } else { (LightKind::Directional, 1.0) };
            Light { kind, vector: dir.map(|v| (v * scale) as f32), intensity: (total * share / share_sum) as f32 }
        })
        .collect();
    let material = Material {
        ambient: rng.uniform(config.ambient.lo, config.ambient.hi) as f32,
        diffuse: rng.uniform(config.diffuse.lo, config.diffuse.hi) as f32,
        specular: rng.uniform(config.specular.lo, config.specular.hi) as f32,
        shininess: rng.log_uniform(config.shininess.lo, config.shininess.hi) as f32,
    };
    let texture = match bank {
        Some(bank) => {
            let index = (rng.next_u64() % bank.images.len() as u64) as usize;
            let image = &bank.images[index];
            let (crop_h, crop_w) = (config.texture_size.min(image.height()), config.texture_size.min(image.width()));
            let top = (rng.next_u64() % (image.height() - crop_h + 1) as u64) as usize;
            let left = (rng.next_u64() % (image.width() - crop_w + 1) as u64) as usize;
            TextureChoice::Image { index, top, left }
        }
        None => {
            let family = config.texture_families[(rng.next_u64() % config.texture_families.len() as u64) as usize];
            TextureChoice::Procedural { family, seed: rng.next_u64() }
        }
    };
    let noise_std = rng.uniform(config.noise_std.lo, config.noise_std.hi);
    let noise_seed = rng.next_u64();
    // Drawn last, so that a config without camera effects draws everything else as before.
    let blur = rng.uniform(config.blur.lo, config.blur.hi);
    let gamma = rng.uniform(config.gamma.lo, config.gamma.hi);
    let sheet = config.sheet.sample(rng);
    let backdrop = config.backdrop.sample(&config.texture_families, rng);
    if let Some(b) = &backdrop {
        window = b.window;
    }
    let pinhole = config.camera.sample(window, rng);
    Ok(ClipParams { surface, window, lights, material, texture, noise_std, noise_seed, blur, gamma, sheet, backdrop, pinhole, redraws: 0 })
}

/// The camera's optics and response on a rendered `size`² frame, in place:
/// a Gaussian blur of standard deviation `sigma` pixels (separable, kernel
/// radius ⌈3σ⌉, edges clamped), then `v ↦ max(v, 0)^gamma` (the
/// rasteriser's `pow4`, relative error below 2e-7 + 1.5e-7·|γ log₂ v|). `sigma = 0` and
/// `gamma = 1` leave the frame's bytes as they are.
pub fn camera_response(image: &mut [f32], size: usize, sigma: f64, gamma: f64, kernel: &mut Vec<f32>, scratch: &mut Vec<f32>) {
    if sigma > 0.0 {
        let radius = (3.0 * sigma).ceil() as isize;
        kernel.clear();
        kernel.extend((-radius..=radius).map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp() as f32));
        let total: f32 = kernel.iter().sum();
        kernel.iter_mut().for_each(|w| *w /= total);
        let at = |i: usize, k: usize| (i as isize + k as isize - radius).clamp(0, size as isize - 1) as usize;
        scratch.resize(image.len(), 0.0);
        for (row, out) in image.chunks_exact(size).zip(scratch.chunks_exact_mut(size)) {
            out.iter_mut().enumerate().for_each(|(x, o)| *o = kernel.iter().enumerate().map(|(k, w)| w * row[at(x, k)]).sum());
        }
        for y in 0..size {
            for x in 0..size {
                image[y * size + x] = kernel.iter().enumerate().map(|(k, w)| w * scratch[at(y, k) * size + x]).sum();
            }
        }
    }
    if gamma != 1.0 {
        // The rasteriser's polynomial power: the same bits on every platform.
        for chunk in image.chunks_mut(4) {
            let mut lanes = [0.0f32; 4];
            lanes[..chunk.len()].copy_from_slice(chunk);
            let powered = crate::raster::pow4(wide::f32x4::from(lanes), gamma as f32).to_array();
            chunk.iter_mut().zip(powered).for_each(|(v, p)| *v = if *v > 0.0 { p } else { 0.0 });
        }
    }
}

/// Add N(0, std²) noise (a pure function of seed, frame, pixel), clamp to
/// [0, 1], quantise to 0..=255 (round half up). Pixels 8g .. 8g + 8 take the
/// normals of words 4g .. 4g + 4 of the frame's stream.
pub fn noisy_u8(image: &[f32], std: f64, seed: u64, frame: usize, out: &mut [u8]) {
    let std = std as f32;
    let quantise = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    if std == 0.0 {
        out.iter_mut().zip(image).for_each(|(o, &v)| *o = quantise(v));
        return;
    }
    let mut stream = SplitMix64::new(hash(seed, &[frame as u64]));
    for (o, v) in out.chunks_mut(8).zip(image.chunks(8)) {
        let normals = normals8(std::array::from_fn(|_| stream.next_u64()));
        o.iter_mut().zip(v).zip(normals).for_each(|((o, &v), n)| *o = quantise(v + std * n));
    }
}

/// The texture rows and columns (of a `size²` texture) that a clip's frames
/// can sample: texture coordinates of a hit interpolate those of its grid
/// cell's corners, so those of the cells whose xy bounding box meets the view
/// window in some frame, plus the bilinear neighbour and a texel of slack.
fn sampled_texels(positions: &[[f32; 3]], grid: usize, [x0, y0, x1, y1]: [f32; 4], size: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    // Corner index bounds (column i, row j) of the cells that meet the window.
    // One bit per side of the window a vertex lies beyond: a cell's bounding
    // box meets the window unless its four corners share a bit.
    let (mut i_lo, mut i_hi, mut j_lo, mut j_hi) = (usize::MAX, 0, usize::MAX, 0);
    let mut outside = Vec::with_capacity(grid * grid);
    for frame in positions.chunks_exact(grid * grid) {
        outside.clear();
        outside.extend(frame.iter().map(|p| u8::from(p[0] < x0) | u8::from(p[0] > x1) << 1 | u8::from(p[1] < y0) << 2 | u8::from(p[1] > y1) << 3));
        for j in 0..grid - 1 {
            let (row, next) = (&outside[j * grid..(j + 1) * grid], &outside[(j + 1) * grid..(j + 2) * grid]);
            let meets = |i: usize| row[i] & row[i + 1] & next[i] & next[i + 1] == 0;
            if let (Some(first), Some(last)) = ((0..grid - 1).find(|&i| meets(i)), (0..grid - 1).rev().find(|&i| meets(i))) {
                (i_lo, i_hi, j_lo, j_hi) = (i_lo.min(first), i_hi.max(last + 1), j_lo.min(j), j_hi.max(j + 1));
            }
        }
    }
    if i_lo > i_hi {
        return (0..0, 0..0);
    }
    // Corner k has texture coordinates (i·step, 1 − j·step); `Texture::sample`
    // reads texels floor(t·size − ½) and the next one.
    let step = 1.0 / (grid - 1) as f64;
    let texels = |lo: f64, hi: f64| {
        let first = (lo * size as f64 - 0.5).floor() - 1.0;
        let last = (hi * size as f64 - 0.5).floor() + 2.0;
        first.max(0.0) as usize..(last + 1.0).clamp(0.0, size as f64) as usize
    };
    (texels(1.0 - j_hi as f64 * step, 1.0 - j_lo as f64 * step), texels(i_lo as f64 * step, i_hi as f64 * step))
}

/// Per-thread state: everything one clip needs, reused across clips.
pub struct ClipWorker {
    synth: Synthesizer,
    triangles: Vec<[u32; 3]>,
    uv: Vec<[f32; 2]>,
    positions: Vec<[f32; 3]>,
    texture: Texture,
    rasterizer: Rasterizer,
    frame: Frame,
    kernel: Vec<f32>,
    scratch: Vec<f32>,
    bender: Bender,
    local: Vec<[f64; 3]>,
    background_texture: Texture,
    background: Vec<f32>,
    /// The positions warped to where a perspective camera's rays are vertical (`View::warp`).
    warped: Vec<[f32; 3]>,
}

impl ClipWorker {
    pub fn new(config: &GeneratorConfig) -> Self {
        let grid = config.grid;
        let triangles = grid_triangles(grid as i64).expect("validated grid").chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        // Texture coordinates = undeformed position: u = (x + 1)/2, v = (1 − y)/2 (texture row 0 at the top).
        let step = 1.0 / (grid - 1) as f32;
        let uv = (0..grid * grid).map(|i| [(i % grid) as f32 * step, 1.0 - (i / grid) as f32 * step]).collect();
        Self {
            synth: Synthesizer::new(grid),
            triangles,
            uv,
            positions: vec![[0.0; 3]; clip_len(config.frames, grid) / 3],
            texture: Texture::default(),
            rasterizer: Rasterizer::default(),
            frame: Frame::default(),
            kernel: Vec::new(),
            scratch: Vec::new(),
            bender: Bender::default(),
            local: Vec::new(),
            background_texture: Texture::default(),
            background: Vec::new(),
            warped: Vec::new(),
        }
    }

    /// Whether this worker was built for `config`'s mesh and frame count.
    fn fits(&self, config: &GeneratorConfig) -> bool {
        self.synth.grid() == config.grid && self.positions.len() * 3 == clip_len(config.frames, config.grid)
    }

    /// Generate clip `index` into `video` / `depth` (T·H·W each).
    pub fn clip(&mut self, config: &GeneratorConfig, bank: Option<&TextureBank>, seed: u64, index: u64, video: &mut [u8], depth: &mut [f32]) -> Result<ClipParams> {
        self.clip_until(config, bank, seed, index, video, depth, &AtomicBool::new(false))
    }

    /// [`clip`](Self::clip), giving up with an `interrupted` error as soon as
    /// `cancel` is set (checked before every draw).
    #[allow(clippy::too_many_arguments)]
    pub fn clip_until(&mut self, config: &GeneratorConfig, bank: Option<&TextureBank>, seed: u64, index: u64, video: &mut [u8], depth: &mut [f32], cancel: &AtomicBool) -> Result<ClipParams> {
        for attempt in 0..=config.max_redraws {
            if cancel.load(Ordering::Relaxed) {
                return Err(interrupted());
            }
            let mut rng = SplitMix64::new(hash(seed, &[index, attempt as u64]));
            let mut params = draw_clip(config, bank, &mut rng)?;
            if self.try_clip(config, bank, &params, video, depth)? {
                params.redraws = attempt;
                return Ok(params);
            }
        }
        Err(InvalidArgument::new(
            "config",
            format!("clip {index}: the view window showed background (or, with a backdrop, too little of the sheet) in {} attempts; shrink window_width (backdrop_window_width) or the motion ranges", config.max_redraws + 1),
        ))
    }

    /// A sheet's vertex positions: the surface's relief (intensity scaled by
    /// `sheet.relief`) without its rigid motion, bent, then moved by `E_t`.
    fn synthesize_sheet(&mut self, surface: &SurfaceParams, sheet: &SheetParams, frames: usize) -> Result<()> {
        let relief = SurfaceParams { intensity: surface.intensity * sheet.relief, rotation: [0.0; 3], rotation_rate: [0.0; 3], drift: [0.0; 3], ..surface.clone() };
        self.synth.synthesize_into(&relief, frames, self.positions.as_flattened_mut())?;
        let vertex_count = self.synth.grid() * self.synth.grid();
        for (f, frame) in self.positions.chunks_exact_mut(vertex_count).enumerate() {
            let t = frame_time(f, frames);
            self.local.clear();
            self.local.extend(frame.iter().map(|p| p.map(f64::from)));
            self.bender.bend_frame(sheet, t, &mut self.local);
            let (rotation, translation) = rigid_motion(surface, t);
            for (out, p) in frame.iter_mut().zip(&self.local) {
                let world = rotation * nalgebra::Vector3::new(p[0], p[1], p[2]) + translation;
                *out = [world.x as f32, world.y as f32, world.z as f32];
            }
        }
        Ok(())
    }

    /// Render one drawn clip; false if the window shows background anywhere.
    fn try_clip(&mut self, config: &GeneratorConfig, bank: Option<&TextureBank>, p: &ClipParams, video: &mut [u8], depth: &mut [f32]) -> Result<bool> {
        let (frames, grid) = (config.frames, config.grid);
        match &p.sheet {
            None => self.synth.synthesize_into(&p.surface, frames, self.positions.as_flattened_mut())?,
            Some(sheet) => self.synthesize_sheet(&p.surface, sheet, frames)?,
        }
        let view = clip_view(config, p)?;
        if let Some(pinhole) = p.pinhole {
            // A surface point nearer the pinhole than half the window's plane is a close-up no real footage of a sheet shows.
            if self.positions.iter().any(|v| v[2] > pinhole.camera_z / 2.0) {
                return Ok(false);
            }
            self.warped.clear();
            self.warped.extend(self.positions.iter().map(|&v| view.warp(v)));
        }
        match &p.texture {
            TextureChoice::Procedural { family, seed } => {
                let seen = if p.pinhole.is_some() { &self.warped } else { &self.positions };
                let region = sampled_texels(seen, grid, p.window, config.texture_size);
                procedural_region(*family, *seed, config.texture_size, region, &mut self.texture)
            }
            TextureChoice::Image { index, top, left } => {
                let bank = bank.expect("image texture without a bank");
                let image = &bank.images[*index];
                bank.crop(*index, *top, *left, config.texture_size.min(image.height()).min(image.width()), &mut self.texture)
            }
        }
        let scene = Scene { view, supersample: config.supersample, lights: &p.lights, material: p.material, texture: &self.texture, shading: config.shading };
        let (vertex_count, frame_len) = (grid * grid, config.frame_len());
        if let Some(b) = &p.backdrop {
            b.background_into(config.size, &mut self.background_texture, &mut self.background);
        }
        for f in 0..frames {
            let vertices = &self.positions[f * vertex_count..(f + 1) * vertex_count];
            self.rasterizer.render_into(vertices, &self.triangles, &self.uv, &scene, &mut self.frame);
            match p.backdrop {
                None if self.frame.coverage.iter().any(|&c| c < 1.0) || self.frame.depth.iter().any(|d| d.is_nan()) => return Ok(false),
                None => {}
                Some(_) if !covers(&self.frame.depth, config.backdrop.min_cover) => return Ok(false),
                Some(_) => composite(&mut self.frame.image, &self.frame.coverage, &self.background),
            }
            depth[f * frame_len..(f + 1) * frame_len].copy_from_slice(&self.frame.depth);
            camera_response(&mut self.frame.image, config.size, p.blur, p.gamma, &mut self.kernel, &mut self.scratch);
            noisy_u8(&self.frame.image, p.noise_std, p.noise_seed, f, &mut video[f * frame_len..(f + 1) * frame_len]);
        }
        Ok(true)
    }
}

/// The view of a drawn clip: its window, seen by its camera.
pub fn clip_view(config: &GeneratorConfig, p: &ClipParams) -> Result<View> {
    let view = View::new(config.size, config.size, p.window, CAMERA_Z)?;
    match p.pinhole {
        None => Ok(view),
        Some(pinhole) => View { camera_z: pinhole.camera_z, ..view }.with_pinhole(pinhole.xy),
    }
}

/// The error of work stopped by its `cancel` flag.
pub fn interrupted() -> InvalidArgument {
    InvalidArgument::new("interrupted", "stopped before the clips were complete")
}

/// Clips `start .. start + n` into `video` (n·T·H·W u8) and `depth` (same, f32),
/// in parallel over clips.
pub fn generate_clips(config: &GeneratorConfig, bank: Option<&TextureBank>, seed: u64, start: u64, n: usize, video: &mut [u8], depth: &mut [f32]) -> Result<Vec<ClipParams>> {
    generate_clips_until(config, bank, seed, start, n, video, depth, None, &AtomicBool::new(false))
}

/// [`generate_clips`], giving up with an `interrupted` error soon after
/// `cancel` is set (every clip checks it before each draw), so a caller can
/// honour Ctrl-C during a long or hopeless batch; with `vertices`
/// (n·T·grid·grid·3), also each clip's mesh in world coordinates (T, grid,
/// grid, 3): vertex (j, k) is the undeformed point (`grid_coordinate(k)`,
/// `grid_coordinate(j)`, 0), so a vertex keeps its index in every frame.
#[allow(clippy::too_many_arguments)]
pub fn generate_clips_until(config: &GeneratorConfig, bank: Option<&TextureBank>, seed: u64, start: u64, n: usize, video: &mut [u8], depth: &mut [f32], vertices: Option<&mut [f32]>, cancel: &AtomicBool) -> Result<Vec<ClipParams>> {
    config.validate()?;
    if n > 0 && start.checked_add(n as u64 - 1).is_none() {
        return Err(InvalidArgument::new("start", format!("clips {start} .. {start} + {n} pass the last clip index 2**64 − 1")));
    }
    let len = config.clip_pixels();
    if video.len() != n * len || depth.len() != n * len {
        return Err(InvalidArgument::new("out", format!("expected {} values per output, got {} and {}", n * len, video.len(), depth.len())));
    }
    let mesh_len = clip_len(config.frames, config.grid);
    let meshes: Vec<Option<&mut [f32]>> = match vertices {
        Some(v) if v.len() != n * mesh_len => return Err(InvalidArgument::new("vertices", format!("expected {} values, got {}", n * mesh_len, v.len()))),
        Some(v) => v.chunks_mut(mesh_len.max(1)).map(Some).collect(),
        None => (0..n).map(|_| None).collect(),
    };
    if n == 0 {
        return Ok(Vec::new());
    }
    video
        .par_chunks_mut(len)
        .zip(depth.par_chunks_mut(len))
        .zip(meshes)
        .enumerate()
        .map(|(i, ((v, d), mesh))| {
            with_worker(config, |worker| {
                let params = worker.clip_until(config, bank, seed, start + i as u64, v, d, cancel)?;
                if let Some(mesh) = mesh {
                    mesh.copy_from_slice(worker.positions.as_flattened());
                }
                Ok(params)
            })
        })
        .collect()
}

thread_local! {
    /// This thread's clip worker, kept between clips and batches: rayon
    /// splits a batch into about one job per two clips, and a worker built
    /// per job (FFT plan, mesh, buffers first touched) cost ~0.1 ms a clip.
    static WORKER: std::cell::RefCell<Option<ClipWorker>> = const { std::cell::RefCell::new(None) };
}

/// Run `f` with this thread's clip worker for `config` (built on first use
/// or when the config's mesh or frame count changed; a fresh one if the
/// thread's is busy further up its stack).
fn with_worker<T>(config: &GeneratorConfig, f: impl FnOnce(&mut ClipWorker) -> T) -> T {
    WORKER.with(|cell| match cell.try_borrow_mut() {
        Ok(mut slot) => {
            let worker = match slot.take() {
                Some(worker) if worker.fits(config) => worker,
                _ => ClipWorker::new(config),
            };
            f(slot.insert(worker))
        }
        Err(_) => f(&mut ClipWorker::new(config)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> GeneratorConfig {
        GeneratorConfig { frames: 4, size: 24, grid: 24, texture_size: 64, ..GeneratorConfig::default() }
    }

    /// `small` seen by wide-angle perspective cameras, crops of their frames and whole frames.
    fn perspective() -> GeneratorConfig {
        GeneratorConfig { camera: CameraConfig { fov: Range::new(0.6, 1.3), crop_share: Range::new(0.3, 1.0), probability: 1.0 }, ..small() }
    }

    fn run(config: &GeneratorConfig, seed: u64, start: u64, n: usize) -> (Vec<u8>, Vec<f32>, Vec<ClipParams>) {
        let len = config.clip_pixels();
        let (mut video, mut depth) = (vec![0u8; n * len], vec![0f32; n * len]);
        let params = generate_clips(config, None, seed, start, n, &mut video, &mut depth).unwrap();
        (video, depth, params)
    }

    #[test]
    fn clips_have_no_background_and_depend_only_on_their_index() {
        let config = small();
        let (video, depth, params) = run(&config, 3, 0, 6);
        assert!(depth.iter().all(|d| d.is_finite()));
        assert!(video.iter().any(|&v| v > 0));
        // Clip 4 alone (start = 4) equals clip 4 of the batch.
        let (v4, d4, p4) = run(&config, 3, 4, 1);
        let len = config.clip_pixels();
        assert_eq!(&video[4 * len..5 * len], &v4[..]);
        assert!(depth[4 * len..5 * len].iter().zip(&d4).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(params[4], p4[0]);
    }

    #[test]
    fn a_thread_reuses_its_worker_across_batches_and_configs_without_changing_a_byte() {
        // One thread, so that every batch runs on the same worker slot.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let (a, b) = (small(), GeneratorConfig { grid: 17, frames: 3, size: 20, texture_size: 32, ..small() });
        let fresh: Vec<_> = [&a, &b].map(|config| {
            let len = config.clip_pixels();
            let (mut video, mut depth) = (vec![0u8; 2 * len], vec![0f32; 2 * len]);
            for i in 0..2 {
                // A worker of its own per clip: nothing carried over.
                ClipWorker::new(config).clip(config, None, 9, i as u64, &mut video[i * len..(i + 1) * len], &mut depth[i * len..(i + 1) * len]).unwrap();
            }
            (video, depth.iter().map(|d| d.to_bits()).collect::<Vec<u32>>())
        }).into();
        // a, b, a again: the worker is rebuilt for b and for a, and reused within each batch.
        for (config, expected) in [(&a, &fresh[0]), (&b, &fresh[1]), (&a, &fresh[0])] {
            let (video, depth, _) = pool.install(|| run(config, 9, 0, 2));
            assert_eq!((&video, &depth.iter().map(|d| d.to_bits()).collect::<Vec<u32>>()), (&expected.0, &expected.1));
        }
    }

    #[test]
    fn clip_depth_is_the_ray_casters() {
        // The renderer's centre depth replaces a BVH pass per frame: check it
        // against the ray caster, bit for bit at s = 2, to rounding at s = 3.
        // Strong folding compresses cells into slivers, where pixel centres
        // and subsamples part ways.
        let folded = |supersample| {
            let mut config = GeneratorConfig { supersample, max_redraws: 200, ..small() };
            config.surface.folding = Range::new(2.0, 2.0);
            config.surface.intensity = Range::new(0.8, 1.0);
            config
        };
        for (config, tolerance) in [(GeneratorConfig { supersample: 2, ..small() }, 0.0f32), (folded(2), 0.0), (GeneratorConfig { supersample: 3, ..small() }, 2e-6), (perspective(), 0.0)] {
            let (_, depth, params) = run(&config, 5, 0, 3);
            let triangles: Vec<[u32; 3]> = grid_triangles(config.grid as i64).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            for (clip, p) in params.iter().enumerate() {
                let positions = crate::synthesis::synthesize(&p.surface, config.frames, config.grid).unwrap();
                assert_eq!(p.pinhole.is_some(), config.camera.fov.hi > 0.0);
                let view = clip_view(&config, p).unwrap();
                for (f, frame) in positions.chunks_exact(config.grid * config.grid * 3).enumerate() {
                    let vertices: Vec<[f32; 3]> = frame.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                    let cast = crate::bvh::raycast_depth(&vertices, &triangles, &view).unwrap();
                    let rendered = &depth[(clip * config.frames + f) * config.frame_len()..][..config.frame_len()];
                    for (a, b) in rendered.iter().zip(&cast) {
                        assert!((a - b).abs() <= tolerance, "s {} clip {clip} frame {f}: {a} vs {b}", config.supersample);
                    }
                }
            }
        }
    }

    #[test]
    fn clips_equal_their_parameters_rendered_by_the_generic_renderer_with_the_whole_texture() {
        // A clip computes only the texels its frames can sample: the bytes
        // must be those of the whole texture, folds and all.
        let mut folded = small();
        folded.surface.folding = Range::new(2.0, 2.0);
        folded.surface.intensity = Range::new(0.8, 1.0);
        // The generic `render` also computes every vertex normal, where a
        // clip computes only those of the triangles that light a pixel.
        let gouraud = GeneratorConfig { shading: Shading::Gouraud, ..small() };
        let wide = GeneratorConfig { texture_size: 128, ..perspective() };
        let wide_gouraud = GeneratorConfig { shading: Shading::Gouraud, ..perspective() };
        for config in [GeneratorConfig { texture_size: 128, ..small() }, folded, gouraud, wide, wide_gouraud] {
            let (video, _, params) = run(&config, 8, 0, 4);
            let worker = ClipWorker::new(&config);
            let mut partial = 0;
            for (clip, p) in params.iter().enumerate() {
                let TextureChoice::Procedural { family, seed } = p.texture else { unreachable!() };
                let mut texture = Texture::default();
                crate::textures::procedural(family, seed, config.texture_size, &mut texture);
                let positions: Vec<[f32; 3]> = crate::synthesis::synthesize(&p.surface, config.frames, config.grid).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                let view = clip_view(&config, p).unwrap();
                let warped: Vec<[f32; 3]> = positions.iter().map(|&v| view.warp(v)).collect();
                let (rows, cols) = sampled_texels(&warped, config.grid, p.window, config.texture_size);
                partial += usize::from(rows.len() * cols.len() < config.texture_size.pow(2));
                let scene = Scene { view, supersample: config.supersample, lights: &p.lights, material: p.material, texture: &texture, shading: config.shading };
                for (f, vertices) in positions.chunks_exact(config.grid * config.grid).enumerate() {
                    let frame = crate::raster::render(vertices, &worker.triangles, &worker.uv, &scene).unwrap();
                    let mut expected = vec![0u8; config.frame_len()];
                    noisy_u8(&frame.image, p.noise_std, p.noise_seed, f, &mut expected);
                    assert_eq!(&video[(clip * config.frames + f) * config.frame_len()..][..config.frame_len()], &expected[..], "clip {clip} frame {f}");
                }
            }
            assert!(partial > 0, "no clip used a partial texture");
        }
    }

    #[test]
    fn a_backdrop_clip_is_the_rendered_sheet_over_its_background_with_depth_only_on_the_sheet() {
        let config = GeneratorConfig { backdrop: BackdropConfig { probability: 1.0, ..BackdropConfig::default() }, ..small() };
        let (video, depth, params) = run(&config, 4, 0, 6);
        let worker = ClipWorker::new(&config);
        let (mut off_sheet, mut background_texture, mut background) = (0, Texture::default(), Vec::new());
        for (clip, p) in params.iter().enumerate() {
            let b = p.backdrop.as_ref().expect("probability 1 draws a backdrop");
            assert_eq!(p.window, b.window);
            b.background_into(config.size, &mut background_texture, &mut background);
            let TextureChoice::Procedural { family, seed } = p.texture else { unreachable!() };
            let mut texture = Texture::default();
            crate::textures::procedural(family, seed, config.texture_size, &mut texture);
            let positions: Vec<[f32; 3]> = crate::synthesis::synthesize(&p.surface, config.frames, config.grid).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let view = View::new(config.size, config.size, p.window, CAMERA_Z).unwrap();
            let scene = Scene { view, supersample: config.supersample, lights: &p.lights, material: p.material, texture: &texture, shading: config.shading };
            for (f, vertices) in positions.chunks_exact(config.grid * config.grid).enumerate() {
                let at = (clip * config.frames + f) * config.frame_len();
                let mut frame = crate::raster::render(vertices, &worker.triangles, &worker.uv, &scene).unwrap();
                composite(&mut frame.image, &frame.coverage, &background);
                let mut expected = vec![0u8; config.frame_len()];
                noisy_u8(&frame.image, p.noise_std, p.noise_seed, f, &mut expected);
                assert_eq!(&video[at..][..config.frame_len()], &expected[..], "clip {clip} frame {f}");
                let cast = crate::bvh::raycast_depth(vertices, &worker.triangles, &view).unwrap();
                let rendered = &depth[at..][..config.frame_len()];
                assert!(rendered.iter().zip(&cast).all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())), "clip {clip} frame {f}");
                assert!(covers(rendered, config.backdrop.min_cover), "clip {clip} frame {f} shows too little of the sheet");
                off_sheet += rendered.iter().filter(|d| d.is_nan()).count();
            }
        }
        assert!(off_sheet > 0, "no clip showed the border");
    }

    #[test]
    fn a_window_too_large_is_redrawn_and_counted_or_refused() {
        let mut config = small();
        config.window_width = Range::new(1.7, 1.7);
        config.max_redraws = 2000;
        let (_, depth, params) = run(&config, 1, 0, 2);
        assert!(depth.iter().all(|d| d.is_finite()));
        assert!(params.iter().map(|p| p.redraws).sum::<usize>() > 0);
        config.window_width = Range::new(2.0, 2.0);
        config.max_redraws = 3;
        let len = config.clip_pixels();
        let err = generate_clips(&config, None, 0, 0, 1, &mut vec![0; len], &mut vec![0.0; len]).unwrap_err();
        assert_eq!(err.name, "config");
    }

    #[test]
    fn camera_blur_is_a_unit_gaussian_and_the_response_a_power() {
        let (size, sigma) = (41, 2.5);
        let (mut kernel, mut scratch) = (Vec::new(), Vec::new());
        let mut image = vec![0.0f32; size * size];
        image[20 * size + 20] = 1.0;
        camera_response(&mut image, size, sigma, 1.0, &mut kernel, &mut scratch);
        let total: f64 = image.iter().map(|&v| v as f64).sum();
        let variance: f64 = image.iter().enumerate().map(|(i, &v)| v as f64 * ((i % size) as f64 - 20.0).powi(2)).sum::<f64>() / total;
        assert!((total - 1.0).abs() < 1e-5, "the blur keeps the energy: {total}");
        // The kernel is cut at 3σ: its variance falls short of σ² by about 1 %.
        assert!((variance / (sigma * sigma) - 1.0).abs() < 0.02, "variance {variance} vs {}", sigma * sigma);
        assert_eq!(image[20 * size + 17], image[17 * size + 20], "the same along both axes");
        let mut constant = vec![0.3f32; size * size];
        camera_response(&mut constant, size, sigma, 2.0, &mut kernel, &mut scratch);
        assert!(constant.iter().all(|&v| (v - 0.09).abs() < 1e-6), "edges clamped, then v²");
        let mut ramp: Vec<f32> = (0..size * size).map(|i| i as f32 / (size * size) as f32 - 0.01).collect();
        camera_response(&mut ramp, size, 0.0, 0.45, &mut kernel, &mut scratch);
        for (i, &v) in ramp.iter().enumerate() {
            let x = (i as f64 / (size * size) as f64 - 0.01).max(0.0);
            assert!((v as f64 - x.powf(0.45)).abs() <= 1e-6 * x.powf(0.45) + 1e-30, "pixel {i}: {v} vs {}", x.powf(0.45));
        }
        let frame: Vec<f32> = (0..size * size).map(|i| (i as f32 * 0.618).fract()).collect();
        let mut same = frame.clone();
        camera_response(&mut same, size, 0.0, 1.0, &mut kernel, &mut scratch);
        assert_eq!(same, frame, "no blur and a linear response leave the bits");
    }

    #[test]
    fn noise_has_the_drawn_standard_deviation() {
        let image = vec![0.5f32; 200 * 200];
        let mut out = vec![0u8; image.len()];
        for std in [0.01, 0.05] {
            noisy_u8(&image, std, 9, 2, &mut out);
            let vals: Vec<f64> = out.iter().map(|&v| v as f64 / 255.0 - 0.5).collect();
            let mean = vals.iter().sum::<f64>() / vals.len() as f64;
            let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / vals.len() as f64;
            // Quantisation adds a uniform error of variance (1/255)²/12.
            let expected = std * std + 1.0 / (12.0 * 255.0 * 255.0);
            assert!((var / expected - 1.0).abs() < 0.05, "std {std}: var {var} vs {expected}");
            assert!(mean.abs() < 3.0 * std / 200.0 + 0.002);
            // The two normals of a Box–Muller pair, on neighbouring pixels, are uncorrelated.
            let pairs = vals.chunks_exact(2).map(|p| (p[0] - mean) * (p[1] - mean)).sum::<f64>() / (vals.len() / 2) as f64;
            assert!((pairs / var).abs() < 0.03, "neighbour correlation {}", pairs / var);
        }
    }

    /// Azimuth of a light in image coordinates (0 = image-up, +π/2 = image-right).
    fn azimuth(light: &Light) -> f64 {
        (light.vector[0] as f64).atan2(light.vector[1] as f64)
    }

    #[test]
    fn a_relief_and_its_mirror_under_mirrored_lights_render_alike() {
        // The ambiguity the light prior breaks: z ↦ −z with every directional
        // light's azimuth turned by π gives the same image, to rounding.
        let config = GeneratorConfig { point_light_probability: 0.0, light_azimuth: Range::new(-std::f64::consts::PI, std::f64::consts::PI), ..small() };
        let (_, _, params) = run(&config, 21, 0, 4);
        let worker = ClipWorker::new(&config);
        let mut largest_change = 0.0f32;
        for p in &params {
            let TextureChoice::Procedural { family, seed } = p.texture else { unreachable!() };
            let mut texture = Texture::default();
            crate::textures::procedural(family, seed, config.texture_size, &mut texture);
            let mirrored: Vec<Light> = p.lights.iter().map(|l| Light { vector: [-l.vector[0], -l.vector[1], l.vector[2]], ..*l }).collect();
            let view = View::new(config.size, config.size, p.window, CAMERA_Z).unwrap();
            let scene = Scene { view, supersample: config.supersample, lights: &p.lights, material: p.material, texture: &texture, shading: config.shading };
            let scene_mirrored = Scene { lights: &mirrored, ..scene };
            let positions = crate::synthesis::synthesize(&p.surface, config.frames, config.grid).unwrap();
            for frame in positions.chunks_exact(config.grid * config.grid * 3) {
                let vertices: Vec<[f32; 3]> = frame.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                let negated: Vec<[f32; 3]> = vertices.iter().map(|v| [v[0], v[1], -v[2]]).collect();
                let a = crate::raster::render(&vertices, &worker.triangles, &worker.uv, &scene).unwrap();
                let b = crate::raster::render(&negated, &worker.triangles, &worker.uv, &scene_mirrored).unwrap();
                let c = crate::raster::render(&negated, &worker.triangles, &worker.uv, &scene).unwrap();
                for ((x, y), z) in a.image.iter().zip(&b.image).zip(&c.image) {
                    assert!((x - y).abs() < 1e-4, "mirrored relief and lights: {x} vs {y}");
                    largest_change = largest_change.max((x - z).abs());
                }
            }
        }
        // Without the mirrored lights the negated relief does look different.
        assert!(largest_change > 0.05, "the relief's sign shows nowhere: {largest_change}");
    }

    #[test]
    fn the_default_prior_lights_from_above_and_excludes_every_mirrored_light() {
        let config = small();
        let (lo, hi) = (config.light_azimuth.lo, config.light_azimuth.hi);
        assert!(hi - lo < std::f64::consts::PI, "a prior wider than π holds some light and its mirror");
        let mut rng = SplitMix64::new(5);
        let (mut lights, mut mirrors_inside, mut left, mut right) = (0, 0, 0, 0);
        for _ in 0..2000 {
            for light in draw_clip(&config, None, &mut rng).unwrap().lights {
                let a = azimuth(&light);
                assert!((lo - 1e-6..=hi + 1e-6).contains(&a), "azimuth {a} outside ({lo}, {hi})");
                let mirrored = (a + std::f64::consts::PI + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
                mirrors_inside += usize::from((lo..=hi).contains(&mirrored));
                lights += 1;
                (left, right) = (left + usize::from(a < -0.5), right + usize::from(a > 0.5));
            }
        }
        assert_eq!(mirrors_inside, 0);
        assert!(lights > 3000 && left > lights / 5 && right > lights / 5, "{lights} lights, {left} left, {right} right");
        // The uniform setting stays one field away and does reach below.
        let uniform = GeneratorConfig { light_azimuth: Range::new(-std::f64::consts::PI, std::f64::consts::PI), ..small() };
        let below = (0..500).flat_map(|_| draw_clip(&uniform, None, &mut rng).unwrap().lights).filter(|l| azimuth(l).abs() > 2.0).count();
        assert!(below > 100, "{below}");
    }

    #[test]
    fn a_cancelled_batch_stops_and_an_index_past_the_last_is_refused() {
        // A window that never fits would redraw for a long time: cancel stops it.
        let config = GeneratorConfig { window_width: Range::new(2.0, 2.0), window_offset: Range::new(1.0, 1.0), max_redraws: 1_000_000, ..small() };
        let len = config.clip_pixels();
        let cancel = AtomicBool::new(false);
        let started = std::time::Instant::now();
        let err = std::thread::scope(|s| {
            s.spawn(|| {
                std::thread::sleep(std::time::Duration::from_millis(50));
                cancel.store(true, Ordering::Relaxed);
            });
            generate_clips_until(&config, None, 0, 0, 2, &mut vec![0; 2 * len], &mut vec![0.0; 2 * len], None, &cancel).unwrap_err()
        });
        assert_eq!(err.name, "interrupted");
        assert!(started.elapsed().as_secs() < 10);
        let config = small();
        let len = config.clip_pixels();
        let err = generate_clips(&config, None, 0, u64::MAX, 2, &mut vec![0; 2 * len], &mut vec![0.0; 2 * len]).unwrap_err();
        assert_eq!(err.name, "start");
        generate_clips(&config, None, 0, u64::MAX, 1, &mut vec![0; len], &mut vec![0.0; len]).unwrap();
    }

    #[test]
    fn bad_config_is_named() {
        let mut config = small();
        config.size = 0;
        let err = generate_clips(&config, None, 0, 0, 1, &mut [], &mut []).unwrap_err();
        assert_eq!(err.name, "config.size");
        let config = small();
        let len = config.clip_pixels();
        let err = generate_clips_until(&config, None, 0, 0, 1, &mut vec![0; len], &mut vec![0.0; len], Some(&mut []), &AtomicBool::new(false)).unwrap_err();
        assert_eq!(err.name, "vertices");
        let mut config = small();
        config.light_count = (3, 2);
        assert_eq!(config.validate().unwrap_err().name, "config.light_count");
        for azimuth in [Range::new(1.0, -1.0), Range::new(-7.0, 0.0), Range::new(-4.0, 4.0)] {
            let config = GeneratorConfig { light_azimuth: azimuth, ..small() };
            assert!(config.validate().unwrap_err().name.starts_with("config.light_azimuth"), "{azimuth:?}");
        }
    }
}
