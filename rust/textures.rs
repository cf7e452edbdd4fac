//! Albedo textures: five procedural families with random parameters, and
//! random crops of a user's image folder (the paper used 256×256 crops of DTD).
//!
//! A texture is a grayscale `Texture` (row-major, values in [0, 1]) of
//! `size × size` texels spanning the whole undeformed patch. Every procedural
//! texture is a pure function of (family, seed, size); spatial coordinates
//! below are in texture widths, (0, 0) top-left, periodic where noted.

use std::path::{Path, PathBuf};

use crate::error::{InvalidArgument, Result};
use crate::geometry::floor_fast;
use crate::raster::Texture;
use crate::rng::{hash, mix64, unit_f64, SplitMix64};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureFamily {
    /// Fractal (fBm) value noise, sometimes folded into marble veins.
    Fractal,
    /// Sums of one to three oriented sinusoids (Gabor-like), domain-warped.
    Stripes,
    /// Checkerboards and plaids of random period, orientation and duty cycle.
    Plaid,
    /// Cellular (Worley) spots or cell walls.
    Cells,
    /// Woven fabric: plain or twill over-under threads with fibre noise.
    Weave,
}

pub const FAMILIES: [TextureFamily; 5] = [TextureFamily::Fractal, TextureFamily::Stripes, TextureFamily::Plaid, TextureFamily::Cells, TextureFamily::Weave];

impl TextureFamily {
    pub fn name(self) -> &'static str {
        match self {
            Self::Fractal => "fractal",
            Self::Stripes => "stripes",
            Self::Plaid => "plaid",
            Self::Cells => "cells",
            Self::Weave => "weave",
        }
    }

    pub fn from_name(name: &str) -> Result<Self> {
        FAMILIES.into_iter().find(|f| f.name() == name).ok_or_else(|| {
            let names: Vec<_> = FAMILIES.iter().map(|f| f.name()).collect();
            InvalidArgument::new("texture_families", format!("unknown family {name:?}; expected one of {names:?}"))
        })
    }
}

#[inline]
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Periodic fBm value noise into `out` (size², row-major), roughly in [0, 1].
fn fbm(seed: u64, size: usize, base_cells: usize, octaves: usize, persistence: f32, out: &mut [f32]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    let mut amplitude = 1.0f32;
    let mut total = 0.0f32;
    let mut lattice = Vec::new();
    let mut weights = Vec::with_capacity(size);
    for octave in 0..octaves {
        let cells = base_cells << octave;
        lattice.clear();
        for j in 0..cells {
            for i in 0..cells {
                lattice.push(unit_f64(hash(seed, &[octave as u64, j as u64, i as u64])) as f32);
            }
        }
        // Cell index and smoothstep weight of every texel column (= row) coordinate.
        weights.clear();
        for x in 0..size {
            let p = (x as f32 + 0.5) / size as f32 * cells as f32;
            let i = floor_fast(p) as usize % cells;
            let f = p - floor_fast(p);
            weights.push((i, (i + 1) % cells, f * f * (3.0 - 2.0 * f)));
        }
        for (y, row) in out.chunks_exact_mut(size).enumerate() {
            let (j0, j1, fy) = weights[y];
            let (l0, l1) = (&lattice[j0 * cells..(j0 + 1) * cells], &lattice[j1 * cells..(j1 + 1) * cells]);
            for (v, &(i0, i1, fx)) in row.iter_mut().zip(&weights) {
                let top = l0[i0] + (l0[i1] - l0[i0]) * fx;
                let bottom = l1[i0] + (l1[i1] - l1[i0]) * fx;
                *v += amplitude * (top + (bottom - top) * fy);
            }
        }
        total += amplitude;
        amplitude *= persistence;
    }
    out.iter_mut().for_each(|v| *v /= total);
}

fn normalize_range(data: &mut [f32]) {
    let (lo, hi) = data.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let span = hi - lo;
    if span > 0.0 {
        data.iter_mut().for_each(|v| *v = (*v - lo) / span);
    } else {
        data.iter_mut().for_each(|v| *v = 0.5);
    }
}

