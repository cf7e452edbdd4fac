//! Albedo textures: six procedural families with random parameters, and
//! random crops of a user's image folder (the paper used 256×256 crops of DTD).
//!
//! A texture is a grayscale `Texture` (row-major, values in [0, 1]) of
//! `size × size` texels spanning the whole undeformed patch. Every procedural
//! texture is a pure function of (family, seed, size), and so is every texel:
//! a clip computes only the texels it can see (`procedural_region`). Spatial
//! coordinates below are in texture widths, (0, 0) top-left, periodic where
//! noted.

use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::error::{InvalidArgument, Result};
use crate::geometry::floor_fast;
use crate::raster::{pow4, Texture};
use crate::rng::{hash, mix64, unit_f64, SplitMix64};

use wide::{f32x4, i32x4};

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
    /// Print on white paper: lines of text-like glyphs and line drawings
    /// (segments and circles) in dark ink.
    Print,
}

/// Every family, by name.
pub const FAMILIES: [TextureFamily; 6] = [TextureFamily::Fractal, TextureFamily::Stripes, TextureFamily::Plaid, TextureFamily::Cells, TextureFamily::Weave, TextureFamily::Print];

/// The families a clip draws from by default (the distribution the shipped model learnt).
pub const DEFAULT_FAMILIES: [TextureFamily; 5] = [TextureFamily::Fractal, TextureFamily::Stripes, TextureFamily::Plaid, TextureFamily::Cells, TextureFamily::Weave];

impl TextureFamily {
    pub fn name(self) -> &'static str {
        match self {
            Self::Fractal => "fractal",
            Self::Stripes => "stripes",
            Self::Plaid => "plaid",
            Self::Cells => "cells",
            Self::Weave => "weave",
            Self::Print => "print",
        }
    }

    pub fn from_name(name: &str) -> Result<Self> {
        FAMILIES.into_iter().find(|f| f.name() == name).ok_or_else(|| {
            let names: Vec<_> = FAMILIES.iter().map(|f| f.name()).collect();
            InvalidArgument::new("texture_families", format!("unknown family {name:?}; expected one of {names:?}"))
        })
    }
}

/// Hermite smoothstep from 0 at `e0` to 1 at `e1` (either order), four lanes.
#[inline]
fn smoothstep4(e0: f32, e1: f32, x: f32x4) -> f32x4 {
    // Clamped as `f32::clamp` clamps finite values.
    let t = ((x - f32x4::splat(e0)) / f32x4::splat(e1 - e0)).fast_max(f32x4::ZERO).fast_min(f32x4::ONE);
    t * t * (f32x4::splat(3.0) - f32x4::splat(2.0) * t)
}

/// Periodic fBm value noise, roughly in [0, 1]: octave o interpolates (by
/// smoothstep) a periodic lattice of `base_cells · 2^o` random values per side.
struct Fbm {
    /// Per octave: cells per side and the lattice, row-major.
    octaves: Vec<(usize, Vec<f32>)>,
    persistence: f32,
}

impl Fbm {
    fn new(seed: u64, base_cells: usize, octaves: usize, persistence: f32) -> Self {
        let octaves = (0..octaves)
            .map(|octave| {
                let cells = base_cells << octave;
                let lattice = (0..cells).flat_map(|j| (0..cells).map(move |i| unit_f64(hash(seed, &[octave as u64, j as u64, i as u64])) as f32)).collect();
                (cells, lattice)
            })
            .collect();
        Self { octaves, persistence }
    }

    /// The noise at texels `rows` × `cols` of a `size²` texture, into `out`
    /// (row-major over the two lists).
    fn evaluate(&self, size: usize, rows: &[usize], cols: &[usize], out: &mut Vec<f32>) {
        out.clear();
        out.resize(rows.len() * cols.len(), 0.0);
        let mut amplitude = 1.0f32;
        let mut total = 0.0f32;
        for (cells, lattice) in &self.octaves {
            let cells = *cells;
            // Cell index and smoothstep weight of a texel column (= row) coordinate.
            let weight = |x: usize| {
                let p = (x as f32 + 0.5) / size as f32 * cells as f32;
                let i = floor_fast(p) as usize % cells;
                let f = p - floor_fast(p);
                (i, (i + 1) % cells, f * f * (3.0 - 2.0 * f))
            };
            let col_weights: Vec<_> = cols.iter().map(|&x| weight(x)).collect();
            // Lattice row j interpolated along x at every column: shared by
            // all the texel rows between lattice rows j and j ± 1, so built
            // once per lattice row (the last two kept), and the texels then
            // need no lattice lookups.
            let along_x = |j: usize, values: &mut Vec<f32>| {
                let l = &lattice[j * cells..(j + 1) * cells];
                values.clear();
                values.extend(col_weights.iter().map(|&(i0, i1, fx)| l[i0] + (l[i1] - l[i0]) * fx));
            };
            let mut lines: [(usize, Vec<f32>); 2] = [(usize::MAX, Vec::new()), (usize::MAX, Vec::new())];
            for (&y, row) in rows.iter().zip(out.chunks_exact_mut(cols.len())) {
                let (j0, j1, fy) = weight(y);
                for (slot, j) in [j0, j1].into_iter().enumerate() {
                    if lines[slot].0 != j {
                        match lines.iter().position(|line| line.0 == j) {
                            Some(other) => lines.swap(slot, other),
                            None => {
                                along_x(j, &mut lines[slot].1);
                                lines[slot].0 = j;
                            }
                        }
                    }
                }
                // Contiguous, no lookups: the compiler vectorises this loop.
                for ((v, &top), &bottom) in row.iter_mut().zip(&lines[0].1).zip(&lines[1].1) {
                    *v += amplitude * (top + (bottom - top) * fy);
                }
            }
            total += amplitude;
            amplitude *= self.persistence;
        }
        out.iter_mut().for_each(|v| *v /= total);
    }
}

