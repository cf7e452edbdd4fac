//! Deforming-surface synthesis by FFT coloured noise (paper eqs. vdm, vdm_Fourier).
//!
//! `f(x, t) = E_t(x + d(x, t))` with `x` on the bi-unit square embedded as
//! `(x, y, 0)` and
//!
//! ```text
//! d(x, t) = κ · G_ν(x) · diag(ζ, ζ, 1) · r(x, t)
//! r_i(x, t) = Re F⁻¹{ w · G_ξ · G_Σ · cos(t φ_i + θ_i) · e^{iψ_i} }(x) / n
//! ```
//!
//! - Frequencies `u = k / PERIOD` (cycles per unit) on an M×M grid, `M = 2(grid − 1)`:
//!   the field is periodic over PERIOD = 4 units, twice the patch, so opposite
//!   borders of the patch move independently and half-wave bends of the whole
//!   sheet exist (a period equal to the patch would force the left border to
//!   copy the right one).
//! - `w(u) = 1 − exp(−(|u|/W_RADIUS)²)`: radial, in [0, 1), `w(0) = 0`, so `r`
//!   has exactly zero mean over its period.
//! - `G_ξ(u) = exp(−|u|²/(2ξ²))`: width ξ grows with *flexibility*.
//! - `G_Σ(u) = exp(−uᵀΣu)`: *orientation* of the folds.
//! - `φ_i(u) = speeds[i] · ρ_i(u)`, `ρ_i ~ U[0.5, 1.5]`; `θ_i ~ U[0, 2π)`.
//! - `ψ_i ~ U[0, 2π)` is a spatial phase the paper's formula does not have: with
//!   a real spectrum, `Re F⁻¹` is an even function of `x` and every surface would
//!   be point-symmetric about the patch centre. A unit phase factor leaves
//!   |spectrum| and so every parameter's meaning unchanged and removes that.
//! - `n = sqrt(Σ_{half plane} S²)` makes `E[r_i²] = 1`: κ is the RMS of each
//!   channel before the envelope and folding, whatever ξ and Σ.
//! - `G_ν(x) = exp(−ν|x|²)`; `E_t(p) = R(rotation + t · rotation_rate) p + t · drift`
//!   with `R(v)` the rotation by |v| about v; `t = frame / (frames − 1)`.
//!
//! Each random draw of frequency `k` (signed integers) is `hash(phase_seed, channel, k)`,
//! so a surface is the same continuous field sampled more finely on a larger grid.
//! Frequencies whose amplitude is below SPECTRUM_CUTOFF × the largest are dropped.
//!
//! Cost: two real channels are packed in one complex inverse transform (their
//! spectra are Hermitian), which is one of two, chosen per clip by an
//! operation count of its spectrum (never by the CPU, so the bits are the
//! same everywhere): FFTs, where only the frequency rows that hold energy go
//! through the first pass and only the `grid` output columns through the
//! second, or, where few frequencies hold energy (the default ranges: ~280
//! of 126² for a 64-vertex grid), the sums over those frequencies done
//! directly, in chunks of 32 output columns (`DirectSums`). Output:
//! f32 vertex positions, shape (frames, grid, grid, 3), row index = y,
//! column index = x.

use std::f64::consts::TAU;
use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use rayon::prelude::*;
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

use crate::error::{size_in, InvalidArgument, Result};
use crate::lanes::with_avx2;
use crate::params::SurfaceParams;
use crate::rng::{hash, unit_f64};

/// Period of the displacement field in units (the patch is 2 units wide).
pub const PERIOD: f64 = 4.0;
/// Radius (cycles per unit) of the radial profile `w(u) = 1 − exp(−(|u|/W_RADIUS)²)`.
pub const W_RADIUS: f64 = 0.25;
/// Relative amplitude below which a frequency is dropped.
pub const SPECTRUM_CUTOFF: f64 = 1e-4;
pub const MAX_GRID: i64 = 4096;
pub const MAX_FRAMES: i64 = 4096;
/// Instructions, as measured with AVX2 (callgrind, default clips), of one
/// complex multiply-add of the direct sums (2.05) and of one point and bit of
/// M of an FFT pass, the passes' set-up and transposes included (6.7): the
/// direct sums run where they cost less.
const DIRECT_COST: usize = 2;
const FFT_COST: usize = 7;

const TAG_THETA: u64 = 1;
const TAG_PSI: u64 = 2;
const TAG_RHO: u64 = 3;

/// Validated (frames, grid).
pub fn check_sizes(frames: i64, grid: i64) -> Result<(usize, usize)> {
    let (frames, grid) = (size_in("frames", frames, 1, MAX_FRAMES)?, size_in("grid", grid, 2, MAX_GRID)?);
    if clip_len(frames, grid) > MAX_CLIP_VALUES {
        let gib = clip_len(frames, grid) as f64 * 4.0 / (1u64 << 30) as f64;
        return Err(InvalidArgument::new("grid", format!("frames × grid² × 3 = {frames} × {grid}² × 3 float32 values ({gib:.1} GiB) exceed {MAX_CLIP_VALUES} (8 GiB); use fewer frames or a smaller grid")));
    }
    Ok((frames, grid))
}