/// A procedural texture of `family`; a pure function of (family, seed, size).
pub fn procedural(family: TextureFamily, seed: u64, size: usize, texture: &mut Texture) {
    let n = size * size;
    texture.height = size;
    texture.width = size;
    texture.data.clear();
    texture.data.resize(n, 0.0);
    let mut rng = SplitMix64::new(hash(seed, &[family as u64]));
    let coords = |k: usize| ((k % size) as f32 + 0.5) / size as f32;
    let data = &mut texture.data;
    match family {
        TextureFamily::Fractal => {
            let base = 2 + (rng.next_u64() % 5) as usize;
            let persistence = rng.uniform(0.35, 0.7) as f32;
            fbm(rng.next_u64(), size, base, 5, persistence, data);
            if rng.unit() < 0.35 {
                // Marble: veins where a sinusoid of the noise crosses zero.
                let k = rng.uniform(4.0, 14.0) as f32;
                data.iter_mut().for_each(|v| *v = (0.5 + 0.5 * (k * *v * std::f32::consts::TAU).sin()).powf(0.7));
            }
        }
        TextureFamily::Stripes => {
            let waves = 1 + (rng.next_u64() % 3) as usize;
            let params: Vec<(f32, f32, f32, f32)> = (0..waves)
                .map(|_| {
                    let angle = rng.uniform(0.0, std::f64::consts::PI) as f32;
                    let freq = rng.log_uniform(3.0, 24.0) as f32;
                    (angle.cos() * freq, angle.sin() * freq, rng.uniform(0.0, 6.3) as f32, rng.uniform(0.4, 1.0) as f32)
                })
                .collect();
            let warp = rng.uniform(0.0, 1.5) as f32;
            let mut noise = vec![0.0; n];
            fbm(rng.next_u64(), size, 3, 3, 0.5, &mut noise);
            for (k, v) in data.iter_mut().enumerate() {
                let (x, y) = (coords(k), coords(k / size));
                *v = params.iter().map(|&(fx, fy, ph, a)| a * (std::f32::consts::TAU * (fx * x + fy * y) + ph + warp * 6.0 * noise[k]).sin()).sum();
            }
        }
        TextureFamily::Plaid => {
            let angle = rng.uniform(0.0, std::f64::consts::PI) as f32;
            let (c, s) = (angle.cos(), angle.sin());
            let freq = rng.log_uniform(3.0, 16.0) as f32;
            let checks = rng.unit() < 0.5;
            let duty = [rng.uniform(-0.6, 0.6) as f32, rng.uniform(-0.6, 0.6) as f32];
            let levels = [rng.unit() as f32, rng.unit() as f32, rng.uniform(0.3, 0.8) as f32];
            // Edge softness of about one texel, so the pattern is anti-aliased.
            let soft = std::f32::consts::TAU * freq / size as f32;
            for (k, v) in data.iter_mut().enumerate() {
                let (x, y) = (coords(k), coords(k / size));
                let (u, w) = (c * x + s * y, -s * x + c * y);
                let a = smoothstep(-soft, soft, (std::f32::consts::TAU * freq * u).sin() - duty[0]);
                let b = smoothstep(-soft, soft, (std::f32::consts::TAU * freq * w).sin() - duty[1]);
                *v = if checks { a * b + (1.0 - a) * (1.0 - b) } else { levels[2] * (levels[0] * a + levels[1] * b) + (1.0 - levels[2]) * a * b };
            }
        }
        TextureFamily::Cells => {
            let cells = 4 + (rng.next_u64() % 11) as usize;
            let radius = rng.uniform(0.2, 0.6) as f32;
            let walls = rng.unit() < 0.4;
            let cell_seed = rng.next_u64();
            // Feature point offset and tone of every cell (periodic).
            let features: Vec<(f32, f32, f32)> = (0..cells * cells)
                .map(|k| {
                    let h = hash(cell_seed, &[(k % cells) as u64, (k / cells) as u64]);
                    (unit_f64(h) as f32, unit_f64(h.rotate_left(32)) as f32, unit_f64(mix64(h)) as f32)
                })
                .collect();
            let point = |i: i64, j: i64| {
                let (ox, oy, tone) = features[j.rem_euclid(cells as i64) as usize * cells + i.rem_euclid(cells as i64) as usize];
                (i as f32 + ox, j as f32 + oy, tone)
            };
            for (k, v) in data.iter_mut().enumerate() {
                let (x, y) = (coords(k) * cells as f32, coords(k / size) * cells as f32);
                let (ci, cj) = (floor_fast(x) as i64, floor_fast(y) as i64);
                let (mut d1, mut d2, mut tone) = (f32::INFINITY, f32::INFINITY, 0.0);
                for dj in -1..=1 {
                    for di in -1..=1 {
                        let (px, py, t) = point(ci + di, cj + dj);
                        let d = (px - x).powi(2) + (py - y).powi(2);
                        if d < d1 {
                            d2 = d1;
                            d1 = d;
                            tone = t;
                        } else if d < d2 {
                            d2 = d;
                        }
                    }
                }
                let (d1, d2) = (d1.sqrt(), d2.sqrt());
                *v = if walls { smoothstep(0.0, 0.15, d2 - d1) * (0.5 + 0.5 * tone) } else { smoothstep(radius, radius * 0.7, d1) * (0.4 + 0.6 * tone) };
            }
        }
        TextureFamily::Weave => {
            let threads = 8 + (rng.next_u64() % 25) as usize;
            let twill = rng.unit() < 0.5;
            let (warp_tone, weft_tone) = (rng.uniform(0.3, 1.0) as f32, rng.uniform(0.3, 1.0) as f32);
            let mut fibre = vec![0.0; n];
            fbm(rng.next_u64(), size, 16, 3, 0.6, &mut fibre);
            for (k, v) in data.iter_mut().enumerate() {
                let (u, w) = (coords(k) * threads as f32, coords(k / size) * threads as f32);
                let (iu, iw) = (floor_fast(u) as i64, floor_fast(w) as i64);
                let warp_on_top = if twill { (iu + iw).rem_euclid(4) < 2 } else { (iu + iw).rem_euclid(2) == 0 };
                // Thread cross-section: bright in the middle, dark at the gaps.
                let (profile, tone) = if warp_on_top { ((std::f32::consts::PI * (u - floor_fast(u))).sin(), warp_tone) } else { ((std::f32::consts::PI * (w - floor_fast(w))).sin(), weft_tone) };
                *v = tone * profile.sqrt() * (0.75 + 0.5 * fibre[k]);
            }
        }
    }
    normalize_range(data);
    let (lo, hi) = (rng.uniform(0.0, 0.35) as f32, rng.uniform(0.6, 1.0) as f32);
    data.iter_mut().for_each(|v| *v = lo + (hi - lo) * *v);
}