/// Texels per side of the lattice whose values set a texture's normalisation.
const RANGE_STRIDE: usize = 4;

/// A family's drawn parameters: the pattern, a pure function of texel position.
enum Pattern {
    Fractal { noise: Fbm, marble: Option<f32> },
    Stripes { waves: Vec<(f32, f32, f32, f32)>, warp: f32, noise: Fbm },
    Plaid { rotation: (f32, f32), freq: f32, checks: bool, duty: [f32; 2], levels: [f32; 3], soft: f32 },
    Cells { cells: usize, radius: f32, walls: bool, features: Vec<(f32, f32, f32)> },
    Weave { threads: usize, twill: bool, tones: (f32, f32), fibres: Fbm },
    Print { text: Option<Text>, strokes: Vec<Stroke>, soft: f32 },
}

/// Lines of glyphs: each glyph a random 3 × 5 bitmap (a space one time in
/// six), in rows of pitch `line` along a direction rotated by (c, s).
struct Text {
    rotation: (f32, f32),
    line: f32,
    glyph: f32,
    seed: u64,
}

impl Text {
    /// Ink (0 or 1) at texture position (x, y).
    fn ink(&self, x: f32, y: f32) -> f32 {
        let (c, s) = self.rotation;
        let (u, v) = (c * x + s * y, -s * x + c * y);
        let (lv, gu) = (v / self.line, u / self.glyph);
        let (row, col) = (floor_fast(lv), floor_fast(gu));
        let (fv, fu) = (lv - row, gu - col);
        // Glyph body: the middle 60 % of a line's height, 80 % of a glyph's width.
        if !(0.2..0.8).contains(&fv) || fu >= 0.8 {
            return 0.0;
        }
        let bits = hash(self.seed, &[row as i64 as u64, col as i64 as u64]);
        if bits % 6 == 0 {
            return 0.0;
        }
        let (r, k) = (((fv - 0.2) / 0.6 * 5.0) as u32, (fu / 0.8 * 3.0) as u32);
        ((bits >> (8 + r.min(4) * 3 + k.min(2))) & 1) as f32
    }
}

/// A stroke of a line drawing: a segment from `a` to `b`, or a circle of
/// centre `a` and radius `b.0`, `width` wide.
struct Stroke {
    a: (f32, f32),
    b: (f32, f32),
    circle: bool,
    width: f32,
}

impl Stroke {
    /// Distance from (x, y) to the stroke's centre line, less its half width.
    fn distance(&self, x: f32, y: f32) -> f32 {
        let (ax, ay) = self.a;
        let d = if self.circle {
            (((x - ax) * (x - ax) + (y - ay) * (y - ay)).sqrt() - self.b.0).abs()
        } else {
            let (dx, dy) = (self.b.0 - ax, self.b.1 - ay);
            let t = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy).max(1e-12)).clamp(0.0, 1.0);
            ((x - ax - t * dx).powi(2) + (y - ay - t * dy).powi(2)).sqrt()
        };
        d - 0.5 * self.width
    }
}