/// Most f32 values one synthesised clip may hold (8 GiB).
pub const MAX_CLIP_VALUES: usize = 1 << 31;

/// Number of f32 values of one clip: frames · grid · grid · 3.
pub fn clip_len(frames: usize, grid: usize) -> usize {
    frames * grid * grid * 3
}

/// The undeformed coordinate of grid index `j`: −1 at 0, +1 at grid − 1.
#[inline]
pub fn grid_coordinate(j: usize, grid: usize) -> f64 {
    -1.0 + 2.0 * j as f64 / (grid - 1) as f64
}

/// `t` of a frame: 0 at the first, 1 at the last.
#[inline]
pub fn frame_time(frame: usize, frames: usize) -> f64 {
    if frames > 1 {
        frame as f64 / (frames - 1) as f64
    } else {
        0.0
    }
}

/// Unnormalised spectrum magnitude `w · G_ξ · G_Σ` at frequency `u` (cycles per unit).
pub fn spectrum_magnitude(params: &SurfaceParams, ux: f64, uy: f64) -> f64 {
    let r2 = ux * ux + uy * uy;
    let [sxx, sxy, syy] = params.orientation;
    let w = 1.0 - (-r2 / (W_RADIUS * W_RADIUS)).exp();
    let xi = params.flexibility;
    w * (-r2 / (2.0 * xi * xi) - (sxx * ux * ux + 2.0 * sxy * ux * uy + syy * uy * uy)).exp()
}

/// Reusable state for synthesising clips of one grid size; one per thread.
pub struct Synthesizer {
    grid: usize,
    m: usize,
    fft: Arc<dyn Fft<f32>>,
    fft_scratch: Vec<Complex32>,
    // Active half-plane frequencies (structure of arrays, one entry per frequency).
    rows_k: Vec<usize>,
    cols_k: Vec<usize>,
    rows_mirror: Vec<usize>,
    cols_mirror: Vec<usize>,
    amplitude: Vec<f64>,
    // Per channel-major (channel, entry): e^{iψ}, cosine recurrence state.
    phase: Vec<Complex32>,
    cos_prev: Vec<f64>,
    cos_now: Vec<f64>,
    two_cos_step: Vec<f64>,
    // Amplitudes of the last two frames, (channel, entry), indexed by frame parity.
    frame_amplitude: [Vec<f32>; 2],
    row_slot: Vec<usize>,
    active_rows: Vec<usize>,
    rows: Vec<Complex32>,
    cols: Vec<Complex32>,
    /// e^{2πi j/M} for j < M: the inverse transform's twiddle factors.
    twiddle: Vec<Complex32>,
    /// How this clip's fields are computed, and the direct sums' layout.
    transform: Transform,
    direct: DirectSums,
    envelope: Vec<f64>,
    /// `grid_coordinate` of every grid index.
    coordinates: Vec<f64>,
}

impl Synthesizer {
    pub fn new(grid: usize) -> Self {
        assert!(grid >= 2, "grid must be at least 2");
        let m = 2 * (grid - 1);
        let fft = FftPlanner::<f32>::new().plan_fft_inverse(m);
        let scratch = vec![Complex32::default(); fft.get_inplace_scratch_len()];
        Self {
            grid,
            m,
            fft,
            fft_scratch: scratch,
            rows_k: Vec::new(),
            cols_k: Vec::new(),
            rows_mirror: Vec::new(),
            cols_mirror: Vec::new(),
            amplitude: Vec::new(),
            phase: Vec::new(),
            cos_prev: Vec::new(),
            cos_now: Vec::new(),
            two_cos_step: Vec::new(),
            frame_amplitude: [Vec::new(), Vec::new()],
            row_slot: vec![usize::MAX; m],
            active_rows: Vec::new(),
            rows: Vec::new(),
            cols: Vec::new(),
            twiddle: (0..m)
                .map(|j| {
                    let angle = TAU * j as f64 / m as f64;
                    Complex32::new(angle.cos() as f32, angle.sin() as f32)
                })
                .collect(),
            transform: Transform::Fft,
            direct: DirectSums::default(),
            envelope: Vec::new(),
            coordinates: (0..grid).map(|j| grid_coordinate(j, grid)).collect(),
        }
    }

    pub fn grid(&self) -> usize {
        self.grid
    }

    /// FFT size M = 2(grid − 1): the number of samples of one field period per axis.
    pub fn fft_size(&self) -> usize {
        self.m
    }

    /// Vertex positions of one clip into `out` (len `clip_len(frames, grid)`).
    pub fn synthesize_into(&mut self, params: &SurfaceParams, frames: usize, out: &mut [f32]) -> Result<()> {
        let grid = self.grid;
        self.fields_into(params, frames, grid, out)?;
        self.compose(params, frames, out);
        Ok(())
    }