/// Grayscale images of a folder, decoded once, for random crops.
#[derive(Clone, Debug, Default)]
pub struct TextureBank {
    pub paths: Vec<PathBuf>,
    pub images: Vec<Texture>,
}

const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "jpe"];

impl TextureBank {
    /// Every PNG/JPEG file of `dir` (sorted by name, not recursive), each
    /// upscaled if needed so that its shorter side is at least `crop` texels.
    pub fn load_dir(dir: &Path, crop: usize) -> Result<Self> {
        let err = |m: String| InvalidArgument::new("textures", m);
        let entries = std::fs::read_dir(dir).map_err(|e| err(format!("cannot read folder {}: {e}", dir.display())))?;
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && p.extension().and_then(|x| x.to_str()).is_some_and(|x| IMAGE_EXTENSIONS.contains(&x.to_ascii_lowercase().as_str())))
            .collect();
        paths.sort();
        if paths.is_empty() {
            return Err(err(format!("no PNG or JPEG images in {}", dir.display())));
        }
        let mut images = Vec::with_capacity(paths.len());
        for path in &paths {
            let img = image::open(path).map_err(|e| err(format!("cannot read image {}: {e}", path.display())))?.to_luma32f();
            let (w, h) = img.dimensions();
            let scale = (crop as f32 / w.min(h) as f32).max(1.0);
            let img = if scale > 1.0 {
                image::imageops::resize(&img, (w as f32 * scale).ceil() as u32, (h as f32 * scale).ceil() as u32, image::imageops::FilterType::Triangle)
            } else {
                img
            };
            let (w, h) = img.dimensions();
            images.push(Texture { height: h as usize, width: w as usize, data: img.into_raw().into_iter().map(|v| v.clamp(0.0, 1.0)).collect() });
        }
        Ok(Self { paths, images })
    }

    /// A `crop × crop` window of image `index` at (top, left) into `texture`.
    pub fn crop(&self, index: usize, top: usize, left: usize, crop: usize, texture: &mut Texture) {
        let image = &self.images[index];
        texture.height = crop;
        texture.width = crop;
        texture.data.clear();
        for r in top..top + crop {
            texture.data.extend_from_slice(&image.data[r * image.width + left..r * image.width + left + crop]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_fills_its_range_with_contrast_and_is_reproducible() {
        for family in FAMILIES {
            for seed in 0..4 {
                let (mut a, mut b) = (Texture::default(), Texture::default());
                procedural(family, seed, 64, &mut a);
                procedural(family, seed, 64, &mut b);
                assert_eq!(a, b);
                assert!(a.data.iter().all(|v| (0.0..=1.0).contains(v)), "{family:?}");
                let mean = a.data.iter().sum::<f32>() / a.data.len() as f32;
                let var = a.data.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / a.data.len() as f32;
                assert!(var > 1e-3, "{family:?} seed {seed} is flat: var {var}");
                let mut c = Texture::default();
                procedural(family, seed + 100, 64, &mut c);
                assert_ne!(a, c);
            }
        }
    }

    #[test]
    fn family_names_round_trip() {
        for f in FAMILIES {
            assert_eq!(TextureFamily::from_name(f.name()).unwrap(), f);
        }
        assert_eq!(TextureFamily::from_name("velvet").unwrap_err().name, "texture_families");
    }
}