impl Pattern {
    fn draw(family: TextureFamily, size: usize, rng: &mut SplitMix64) -> Self {
        match family {
            TextureFamily::Fractal => {
                let base = 2 + (rng.next_u64() % 5) as usize;
                let persistence = rng.uniform(0.35, 0.7) as f32;
                let seed = rng.next_u64();
                // Marble: veins where a sinusoid of the noise crosses zero.
                let marble = (rng.unit() < 0.35).then(|| rng.uniform(4.0, 14.0) as f32);
                Self::Fractal { noise: Fbm::new(seed, base, 5, persistence), marble }
            }
            TextureFamily::Stripes => {
                let count = 1 + (rng.next_u64() % 3) as usize;
                let waves = (0..count)
                    .map(|_| {
                        let angle = rng.uniform(0.0, std::f64::consts::PI) as f32;
                        let freq = rng.log_uniform(3.0, 24.0) as f32;
                        (angle.cos() * freq, angle.sin() * freq, rng.uniform(0.0, 6.3) as f32, rng.uniform(0.4, 1.0) as f32)
                    })
                    .collect();
                Self::Stripes { waves, warp: rng.uniform(0.0, 1.5) as f32, noise: Fbm::new(rng.next_u64(), 3, 3, 0.5) }
            }
            TextureFamily::Plaid => {
                let angle = rng.uniform(0.0, std::f64::consts::PI) as f32;
                let freq = rng.log_uniform(3.0, 16.0) as f32;
                let checks = rng.unit() < 0.5;
                let duty = [rng.uniform(-0.6, 0.6) as f32, rng.uniform(-0.6, 0.6) as f32];
                let levels = [rng.unit() as f32, rng.unit() as f32, rng.uniform(0.3, 0.8) as f32];
                // Edge softness of about one texel, so the pattern is anti-aliased.
                let soft = std::f32::consts::TAU * freq / size as f32;
                Self::Plaid { rotation: (angle.cos(), angle.sin()), freq, checks, duty, levels, soft }
            }
            TextureFamily::Cells => {
                let cells = 4 + (rng.next_u64() % 11) as usize;
                let radius = rng.uniform(0.2, 0.6) as f32;
                let walls = rng.unit() < 0.4;
                let cell_seed = rng.next_u64();
                // Feature point offset and tone of every cell (periodic).
                let features = (0..cells * cells)
                    .map(|k| {
                        let h = hash(cell_seed, &[(k % cells) as u64, (k / cells) as u64]);
                        (unit_f64(h) as f32, unit_f64(h.rotate_left(32)) as f32, unit_f64(mix64(h)) as f32)
                    })
                    .collect();
                Self::Cells { cells, radius, walls, features }
            }
            TextureFamily::Weave => {
                let threads = 8 + (rng.next_u64() % 25) as usize;
                let twill = rng.unit() < 0.5;
                let tones = (rng.uniform(0.3, 1.0) as f32, rng.uniform(0.3, 1.0) as f32);
                Self::Weave { threads, twill, tones, fibres: Fbm::new(rng.next_u64(), 16, 3, 0.6) }
            }
            TextureFamily::Print => {
                // Text, a drawing, or both, in texture widths.
                let kind = rng.next_u64() % 3;
                let text = (kind != 1).then(|| {
                    let angle = if rng.unit() < 0.7 { 0.0 } else { rng.uniform(0.0, std::f64::consts::PI) } as f32;
                    let line = rng.log_uniform(1.0 / 40.0, 1.0 / 8.0) as f32;
                    let glyph = line * rng.uniform(0.45, 0.8) as f32;
                    Text { rotation: (angle.cos(), angle.sin()), line, glyph, seed: rng.next_u64() }
                });
                let count = if kind == 0 { 0 } else { 3 + (rng.next_u64() % 10) as usize };
                let width = rng.log_uniform(1.0 / 300.0, 1.0 / 60.0) as f32;
                let strokes = (0..count)
                    .map(|_| {
                        let circle = rng.unit() < 0.35;
                        let a = (rng.unit() as f32, rng.unit() as f32);
                        let b = if circle { (rng.uniform(0.03, 0.3) as f32, 0.0) } else { (rng.unit() as f32, rng.unit() as f32) };
                        Stroke { a, b, circle, width }
                    })
                    .collect();
                Self::Print { text, strokes, soft: 1.0 / size as f32 }
            }
        }
    }