    /// The unit-RMS fields `r_i(x, t)` (before envelope, folding and rigid motion)
    /// at the first `samples` (≤ M) grid points per axis, into `out`
    /// (frames, samples, samples, 3). `samples = M` gives one full period.
    pub fn fields_into(&mut self, params: &SurfaceParams, frames: usize, samples: usize, out: &mut [f32]) -> Result<()> {
        self.fields_by(params, frames, samples, out, None)
    }

    /// [`fields_into`](Self::fields_into) by the given transform (None: the cheaper).
    fn fields_by(&mut self, params: &SurfaceParams, frames: usize, samples: usize, out: &mut [f32], transform: Option<Transform>) -> Result<()> {
        params.validate()?;
        if frames == 0 || samples == 0 || samples > self.m {
            return Err(InvalidArgument::new("samples", format!("expected 1..={} samples and frames >= 1", self.m)));
        }
        if out.len() != frames * samples * samples * 3 {
            return Err(InvalidArgument::new("out", format!("expected {} values, got {}", frames * samples * samples * 3, out.len())));
        }
        self.build_table(params, frames);
        self.choose_transform(samples, transform);
        let n_entries = self.amplitude.len();
        let total = 3 * frames;
        let mut next_field = 0;
        for frame in 0..frames {
            let amp = &mut self.frame_amplitude[frame & 1];
            amp.clear();
            for c in 0..3 {
                let now = &self.cos_now[c * n_entries..(c + 1) * n_entries];
                amp.extend(now.iter().zip(&self.amplitude).map(|(cs, a)| (cs * a) as f32));
            }
            self.advance_cosines();
            // Pair fields in (frame, channel) order; a pair may straddle two frames.
            let available = 3 * (frame + 1);
            while next_field + 1 < available || (next_field < available && frame + 1 == frames) {
                let second = (next_field + 1 < total).then_some(next_field + 1);
                self.run_pair(next_field, second, samples, out);
                next_field += 2;
            }
        }
        Ok(())
    }

    /// Amplitudes, phases and cosine recurrences of this clip's active frequencies.
    fn build_table(&mut self, params: &SurfaceParams, frames: usize) {
        let m = self.m;
        let half = m / 2;
        let signed = |k: usize| k as i64 - if k >= half { m as i64 } else { 0 };
        self.rows_k.clear();
        self.cols_k.clear();
        self.rows_mirror.clear();
        self.cols_mirror.clear();
        self.amplitude.clear();
        let mut max_amplitude = 0.0f64;
        for ky in 0..m {
            for kx in 0..m {
                let (sx, sy) = (signed(kx), signed(ky));
                // Half plane without the DC; the Nyquist row and column are dropped
                // (their frequency is ambiguous between ±M/2).
                let in_half = sy > 0 || (sy == 0 && sx > 0);
                if !in_half || kx == half || ky == half {
                    continue;
                }
                let s = spectrum_magnitude(params, sx as f64 / PERIOD, sy as f64 / PERIOD);
                if s > 0.0 {
                    max_amplitude = max_amplitude.max(s);
                    self.rows_k.push(ky);
                    self.cols_k.push(kx);
                    self.amplitude.push(s);
                }
            }
        }
        // Drop the negligible frequencies, then normalise to unit RMS.
        let threshold = SPECTRUM_CUTOFF * max_amplitude;
        let mut kept = 0;
        for i in 0..self.amplitude.len() {
            if self.amplitude[i] >= threshold && self.amplitude[i] > 0.0 {
                self.rows_k[kept] = self.rows_k[i];
                self.cols_k[kept] = self.cols_k[i];
                self.amplitude[kept] = self.amplitude[i];
                kept += 1;
            }
        }
        self.rows_k.truncate(kept);
        self.cols_k.truncate(kept);
        self.amplitude.truncate(kept);
        let norm = self.amplitude.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 0.0 {
            self.amplitude.iter_mut().for_each(|a| *a /= norm);
        }
        for i in 0..kept {
            self.rows_mirror.push((m - self.rows_k[i]) % m);
            self.cols_mirror.push((m - self.cols_k[i]) % m);
        }

        // Compact list of the rows that hold energy (both half planes).
        self.row_slot.iter_mut().for_each(|s| *s = usize::MAX);
        for &r in self.rows_k.iter().chain(&self.rows_mirror) {
            self.row_slot[r] = 0;
        }
        self.active_rows.clear();
        for r in 0..m {
            if self.row_slot[r] == 0 {
                self.row_slot[r] = self.active_rows.len();
                self.active_rows.push(r);
            }
        }

        // Per-channel random functions and the cosine recurrence
        // cos((f+1)Δ + θ) = 2cosΔ · cos(fΔ + θ) − cos((f−1)Δ + θ).
        let dt = if frames > 1 { 1.0 / (frames - 1) as f64 } else { 0.0 };
        self.phase.clear();
        self.cos_prev.clear();
        self.cos_now.clear();
        self.two_cos_step.clear();
        for c in 0..3u64 {
            for i in 0..kept {
                let key = |tag| [tag, c, signed(self.cols_k[i]) as u64, signed(self.rows_k[i]) as u64];
                let theta = TAU * unit_f64(hash(params.phase_seed, &key(TAG_THETA)));
                let psi = TAU * unit_f64(hash(params.phase_seed, &key(TAG_PSI)));
                let rho = 0.5 + unit_f64(hash(params.phase_seed, &key(TAG_RHO)));
                let step = params.speeds[c as usize] * rho * dt;
                self.phase.push(Complex32::new(psi.cos() as f32, psi.sin() as f32));
                self.cos_prev.push((theta - step).cos());
                self.cos_now.push(theta.cos());
                self.two_cos_step.push(2.0 * step.cos());
            }
        }
    }

    /// Sum this clip's fields directly where that costs fewer operations
    /// than the two FFT passes (an operation count of its spectrum, not a
    /// timing: the same choice, so the same bits, on every machine), or as
    /// `forced`; lay out its terms for that.
    fn choose_transform(&mut self, samples: usize, forced: Option<Transform>) {
        let (m, rows, terms) = (self.m, self.active_rows.len(), 2 * self.amplitude.len());
        let direct_ops = (terms + rows * samples) * samples.next_multiple_of(CHUNK);
        let fft_ops = (rows + samples) * m * (usize::BITS - m.leading_zeros()) as usize;
        let cheaper = if direct_ops * DIRECT_COST < fft_ops * FFT_COST { Transform::Direct } else { Transform::Fft };
        self.transform = forced.unwrap_or(cheaper);
        if self.transform == Transform::Direct {
            let mut direct = std::mem::take(&mut self.direct);
            direct.plan(self, samples);
            self.direct = direct;
        }
    }

    fn advance_cosines(&mut self) {
        for ((prev, now), k) in self.cos_prev.iter_mut().zip(self.cos_now.iter_mut()).zip(&self.two_cos_step) {
            let next = k * *now - *prev;
            *prev = *now;
            *now = next;
        }
    }

    /// Inverse FFT of fields `a` and `b` (indices into (frame, channel) order)
    /// packed as `H_a + i·H_b`; writes their real outputs into `out`.
    fn run_pair(&mut self, a: usize, b: Option<usize>, samples: usize, out: &mut [f32]) {
        let (m, n_entries) = (self.m, self.amplitude.len());
        let n_rows = self.active_rows.len();
        let field = |q: usize| ((q / 3) & 1, q % 3);
        let (pa, ca) = field(a);
        let amp_a = &self.frame_amplitude[pa][ca * n_entries..(ca + 1) * n_entries];
        let phase_a = &self.phase[ca * n_entries..(ca + 1) * n_entries];
        let (amp_b, phase_b) = match b.map(field) {
            Some((pb, cb)) => (
                &self.frame_amplitude[pb][cb * n_entries..(cb + 1) * n_entries],
                &self.phase[cb * n_entries..(cb + 1) * n_entries],
            ),
            None => (&amp_a[..0], &phase_a[..0]),
        };
        // Z(k) = H_a(k) + i H_b(k); Z(−k) = conj(H_a(k)) + i conj(H_b(k)).
        let spectrum = |i: usize| {
            let ha = phase_a[i] * amp_a[i];
            let hb = if amp_b.is_empty() { Complex32::default() } else { phase_b[i] * amp_b[i] };
            [Complex32::new(ha.re - hb.im, ha.im + hb.re), Complex32::new(ha.re + hb.im, hb.re - ha.im)]
        };
        if self.transform == Transform::Direct {
            let direct = &mut self.direct;
            direct.values.clear();
            direct.values.extend((0..n_entries).flat_map(spectrum));
            sum_directly(direct, &self.twiddle, &self.active_rows, m);
            let padded = direct.padded;
            for (q, field) in [(Some(a), &direct.fields[0]), (b, &direct.fields[1])] {
                if let Some(q) = q {
                    let base = (q / 3) * samples * samples;
                    for (y, row) in field.chunks_exact(padded).enumerate() {
                        let out_row = &mut out[(base + y * samples) * 3..(base + (y + 1) * samples) * 3];
                        out_row.chunks_exact_mut(3).zip(row).for_each(|(p, &v)| p[q % 3] = v);
                    }
                }
            }
            return;
        }
        self.rows.clear();
        self.rows.resize(n_rows * m, Complex32::default());
        for i in 0..n_entries {
            let [z, z_mirror] = spectrum(i);
            self.rows[self.row_slot[self.rows_k[i]] * m + self.cols_k[i]] += z;
            self.rows[self.row_slot[self.rows_mirror[i]] * m + self.cols_mirror[i]] += z_mirror;
        }
        if n_rows > 0 {
            self.fft.process_with_scratch(&mut self.rows, &mut self.fft_scratch);
        }
        // Transpose the `samples` needed columns, then transform along y.
        self.cols.clear();
        self.cols.resize(samples * m, Complex32::default());
        for (slot, &r) in self.active_rows.iter().enumerate() {
            let row = &self.rows[slot * m..slot * m + samples];
            for (x, v) in row.iter().enumerate() {
                self.cols[x * m + r] = *v;
            }
        }
        self.fft.process_with_scratch(&mut self.cols, &mut self.fft_scratch);
        for (q, take_im) in [(a, false), (b.unwrap_or(usize::MAX), true)] {
            if q == usize::MAX {
                continue;
            }
            let (frame, channel) = (q / 3, q % 3);
            let base = frame * samples * samples;
            for x in 0..samples {
                let col = &self.cols[x * m..x * m + samples];
                for (y, v) in col.iter().enumerate() {
                    out[(base + y * samples + x) * 3 + channel] = if take_im { v.im } else { v.re };
                }
            }
        }
    }