    /// Raw values (before normalisation) at texels `rows` × `cols`, into
    /// `out` (row-major over the two lists); `noise` is scratch.
    fn evaluate(&self, size: usize, rows: &[usize], cols: &[usize], out: &mut Vec<f32>, noise: &mut Vec<f32>) {
        match self {
            Self::Fractal { noise, marble } => {
                noise.evaluate(size, rows, cols, out);
                if let Some(k) = marble {
                    // In place, four at a time (the last group padded).
                    let (splat, half) = (f32x4::splat, f32x4::splat(0.5));
                    for group in out.chunks_mut(4) {
                        let v = f32x4::new(std::array::from_fn(|l| group[l.min(group.len() - 1)]));
                        let veins = pow4(half + half * sin4(splat(k * std::f32::consts::TAU) * v), 0.7).to_array();
                        group.copy_from_slice(&veins[..group.len()]);
                    }
                }
            }
            Self::Stripes { waves, warp, noise: fbm } => {
                fbm.evaluate(size, rows, cols, noise);
                let splat = f32x4::splat;
                fill_texels4(size, rows, cols, out, |texels, x, y| {
                    let warped = splat(warp * 6.0) * f32x4::new(texels.map(|k| noise[k]));
                    waves.iter().fold(f32x4::ZERO, |sum, &(fx, fy, ph, a)| sum + splat(a) * sin4(splat(std::f32::consts::TAU) * (splat(fx) * x + splat(fy * y)) + splat(ph) + warped))
                });
            }
            Self::Plaid { rotation: (c, s), freq, checks, duty, levels, soft } => {
                let (splat, one) = (f32x4::splat, f32x4::ONE);
                fill_texels4(size, rows, cols, out, |_, x, y| {
                    let (u, w) = (splat(*c) * x + splat(s * y), splat(-s) * x + splat(c * y));
                    let wave = |t: f32x4| sin4(splat(std::f32::consts::TAU * freq) * t);
                    let a = smoothstep4(-soft, *soft, wave(u) - splat(duty[0]));
                    let b = smoothstep4(-soft, *soft, wave(w) - splat(duty[1]));
                    if *checks { a * b + (one - a) * (one - b) } else { splat(levels[2]) * (splat(levels[0]) * a + splat(levels[1]) * b) + splat(1.0 - levels[2]) * a * b }
                });
            }
            Self::Cells { cells, radius, walls, features } => cells_texels(*cells, *radius, *walls, features, size, rows, cols, out),
            Self::Weave { threads, twill, tones: (warp_tone, weft_tone), fibres } => {
                fibres.evaluate(size, rows, cols, noise);
                let splat = f32x4::splat;
                fill_texels4(size, rows, cols, out, |texels, x, y| {
                    let (u, w) = (x * splat(*threads as f32), y * *threads as f32);
                    let (iu, iw) = (u.to_array().map(|u| floor_fast(u) as i64), floor_fast(w) as i64);
                    let warp_on_top = iu.map(|iu| if *twill { (iu + iw).rem_euclid(4) < 2 } else { (iu + iw).rem_euclid(2) == 0 });
                    let on_top = f32x4::new(warp_on_top.map(f32::from)).simd_eq(f32x4::ONE);
                    // Thread cross-section: bright in the middle, dark at the gaps.
                    let across = on_top.bitselect(u - f32x4::new(iu.map(|i| i as f32)), splat(w - iw as f32));
                    let profile = sin4(splat(std::f32::consts::PI) * across).fast_max(f32x4::ZERO);
                    let tone = on_top.bitselect(splat(*warp_tone), splat(*weft_tone));
                    tone * profile.sqrt() * (splat(0.75) + splat(0.5) * f32x4::new(texels.map(|k| noise[k])))
                });
            }
            Self::Print { text, strokes, soft } => {
                fill_texels4(size, rows, cols, out, |_, x, y| {
                    f32x4::new(x.to_array().map(|x| {
                        let glyph = text.as_ref().map_or(0.0, |t| t.ink(x, y));
                        // Strokes anti-aliased over about a texel.
                        let line = strokes.iter().map(|s| s.distance(x, y)).fold(f32::INFINITY, f32::min);
                        let stroke = if line < *soft { 1.0 - (line / soft).max(0.0) } else { 0.0 };
                        1.0 - glyph.max(stroke)
                    }))
                });
            }
        }
    }
}

/// The Cells family at texels `rows` × `cols` (see `Pattern::Cells`), four
/// texels of a row at a time: the distance to the nearest (d1) and second
/// nearest (d2) feature point of the 3×3 cells around a texel's cell.
#[allow(clippy::too_many_arguments)]
fn cells_texels(cells: usize, radius: f32, walls: bool, features: &[(f32, f32, f32)], size: usize, rows: &[usize], cols: &[usize], out: &mut Vec<f32>) {
    let splat = f32x4::splat;
    let coord = |x: usize| (x as f32 + 0.5) / size as f32 * cells as f32;
    let n = cells as i64;
    // A column's cell does not depend on the row: the cells of the columns,
    // and the range of cells (and neighbours) they reach.
    let cell_of = |x: f32| floor_fast(x) as i64;
    let (first, last) = cols.iter().fold((i64::MAX, i64::MIN), |(lo, hi), &x| (lo.min(cell_of(coord(x))), hi.max(cell_of(coord(x)))));
    let reach = (first - 1)..=(last + 1);
    // Per row, for each cell i of `reach` and each of the rows cj − 1, cj,
    // cj + 1: the feature point's x, its (py − y)², and its tone.
    let mut table: Vec<[f32; 3]> = Vec::with_capacity(3 * reach.clone().count());
    out.clear();
    for &y in rows {
        let y = coord(y);
        let cj = cell_of(y);
        table.clear();
        for i in reach.clone() {
            for j in cj - 1..=cj + 1 {
                let (ox, oy, tone) = features[j.rem_euclid(n) as usize * cells + i.rem_euclid(n) as usize];
                let py = j as f32 + oy;
                table.push([i as f32 + ox, (py - y) * (py - y), tone]);
            }
        }
        // Neighbour (ci + di − 1, cj + dj − 1); the table starts at cell first − 1.
        let entry = |i: i64, di: usize, dj: usize| table[((i - first) as usize + di) * 3 + dj];
        for group in cols.chunks(4) {
            let x = f32x4::new(std::array::from_fn(|l| coord(group[l.min(group.len() - 1)])));
            let ci = x.to_array().map(cell_of);
            let same_cell = ci.iter().all(|&i| i == ci[0]);
            // Nearest and second nearest, in the order dj, di (ties keep the
            // earlier), branch-free.
            let (mut d1, mut d2, mut tone) = (splat(f32::INFINITY), splat(f32::INFINITY), f32x4::ZERO);
            for dj in 0..3 {
                for di in 0..3 {
                    // Four texels of a row mostly share their cell: one lookup, not four.
                    let [px, dy2, t] = if same_cell { entry(ci[0], di, dj).map(splat) } else { std::array::from_fn(|q| f32x4::new(ci.map(|i| entry(i, di, dj)[q]))) };
                    let d = (px - x) * (px - x) + dy2;
                    let nearer = d.simd_lt(d1);
                    d2 = nearer.bitselect(d1, d.simd_lt(d2).bitselect(d, d2));
                    d1 = nearer.bitselect(d, d1);
                    tone = nearer.bitselect(t, tone);
                }
            }
            let (d1, d2) = (d1.sqrt(), d2.sqrt());
            let value = if walls { smoothstep4(0.0, 0.15, d2 - d1) * (splat(0.5) + splat(0.5) * tone) } else { smoothstep4(radius, radius * 0.7, d1) * (splat(0.4) + splat(0.6) * tone) };
            out.extend_from_slice(&value.to_array()[..group.len()]);
        }
    }
}