    /// Replace the fields in `out` by vertex positions `E_t(x + d(x, t))`.
    fn compose(&mut self, params: &SurfaceParams, frames: usize, out: &mut [f32]) {
        let grid = self.grid;
        self.envelope.clear();
        for &y in &self.coordinates {
            for &x in &self.coordinates {
                self.envelope.push(params.intensity * (-params.constraint * (x * x + y * y)).exp());
            }
        }
        let zeta = params.folding;
        let coordinates = &self.coordinates;
        for (frame, positions) in out.chunks_exact_mut(grid * grid * 3).enumerate() {
            let (rotation, translation) = rigid_motion(params, frame_time(frame, frames));
            let rows = positions.chunks_exact_mut(3 * grid).zip(self.envelope.chunks_exact(grid)).zip(coordinates);
            for ((row, envelope), &y) in rows {
                for ((p, &g), &x) in row.chunks_exact_mut(3).zip(envelope).zip(coordinates) {
                    let local = Vector3::new(x + g * zeta * p[0] as f64, y + g * zeta * p[1] as f64, g * p[2] as f64);
                    let world = rotation * local + translation;
                    p.copy_from_slice(&[world.x as f32, world.y as f32, world.z as f32]);
                }
            }
        }
    }
}

/// `E_t` as (rotation, translation): `E_t(p) = R(rotation + t · rotation_rate) p + t · drift`.
pub fn rigid_motion(params: &SurfaceParams, t: f64) -> (Rotation3<f64>, Vector3<f64>) {
    let v = |a: [f64; 3], b: [f64; 3]| Vector3::new(a[0] + t * b[0], a[1] + t * b[1], a[2] + t * b[2]);
    (Rotation3::new(v(params.rotation, params.rotation_rate)), v([0.0; 3], params.drift))
}

/// How `run_pair` inverts a pair of fields' spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Transform {
    /// Two passes of FFTs (rustfft), over the active rows, then the output columns.
    Fft,
    /// [`DirectSums`].
    Direct,
}

/// Output columns a chunk of the direct sums holds: four AVX registers a
/// component, accumulated in registers over a row's terms.
const CHUNK: usize = 32;

/// The inverse transform of a sparse spectrum summed term by term:
/// `R(row, x) = Σ_k Z(row, k) e^{2πi k x/M}` over the row's terms, then
/// `f(y, x) = Σ_row R(row, x) e^{2πi row y/M}` over the active rows, each in
/// chunks of `CHUNK` output columns accumulated in registers.
#[derive(Default)]
struct DirectSums {
    /// Output columns rounded up to whole chunks.
    padded: usize,
    /// The spectrum's terms `(index in values, offset of the column's wave
    /// in waves)`, grouped by row slot; row slot r's are `row_start[r] ..
    /// row_start[r + 1]`.
    terms: Vec<(usize, usize)>,
    row_start: Vec<usize>,
    /// Where the counting sort puts each row slot's next term.
    next: Vec<usize>,
    /// e^{2πi k x/M} at x < padded for each column k the terms use, split re / im.
    waves: [Vec<f32>; 2],
    /// Per column k, the offset of its wave (usize::MAX: none yet).
    wave_offset: Vec<usize>,
    /// The current pair of fields' `Z(k)` and `Z(−k)` of each entry, in turn.
    values: Vec<Complex32>,
    /// `R(row slot, x)`, split re / im; per row slot, `row · y mod M` and
    /// the twiddle of output row y.
    row_sums: [Vec<f32>; 2],
    row_phases: Vec<usize>,
    row_twiddles: Vec<Complex32>,
    /// The pair's two fields `Re f` and `Im f`, (y, x) with x < padded.
    fields: [Vec<f32>; 2],
}