/// `value(k, x, y)` at four consecutive texels of a row of `rows` × `cols`
/// (row-major), into `out`: k their indices, x their centres' columns, y the
/// row's, in texture widths. In a row's last group, lanes past its end
/// repeat its last texel and are dropped.
fn fill_texels4(size: usize, rows: &[usize], cols: &[usize], out: &mut Vec<f32>, value: impl Fn([usize; 4], f32x4, f32) -> f32x4) {
    let coord = |x: usize| (x as f32 + 0.5) / size as f32;
    out.clear();
    for &y in rows {
        for group in cols.chunks(4) {
            let lane = |l: usize| l.min(group.len() - 1);
            let start = out.len();
            let values = value(std::array::from_fn(|l| start + lane(l)), f32x4::new(std::array::from_fn(|l| coord(group[lane(l)]))), coord(y)).to_array();
            out.extend_from_slice(&values[..group.len()]);
        }
    }
}

/// sin x in four lanes, with polynomials in plain f32 operations (no libm,
/// no fused multiply-add): the same bits on every platform. x is reduced by
/// the nearest multiple k·π/2 (Cody–Waite: π/2 in three parts, the first two
/// of 8 and 11 significant bits, so their products with k are exact for
/// |k| < 2¹³), then Cephes' sinf / cosf polynomials on
/// [−π/4, π/4] and the quadrant k mod 4. Absolute error below 1.5e-7 for
/// |x| ≤ 4000 (tested against f64); textures call it with |x| < 400.
fn sin4(x: f32x4) -> f32x4 {
    let splat = f32x4::splat;
    // k = floor(x·2/π + ½) by truncation (exact for |k| < 2³¹).
    let t = x * splat(std::f32::consts::FRAC_2_PI) + splat(0.5);
    let truncated = f32x4::from_i32x4(t.fast_trunc_int());
    let k = t.simd_lt(truncated).bitselect(truncated - f32x4::ONE, truncated);
    let r = ((x - k * splat(1.570_312_5)) - k * splat(4.837_513e-4)) - k * splat(7.549_79e-8);
    let r2 = r * r;
    let sin = r + r * r2 * (splat(-1.666_665_5e-1) + r2 * (splat(8.332_161e-3) + r2 * splat(-1.951_529_6e-4)));
    let cos = f32x4::ONE - splat(0.5) * r2 + r2 * r2 * (splat(4.166_664_6e-2) + r2 * (splat(-1.388_731_6e-3) + r2 * splat(2.443_315_7e-5)));
    let quadrant = k.fast_trunc_int() & i32x4::splat(3);
    let mask = |bit: i32| wide::bytemuck::cast::<i32x4, f32x4>((quadrant & i32x4::splat(bit)).simd_eq(i32x4::splat(bit)));
    // Quadrants 1 and 3 take the cosine, 2 and 3 are negated (a sign flip).
    mask(1).bitselect(cos, sin) ^ (mask(2) & splat(-0.0))
}

/// A procedural texture of `family`; a pure function of (family, seed, size).
pub fn procedural(family: TextureFamily, seed: u64, size: usize, texture: &mut Texture) {
    procedural_region(family, seed, size, (0..size, 0..size), texture)
}

/// The texels `rows` × `cols` (clamped to the texture) of
/// [`procedural`]`(family, seed, size)`, the others 0: each texel's value
/// does not depend on the region, so a clip computes only the texels it can
/// sample. Raw values are mapped to [0, 1] by their range over the lattice of
/// every RANGE_STRIDE-th texel (every texel below 16; clamped), then to the
/// drawn tone range.
pub fn procedural_region(family: TextureFamily, seed: u64, size: usize, (rows, cols): (Range<usize>, Range<usize>), texture: &mut Texture) {
    texture.reset(size, size);
    let mut rng = SplitMix64::new(hash(seed, &[family as u64]));
    let pattern = Pattern::draw(family, size, &mut rng);
    let (mut values, mut noise) = (Vec::new(), Vec::new());
    // Textures too small for a lattice take the range of every texel.
    let stride = if size >= 4 * RANGE_STRIDE { RANGE_STRIDE } else { 1 };
    let lattice: Vec<usize> = (stride / 2..size).step_by(stride).collect();
    pattern.evaluate(size, &lattice, &lattice, &mut values, &mut noise);
    let (min, max) = values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let (lo, hi) = (rng.uniform(0.0, 0.35) as f32, rng.uniform(0.6, 1.0) as f32);
    let (rows, cols): (Vec<usize>, Vec<usize>) = ((rows.start..rows.end.min(size)).collect(), (cols.start..cols.end.min(size)).collect());
    if rows.is_empty() || cols.is_empty() {
        return;
    }
    pattern.evaluate(size, &rows, &cols, &mut values, &mut noise);
    let span = max - min;
    for (&r, row) in rows.iter().zip(values.chunks_exact(cols.len())) {
        let out = &mut texture.row_mut(r)[cols[0]..][..cols.len()];
        for (o, &v) in out.iter_mut().zip(row) {
            let unit = if span > 0.0 { ((v - min) / span).clamp(0.0, 1.0) } else { 0.5 };
            *o = lo + (hi - lo) * unit;
        }
    }
    texture.repeat_edges();
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
            let texels: Vec<f32> = img.into_raw().into_iter().map(|v| v.clamp(0.0, 1.0)).collect();
            images.push(Texture::new(h as usize, w as usize, &texels).map_err(|e| err(format!("image {}: {}", path.display(), e.message)))?);
        }
        Ok(Self { paths, images })
    }

    /// A `crop × crop` window of image `index` at (top, left) into `texture`.
    pub fn crop(&self, index: usize, top: usize, left: usize, crop: usize, texture: &mut Texture) {
        let image = &self.images[index];
        texture.reset(crop, crop);
        for r in 0..crop {
            texture.row_mut(r).copy_from_slice(&image.row(top + r)[left..left + crop]);
        }
        texture.repeat_edges();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
        let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }

    #[test]
    fn sin4_is_within_1_5e_7_of_sin() {
        let mut rng = SplitMix64::new(5);
        let special = [0.0, -0.0, 1e-30, std::f32::consts::FRAC_PI_4, std::f32::consts::FRAC_PI_2, std::f32::consts::PI, 3.0 * std::f32::consts::FRAC_PI_4, -4000.0, 4000.0];
        let mut worst = 0.0f64;
        for g in 0..50_000 {
            let x: [f32; 4] = if g < 3 { std::array::from_fn(|l| special[(4 * g + l).min(special.len() - 1)]) } else { std::array::from_fn(|_| rng.uniform(-4000.0, 4000.0) as f32 / if g % 2 == 0 { 1000.0 } else { 1.0 }) };
            for (v, x) in sin4(f32x4::new(x)).to_array().into_iter().zip(x) {
                worst = worst.max((v as f64 - (x as f64).sin()).abs());
            }
        }
        assert!(worst < 1.5e-7, "worst error {worst}");
    }

    /// The Cells pattern texel by texel, as written first: scalar, branching
    /// nearest / second-nearest search.
    fn cells_reference(cells: usize, radius: f32, walls: bool, features: &[(f32, f32, f32)], size: usize, rows: &[usize], cols: &[usize]) -> Vec<f32> {
        let n = cells as i64;
        let point = |i: i64, j: i64| {
            let (ox, oy, tone) = features[j.rem_euclid(n) as usize * cells + i.rem_euclid(n) as usize];
            (i as f32 + ox, j as f32 + oy, tone)
        };
        let coord = |x: usize| (x as f32 + 0.5) / size as f32;
        let mut out = Vec::new();
        for &y in rows {
            for &x in cols {
                let (x, y) = (coord(x) * cells as f32, coord(y) * cells as f32);
                let (ci, cj) = (x.floor() as i64, y.floor() as i64);
                let (mut d1, mut d2, mut tone) = (f32::INFINITY, f32::INFINITY, 0.0);
                for dj in -1..=1 {
                    for di in -1..=1 {
                        let (px, py, t) = point(ci + di, cj + dj);
                        let d = (px - x).powi(2) + (py - y).powi(2);
                        if d < d1 {
                            (d2, d1, tone) = (d1, d, t);
                        } else if d < d2 {
                            d2 = d;
                        }
                    }
                }
                let (d1, d2) = (d1.sqrt(), d2.sqrt());
                out.push(if walls { smoothstep(0.0, 0.15, d2 - d1) * (0.5 + 0.5 * tone) } else { smoothstep(radius, radius * 0.7, d1) * (0.4 + 0.6 * tone) });
            }
        }
        out
    }

    #[test]
    fn four_lane_families_follow_their_texel_formulas() {
        // Stripes, Plaid, Weave and marble evaluated four texels at a time
        // against their formulas texel by texel: coordinates in f32 as the
        // lanes compute them, sines and powers in f64. Column lists with a
        // gap and a partial last group check which noise value and which
        // coordinate each lane reads.
        let (size, rows, cols): (usize, Vec<usize>, Vec<usize>) = (96, (0..96).step_by(5).collect(), (2..40).chain(43..93).collect());
        let coord = |x: usize| (x as f32 + 0.5) / size as f32;
        let pi = std::f64::consts::PI;
        let smooth = |e0: f64, e1: f64, x: f64| {
            let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        };
        let mut checked = [0usize; 4];
        for family in [TextureFamily::Fractal, TextureFamily::Stripes, TextureFamily::Plaid, TextureFamily::Weave] {
            for seed in 0..12 {
                let pattern = Pattern::draw(family, size, &mut SplitMix64::new(hash(seed, &[family as u64])));
                let (mut out, mut noise) = (Vec::new(), Vec::new());
                pattern.evaluate(size, &rows, &cols, &mut out, &mut noise);
                let texels = rows.iter().flat_map(|&y| cols.iter().map(move |&x| (coord(x), coord(y))));
                let (expected, tolerance): (Vec<f64>, f64) = match &pattern {
                    Pattern::Fractal { noise: fbm, marble: Some(k) } => {
                        fbm.evaluate(size, &rows, &cols, &mut noise);
                        (noise.iter().map(|&v| (0.5 + 0.5 * ((k * std::f32::consts::TAU * v) as f64).sin()).max(0.0).powf(0.7)).collect(), 1e-4)
                    }
                    Pattern::Fractal { .. } => continue,
                    Pattern::Stripes { waves, warp, noise: fbm } => {
                        fbm.evaluate(size, &rows, &cols, &mut noise);
                        let value = |k: usize, (x, y): (f32, f32)| waves.iter().map(|&(fx, fy, ph, a)| a as f64 * ((std::f32::consts::TAU * (fx * x + fy * y) + ph + warp * 6.0 * noise[k]) as f64).sin()).sum();
                        (texels.enumerate().map(|(k, p)| value(k, p)).collect(), 1e-5)
                    }
                    Pattern::Plaid { rotation: (c, s), freq, checks, duty, levels, soft } => {
                        let value = |(x, y): (f32, f32)| {
                            let (u, w) = (c * x + s * y, -s * x + c * y);
                            let a = smooth(-*soft as f64, *soft as f64, ((std::f32::consts::TAU * freq * u) as f64).sin() - duty[0] as f64);
                            let b = smooth(-*soft as f64, *soft as f64, ((std::f32::consts::TAU * freq * w) as f64).sin() - duty[1] as f64);
                            let [l0, l1, l2] = levels.map(f64::from);
                            if *checks { a * b + (1.0 - a) * (1.0 - b) } else { l2 * (l0 * a + l1 * b) + (1.0 - l2) * a * b }
                        };
                        (texels.map(value).collect(), 1e-4)
                    }
                    Pattern::Weave { threads, twill, tones: (warp_tone, weft_tone), fibres } => {
                        fibres.evaluate(size, &rows, &cols, &mut noise);
                        let value = |k: usize, (x, y): (f32, f32)| {
                            let (u, w) = (x * *threads as f32, y * *threads as f32);
                            let (iu, iw) = (u.floor(), w.floor());
                            let warp_on_top = if *twill { (iu as i64 + iw as i64).rem_euclid(4) < 2 } else { (iu as i64 + iw as i64).rem_euclid(2) == 0 };
                            let (across, tone) = if warp_on_top { (u - iu, warp_tone) } else { (w - iw, weft_tone) };
                            *tone as f64 * (pi * across as f64).sin().max(0.0).sqrt() * (0.75 + 0.5 * noise[k] as f64)
                        };
                        // √ of a sine near 0 magnifies its last bits.
                        (texels.enumerate().map(|(k, p)| value(k, p)).collect(), 1e-3)
                    }
                    Pattern::Cells { .. } | Pattern::Print { .. } => unreachable!(),
                };
                assert_eq!(out.len(), expected.len());
                for (k, (&v, e)) in out.iter().zip(expected).enumerate() {
                    assert!((v as f64 - e).abs() <= tolerance, "{family:?} seed {seed} texel {k}: {v} vs {e}");
                }
                checked[[TextureFamily::Fractal, TextureFamily::Stripes, TextureFamily::Plaid, TextureFamily::Weave].iter().position(|&f| f == family).unwrap()] += 1;
            }
        }
        assert!(checked.iter().all(|&n| n > 0), "families checked: {checked:?}");
    }

    #[test]
    fn cells_four_at_a_time_equal_the_scalar_search_bit_for_bit() {
        // Column lists that start and end mid-cell and mid-group, with a gap:
        // groups of four that share a cell and groups that straddle two.
        let mut rng = SplitMix64::new(3);
        for (cells, size) in [(4, 64), (7, 100), (14, 256), (5, 13)] {
            let features: Vec<(f32, f32, f32)> = (0..cells * cells).map(|_| (rng.unit() as f32, rng.unit() as f32, rng.unit() as f32)).collect();
            let rows: Vec<usize> = (0..size).step_by(3).collect();
            let cols: Vec<usize> = (1..size / 2).chain(size / 2 + 3..size).collect();
            for walls in [false, true] {
                let mut out = Vec::new();
                cells_texels(cells, 0.4, walls, &features, size, &rows, &cols, &mut out);
                let expected = cells_reference(cells, 0.4, walls, &features, size, &rows, &cols);
                assert_eq!(out.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), expected.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), "cells {cells} size {size} walls {walls}");
            }
        }
    }

    #[test]
    fn fbm_equals_the_per_texel_formula_bit_for_bit() {
        // Rows crossing many lattice rows (and the periodic wrap), columns
        // not a multiple of four.
        let fbm = Fbm::new(9, 3, 4, 0.55);
        let (size, rows, cols): (usize, Vec<usize>, Vec<usize>) = (90, (0..90).rev().step_by(2).chain(5..9).collect(), (3..80).collect());
        let mut out = Vec::new();
        fbm.evaluate(size, &rows, &cols, &mut out);
        let (mut amplitude, mut total) = (1.0f32, 0.0f32);
        let mut expected = vec![0.0f32; rows.len() * cols.len()];
        for (cells, lattice) in &fbm.octaves {
            let weight = |x: usize| {
                let p = (x as f32 + 0.5) / size as f32 * *cells as f32;
                let i = p.floor() as usize % cells;
                let f = p - p.floor();
                (i, (i + 1) % cells, f * f * (3.0 - 2.0 * f))
            };
            for (r, &y) in rows.iter().enumerate() {
                let (j0, j1, fy) = weight(y);
                for (c, &x) in cols.iter().enumerate() {
                    let (i0, i1, fx) = weight(x);
                    let at = |j: usize, i: usize| lattice[j * cells + i];
                    let top = at(j0, i0) + (at(j0, i1) - at(j0, i0)) * fx;
                    let bottom = at(j1, i0) + (at(j1, i1) - at(j1, i0)) * fx;
                    expected[r * cols.len() + c] += amplitude * (top + (bottom - top) * fy);
                }
            }
            total += amplitude;
            amplitude *= fbm.persistence;
        }
        expected.iter_mut().for_each(|v| *v /= total);
        assert_eq!(out.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), expected.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    }

    #[test]
    fn every_family_fills_its_range_with_contrast_and_is_reproducible() {
        for family in FAMILIES {
            for seed in 0..4 {
                let (mut a, mut b) = (Texture::default(), Texture::default());
                procedural(family, seed, 64, &mut a);
                procedural(family, seed, 64, &mut b);
                assert_eq!(a, b);
                let texels = a.to_vec();
                assert!(texels.iter().all(|v| (0.0..=1.0).contains(v)), "{family:?}");
                let mean = texels.iter().sum::<f32>() / texels.len() as f32;
                let var = texels.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / texels.len() as f32;
                assert!(var > 1e-3, "{family:?} seed {seed} is flat: var {var}");
                let mut c = Texture::default();
                procedural(family, seed + 100, 64, &mut c);
                assert_ne!(a, c);
            }
        }
    }

    #[test]
    fn a_region_holds_the_whole_textures_texels_bit_for_bit_and_zeros_elsewhere() {
        let (size, rows, cols) = (96, 17..60, 5..91);
        for family in FAMILIES {
            for seed in 0..3 {
                let (mut whole, mut part) = (Texture::default(), Texture::default());
                procedural(family, seed, size, &mut whole);
                procedural_region(family, seed, size, (rows.clone(), cols.clone()), &mut part);
                for (k, (w, p)) in whole.to_vec().iter().zip(&part.to_vec()).enumerate() {
                    let inside = rows.contains(&(k / size)) && cols.contains(&(k % size));
                    assert_eq!(p.to_bits(), if inside { w.to_bits() } else { 0 }, "{family:?} seed {seed} texel {k}");
                }
            }
        }
    }

    #[test]
    fn print_is_dark_ink_on_mostly_white_paper() {
        for seed in 0..16 {
            let mut t = Texture::default();
            procedural(TextureFamily::Print, seed, 128, &mut t);
            let texels = t.to_vec();
            let (lo, hi) = texels.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            let paper = texels.iter().filter(|&&v| v == hi).count() as f64 / texels.len() as f64;
            let ink = texels.iter().filter(|&&v| v < lo + 0.5 * (hi - lo)).count() as f64 / texels.len() as f64;
            assert!(paper > 0.4 && ink > 0.01, "seed {seed}: paper {paper}, ink {ink}");
        }
    }

    #[test]
    fn tiny_textures_keep_their_contrast() {
        for size in [2, 3, 5] {
            let mut t = Texture::default();
            procedural(TextureFamily::Fractal, 1, size, &mut t);
            let (lo, hi) = t.to_vec().iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            assert!(hi - lo > 0.2, "size {size}: {lo}..{hi}");
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