impl DirectSums {
    /// Lay out the terms of `synth`'s table for `samples` output columns.
    fn plan(&mut self, synth: &Synthesizer, samples: usize) {
        let m = synth.m;
        self.padded = samples.next_multiple_of(CHUNK);
        self.wave_offset.clear();
        self.wave_offset.resize(m, usize::MAX);
        self.waves.iter_mut().for_each(Vec::clear);
        let n_rows = synth.active_rows.len();
        // Terms in row-slot order: count, then place (a counting sort).
        self.row_start.clear();
        self.row_start.resize(n_rows + 1, 0);
        // Term 2i is entry i's Z(k), term 2i + 1 its Z(−k), as in `values`.
        let entries = || (0..synth.amplitude.len()).flat_map(|i| [(2 * i, synth.rows_k[i], synth.cols_k[i]), (2 * i + 1, synth.rows_mirror[i], synth.cols_mirror[i])]);
        for (_, row, _) in entries() {
            self.row_start[synth.row_slot[row] + 1] += 1;
        }
        for r in 0..n_rows {
            self.row_start[r + 1] += self.row_start[r];
        }
        self.next.clone_from(&self.row_start);
        self.terms.clear();
        self.terms.resize(self.row_start[n_rows], (0, 0));
        for (value, row, col) in entries() {
            if self.wave_offset[col] == usize::MAX {
                self.wave_offset[col] = self.waves[0].len();
                // The exact angle 2π(k·x mod M)/M: no phase drift along the row.
                for x in 0..self.padded {
                    let w = synth.twiddle[col * x % m];
                    self.waves[0].push(w.re);
                    self.waves[1].push(w.im);
                }
            }
            let slot = &mut self.next[synth.row_slot[row]];
            self.terms[*slot] = (value, self.wave_offset[col]);
            *slot += 1;
        }
        for buffer in self.row_sums.iter_mut() {
            buffer.clear();
            buffer.resize(n_rows * self.padded, 0.0);
        }
        for buffer in self.fields.iter_mut() {
            buffer.clear();
            buffer.resize(samples * self.padded, 0.0);
        }
    }
}

with_avx2! {
    /// [`sum_lanes`], AVX2 where available.
    fn sum_directly(d: &mut DirectSums, twiddle: &[Complex32], active_rows: &[usize], m: usize) => sum_lanes, sum_lanes
}

/// `acc += z · (re, im)` over one chunk: `re·z.re − im·z.im`, `im·z.re + re·z.im`.
#[inline(always)]
fn multiply_add(acc: &mut [[f32; CHUNK]; 2], z: Complex32, re: &[f32; CHUNK], im: &[f32; CHUNK]) {
    for l in 0..CHUNK {
        acc[0][l] += re[l] * z.re - im[l] * z.im;
        acc[1][l] += im[l] * z.re + re[l] * z.im;
    }
}

/// The two passes of [`DirectSums`] over `d.values`.
#[inline(always)]
fn sum_lanes(d: &mut DirectSums, twiddle: &[Complex32], active_rows: &[usize], m: usize) {
    let chunk = |v: &[f32], at: usize| -> [f32; CHUNK] { v[at..at + CHUNK].try_into().expect("a whole chunk") };
    let DirectSums { padded, terms, row_start, waves, values, row_sums, row_phases, row_twiddles, fields, .. } = d;
    for (r, bounds) in row_start.windows(2).enumerate() {
        let row_terms = &terms[bounds[0]..bounds[1]];
        for x in (0..*padded).step_by(CHUNK) {
            let mut acc = [[0.0; CHUNK]; 2];
            for &(value, offset) in row_terms {
                multiply_add(&mut acc, values[value], &chunk(&waves[0], offset + x), &chunk(&waves[1], offset + x));
            }
            let at = r * *padded + x;
            row_sums[0][at..at + CHUNK].copy_from_slice(&acc[0]);
            row_sums[1][at..at + CHUNK].copy_from_slice(&acc[1]);
        }
    }
    let [fields_re, fields_im] = fields;
    row_phases.clear();
    row_phases.resize(active_rows.len(), 0);
    for (field_re, field_im) in fields_re.chunks_exact_mut(*padded).zip(fields_im.chunks_exact_mut(*padded)) {
        // row · y mod M, stepped from the row above: no division.
        row_twiddles.clear();
        for (phase, &row) in row_phases.iter_mut().zip(active_rows) {
            row_twiddles.push(twiddle[*phase]);
            *phase += row;
            if *phase >= m {
                *phase -= m;
            }
        }
        for x in (0..*padded).step_by(CHUNK) {
            let mut acc = [[0.0; CHUNK]; 2];
            for (r, &w) in row_twiddles.iter().enumerate() {
                multiply_add(&mut acc, w, &chunk(&row_sums[0], r * *padded + x), &chunk(&row_sums[1], r * *padded + x));
            }
            field_re[x..x + CHUNK].copy_from_slice(&acc[0]);
            field_im[x..x + CHUNK].copy_from_slice(&acc[1]);
        }
    }
}

/// Vertex positions of one clip: (frames, grid, grid, 3) flattened.
pub fn synthesize(params: &SurfaceParams, frames: usize, grid: usize) -> Result<Vec<f32>> {
    let mut out = vec![0.0; clip_len(frames, grid)];
    Synthesizer::new(grid).synthesize_into(params, frames, &mut out)?;
    Ok(out)
}

/// Many clips in parallel into `out` (n, frames, grid, grid, 3); clip i depends
/// only on `params[i]`, so the bytes do not depend on the thread count.
pub fn synthesize_batch(params: &[SurfaceParams], frames: usize, grid: usize, out: &mut [f32]) -> Result<()> {
    for (i, p) in params.iter().enumerate() {
        p.validate().map_err(|e| InvalidArgument::new(e.name.replacen("params", &format!("params[{i}]"), 1), e.message))?;
    }
    let len = clip_len(frames, grid);
    if out.len() != params.len() * len {
        return Err(InvalidArgument::new("out", format!("expected {} values, got {}", params.len() * len, out.len())));
    }
    out.par_chunks_mut(len.max(1))
        .zip(params.par_iter())
        .try_for_each_init(|| Synthesizer::new(grid), |s, (chunk, p)| s.synthesize_into(p, frames, chunk))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::SurfaceConfig;

    fn still(seed: u64) -> SurfaceParams {
        let mut p = SurfaceConfig::default().sample(seed).unwrap();
        p.rotation = [0.0; 3];
        p.rotation_rate = [0.0; 3];
        p.drift = [0.0; 3];
        p
    }

    fn fields(p: &SurfaceParams, frames: usize, grid: usize, samples: usize) -> Vec<f32> {
        fields_by(p, frames, grid, samples, None)
    }

    fn fields_by(p: &SurfaceParams, frames: usize, grid: usize, samples: usize, transform: Option<Transform>) -> Vec<f32> {
        let mut out = vec![0.0; frames * samples * samples * 3];
        Synthesizer::new(grid).fields_by(p, frames, samples, &mut out, transform).unwrap();
        out
    }

    /// Direct evaluation of r_i at one sample from the same frequency table.
    fn direct_field(p: &SurfaceParams, frames: usize, grid: usize, frame: usize, jx: usize, jy: usize) -> [f64; 3] {
        let mut s = Synthesizer::new(grid);
        s.build_table(p, frames);
        let m = s.m as f64;
        let n = s.amplitude.len();
        let t = frame_time(frame, frames);
        let half = s.m / 2;
        let signed = |k: usize| k as f64 - if k >= half { m } else { 0.0 };
        let mut r = [0.0; 3];
        for c in 0..3 {
            for i in 0..n {
                let (kx, ky) = (signed(s.cols_k[i]), signed(s.rows_k[i]));
                let key = |tag| [tag, c as u64, kx as i64 as u64, ky as i64 as u64];
                let theta = TAU * unit_f64(hash(p.phase_seed, &key(TAG_THETA)));
                let psi = TAU * unit_f64(hash(p.phase_seed, &key(TAG_PSI)));
                let rho = 0.5 + unit_f64(hash(p.phase_seed, &key(TAG_RHO)));
                let arg = TAU * (kx * jx as f64 + ky * jy as f64) / m + psi;
                r[c] += 2.0 * s.amplitude[i] * (t * p.speeds[c] * rho + theta).cos() * arg.cos();
            }
        }
        r
    }

    #[test]
    fn both_transforms_equal_the_fourier_sums_in_f64() {
        let p = still(3);
        let (frames, grid) = (5, 17);
        for transform in [Transform::Fft, Transform::Direct] {
            let f = fields_by(&p, frames, grid, grid, Some(transform));
            for &(frame, jx, jy) in &[(0, 0, 0), (4, 3, 11), (2, 16, 16), (3, 7, 0)] {
                let d = direct_field(&p, frames, grid, frame, jx, jy);
                for c in 0..3 {
                    let got = f[((frame * grid + jy) * grid + jx) * 3 + c] as f64;
                    assert!((got - d[c]).abs() < 2e-4, "{transform:?} frame {frame} ({jx},{jy}) ch {c}: {got} vs {}", d[c]);
                }
            }
        }
    }

    #[test]
    fn direct_sums_equal_the_ffts_to_rounding() {
        // Grids and sample counts off the chunk size, a full period, and an
        // odd frame count (its last field has no partner in the pair).
        for (seed, grid, samples, frames) in [(1, 64, 64, 3), (2, 17, 17, 2), (3, 33, 64, 1), (4, 24, 13, 3), (5, 96, 96, 2)] {
            let p = SurfaceConfig::default().sample(seed).unwrap();
            let fft = fields_by(&p, frames, grid, samples, Some(Transform::Fft));
            let direct = fields_by(&p, frames, grid, samples, Some(Transform::Direct));
            let worst = fft.iter().zip(&direct).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            // Fields have unit RMS: the two roundings differ by ~1e-6.
            assert!(worst < 2e-5, "seed {seed}, grid {grid}, {samples} samples: {worst}");
        }
    }

    #[test]
    fn direct_sums_give_the_same_bits_in_the_baseline_and_avx2_builds() {
        let p = SurfaceConfig::default().sample(6).unwrap();
        let bits = || fields_by(&p, 3, 40, 40, Some(Transform::Direct)).iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
        let (baseline, dispatched) = crate::lanes::tests::both_builds(bits);
        assert_eq!(baseline, dispatched);
    }

    #[test]
    fn fields_have_zero_mean_over_a_period_and_unit_rms_on_average() {
        let mut rms_sum = 0.0;
        let seeds = 40;
        for seed in 0..seeds {
            let p = still(seed);
            let grid = 33;
            let m = 2 * (grid - 1);
            let f = fields(&p, 1, grid, m);
            for c in 0..3 {
                let vals: Vec<f64> = f.iter().skip(c).step_by(3).map(|&v| v as f64).collect();
                let mean = vals.iter().sum::<f64>() / vals.len() as f64;
                let rms = (vals.iter().map(|v| v * v).sum::<f64>() / vals.len() as f64).sqrt();
                assert!(mean.abs() < 1e-5 * rms.max(1e-3), "seed {seed} channel {c}: mean {mean}, rms {rms}");
                rms_sum += rms * rms;
            }
        }
        let mean_ms = rms_sum / (3 * seeds) as f64;
        assert!((mean_ms - 1.0).abs() < 0.25, "mean square {mean_ms}");
    }

    #[test]
    fn surface_is_grid_independent_for_a_band_limited_spectrum() {
        // Coarse vertex j sits at fine vertex 2j; the same frequencies carry the same draws.
        let mut p = still(5);
        p.flexibility = 0.4;
        let (frames, coarse, fine) = (3, 33, 65);
        let a = synthesize(&p, frames, coarse).unwrap();
        let b = synthesize(&p, frames, fine).unwrap();
        for f in 0..frames {
            for jy in 0..coarse {
                for jx in 0..coarse {
                    for c in 0..3 {
                        let va = a[((f * coarse + jy) * coarse + jx) * 3 + c];
                        let vb = b[((f * fine + 2 * jy) * fine + 2 * jx) * 3 + c];
                        assert!((va - vb).abs() < 1e-5, "{va} vs {vb}");
                    }
                }
            }
        }
    }

    #[test]
    fn rigid_motion_is_a_rotation_and_translation_of_the_still_surface() {
        let mut p = still(8);
        let (frames, grid) = (4, 9);
        let base = synthesize(&p, frames, grid).unwrap();
        p.rotation = [0.1, -0.05, 0.7];
        p.rotation_rate = [0.02, 0.03, -0.2];
        p.drift = [0.05, -0.02, 0.1];
        let moved = synthesize(&p, frames, grid).unwrap();
        for f in 0..frames {
            let t = frame_time(f, frames);
            let v = |a: [f64; 3], b: [f64; 3]| Vector3::new(a[0] + t * b[0], a[1] + t * b[1], a[2] + t * b[2]);
            let r = Rotation3::new(v(p.rotation, p.rotation_rate));
            for i in 0..grid * grid {
                let o = (f * grid * grid + i) * 3;
                let q = r * Vector3::new(base[o] as f64, base[o + 1] as f64, base[o + 2] as f64) + v([0.0; 3], p.drift);
                for c in 0..3 {
                    assert!((q[c] - moved[o + c] as f64).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn batch_equals_single_clips() {
        let params: Vec<_> = (0..5).map(|s| SurfaceConfig::default().sample(s).unwrap()).collect();
        let (frames, grid) = (4, 12);
        let mut out = vec![0.0; params.len() * clip_len(frames, grid)];
        synthesize_batch(&params, frames, grid, &mut out).unwrap();
        for (i, p) in params.iter().enumerate() {
            let single = synthesize(p, frames, grid).unwrap();
            let len = single.len();
            assert!(single.iter().zip(&out[i * len..(i + 1) * len]).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    #[test]
    fn bad_params_in_a_batch_name_their_index() {
        let mut params: Vec<_> = (0..3).map(|s| SurfaceConfig::default().sample(s).unwrap()).collect();
        params[2].folding = -1.0;
        let mut out = vec![0.0; 3 * clip_len(2, 4)];
        let err = synthesize_batch(&params, 2, 4, &mut out).unwrap_err();
        assert_eq!(err.name, "params[2].folding");
    }

    #[test]
    fn vanishing_spectrum_gives_a_flat_still_patch_not_nan() {
        let mut p = still(1);
        p.flexibility = 1e-3;
        let out = synthesize(&p, 2, 8).unwrap();
        assert!(out.iter().all(|v| v.is_finite()));
        assert!(out.iter().skip(2).step_by(3).all(|&z| z == 0.0));
    }
}
