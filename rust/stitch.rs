//! Constant overlap-add (COLA) stitching of patch depth videos.
//!
//! A video of shape (T, H, W) is covered by patches of shape (Lt, Ls, Ls) at a
//! hop of half a patch on each axis, over the video padded by half a patch at
//! the front of each axis and at the back by enough to end on a whole hop.
//! Both windows (`Window`, n = 0 .. L − 1) have `w[n] + w[n + L/2] = 1`, so
//! the separable windows `w_t ⊗ w_y ⊗ w_x` of the patches sum to one at
//! every sample of the original video: the overlap-add needs no
//! normalisation. The paper's triangle `w[n] = 1 − |2n + 1 − L| / L` has kinks
//! at a patch's ends and centre, which fall on a grid at the hop: wherever
//! neighbouring patches disagree, the stitched depth's slope jumps there,
//! and the grid shows in its spectrum. The Hann window
//! `w[n] = sin²(π (n + ½) / L)` has a continuous slope, zero where the
//! triangle kinks, so disagreement blends in without a grid
//! (docs/stitching.md).
//!
//! The video is expected padded symmetrically (numpy's "symmetric" mode) and
//! the coarse depth is mirrored the same way under the padding. Each patch's
//! depth is first aligned, frame by frame, to the coarse depth under it by the least-squares GBR `α x + β y + λ p + τ ≈ coarse` (x, y:
//! patch column and row; 4×4 normal equations in f64, solved by SVD so a flat
//! patch gets the minimum-norm fit). Shapes: patches (N, Lt, Ls, Ls),
//! origins (N, 3) as (t, y, x) in padded coordinates, coarse and output
//! (T, H, W), all row-major f32.
//!
//! Temporal alignment (beyond the paper): each stitched frame is right only
//! up to its own GBR, so a video flickers in tilt and relief amplitude.
//! `temporal_align` writes frame t as `plane_0 + Λ_t · r_t`, where `r_t` is the
//! frame minus its least-squares plane (`α x + β y + τ`), `plane_0` is frame
//! 0's plane, and `Λ_0 = 1`, `Λ_t = s_t Λ_{t−1} ‖r_{t−1}‖ / ‖r_t‖` with `s_t` the
//! sign of `⟨r_t, r_{t−1}⟩`. Every frame thus keeps frame 0's GBR: its plane,
//! its relief norm, and a sign consistent with its predecessor. It equals
//! chaining, frame by frame, the GBR that best maps a frame onto the aligned
//! previous one, with λ from the reduced-major-axis fit (`‖q‖/‖p‖`) rather than
//! least squares, whose regression dilution would shrink the relief by the
//! frames' correlation at every step of a long video. Flat frames (relief norm
//! ≤ 1e-9 of the largest) become `plane_0` and are skipped in the chain. The
//! price: true changes of tilt and relief amplitude over time are given up,
//! but a network trained with per-frame GBR-invariant losses does not predict
//! them anyway. The result is invariant to any per-frame GBR of the input, up
//! to one global GBR (tested).

use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

use crate::error::{InvalidArgument, Result};

/// Padding and patch grid of a video shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub shape: [usize; 3],
    pub patch: [usize; 3],
    /// Front padding per axis (half a patch).
    pub pad: [usize; 3],
    /// Padded shape: a whole number of hops.
    pub padded: [usize; 3],
}

impl Layout {
    pub fn new(shape: [usize; 3], patch: [usize; 3]) -> Result<Self> {
        if shape.contains(&0) {
            return Err(InvalidArgument::new("shape", format!("expected a non-empty (T, H, W), got {shape:?}")));
        }
        if patch.iter().any(|&l| l < 2 || l % 2 != 0) {
            return Err(InvalidArgument::new("patch", format!("expected even sizes >= 2, got {patch:?}")));
        }
        let mut pad = [0; 3];
        let mut padded = [0; 3];
        for a in 0..3 {
            let hop = patch[a] / 2;
            pad[a] = hop;
            // Front pad + video + back pad, rounded up to whole hops, at least one patch.
            padded[a] = (shape[a] + 2 * hop).div_ceil(hop).max(2) * hop;
        }
        Ok(Self { shape, patch, pad, padded })
    }

    /// Origins (t, y, x) of every patch, time-major.
    pub fn origins(&self) -> Vec<[usize; 3]> {
        let counts: Vec<usize> = (0..3).map(|a| (self.padded[a] - self.patch[a]) / (self.patch[a] / 2) + 1).collect();
        let mut out = Vec::with_capacity(counts.iter().product());
        for i in 0..counts[0] {
            for j in 0..counts[1] {
                for k in 0..counts[2] {
                    out.push([i * self.patch[0] / 2, j * self.patch[1] / 2, k * self.patch[2] / 2]);
                }
            }
        }
        out
    }
}

/// The overlap-add window along each axis; both are COLA at hop L/2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Window {
    /// The paper's: `1 − |2n + 1 − L| / L`.
    Triangle,
    /// `sin²(π (n + ½) / L)`: no kinks, so no grid where patches disagree.
    Hann,
}

impl Window {
    /// The window named `"triangle"` or `"hann"`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "triangle" => Ok(Self::Triangle),
            "hann" => Ok(Self::Hann),
            _ => Err(InvalidArgument::new("window", format!("expected 'hann' or 'triangle', got {name:?}"))),
        }
    }

    /// The window's `l` weights (`l` even).
    pub fn weights(self, l: usize) -> Vec<f32> {
        (0..l)
            .map(|n| match self {
                Self::Triangle => 1.0 - ((2 * n + 1) as f32 - l as f32).abs() / l as f32,
                Self::Hann => (std::f64::consts::PI * (n as f64 + 0.5) / l as f64).sin().powi(2) as f32,
            })
            .collect()
    }
}

/// Least-squares (α, β, λ, τ) with `α x + β y + λ p + τ ≈ c` over one frame.
pub fn gbr_fit(p: &[f32], c: &[f32], width: usize) -> [f64; 4] {
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = Vector4::<f64>::zeros();
    for (i, (&pv, &cv)) in p.iter().zip(c).enumerate() {
        let row = Vector4::new((i % width) as f64, (i / width) as f64, pv as f64, 1.0);
        ata += row * row.transpose();
        atb += row * cv as f64;
    }
    let svd = ata.svd(true, true);
    let eps = 1e-12 * svd.singular_values.max();
    match svd.solve(&atb, eps) {
        Ok(x) => [x[0], x[1], x[2], x[3]],
        Err(_) => [0.0; 4],
    }
}

/// Coarse depth under a patch, outside the video mirrored like the video's
/// own padding (numpy's "symmetric": … 2 1 0 | 0 1 2 … n−1 | n−1 n−2 …).
pub(crate) fn coarse_at(coarse: &[f32], layout: &Layout, t: isize, y: isize, x: isize) -> f32 {
    let [tt, hh, ww] = layout.shape;
    let mirror = |v: isize, n: usize| {
        let m = v.rem_euclid(2 * n as isize) as usize;
        if m < n { m } else { 2 * n - 1 - m }
    };
    coarse[(mirror(t, tt) * hh + mirror(y, hh)) * ww + mirror(x, ww)]
}

/// Streaming overlap-add: patches arrive in chunks (`add`), in any grouping,
/// and `finish` returns the video. Memory is the video and the coarse depth
/// plus one chunk, whatever the video's length. Chunks are accumulated in the
/// order they arrive (each chunk's patches in order), so the same patches in
/// the same order give the same bytes whatever the chunking or thread count.
pub struct Stitcher {
    layout: Layout,
    coarse: Vec<f32>,
    video: Vec<f32>,
    windows: [Vec<f32>; 3],
}

impl Stitcher {
    /// `coarse`: the coarse depth (T, H, W) the patches are aligned to.
    pub fn new(layout: Layout, coarse: Vec<f32>, window: Window) -> Result<Self> {
        if coarse.len() != layout.shape.iter().product::<usize>() {
            return Err(InvalidArgument::new("coarse", format!("expected shape {:?}", layout.shape)));
        }
        if !coarse.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("coarse", "expected finite values"));
        }
        let windows = layout.patch.map(|l| window.weights(l));
        Ok(Self { layout, video: vec![0.0; coarse.len()], coarse, windows })
    }

    /// Align the patches (N, Lt, Ls, Ls) at `origins` (padded (t, y, x)) to the
    /// coarse depth, window them and add them into the video.
    pub fn add(&mut self, patches: &[f32], origins: &[[usize; 3]]) -> Result<()> {
        let layout = &self.layout;
        let [lt, ly, lx] = layout.patch;
        let patch_len = lt * ly * lx;
        if patches.len() != origins.len() * patch_len {
            return Err(InvalidArgument::new("patches", format!("expected {} patches of {:?}, got {} values", origins.len(), layout.patch, patches.len())));
        }
        if let Some(o) = origins.iter().find(|o| (0..3).any(|a| o[a] + layout.patch[a] > layout.padded[a])) {
            return Err(InvalidArgument::new("origins", format!("patch at {o:?} leaves the padded video {:?}", layout.padded)));
        }
        if !patches.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("patches", "expected finite values"));
        }
        let [wt, wy, wx] = &self.windows;
        let pad = layout.pad.map(|p| p as isize);
        let coarse = &self.coarse;
        // Align and window each patch in parallel; accumulate serially (fixed order).
        let aligned: Vec<Vec<f32>> = origins
            .par_iter()
            .zip(patches.par_chunks(patch_len))
            .map_init(|| vec![0.0f32; ly * lx], |under, (o, patch)| {
                let mut out = vec![0.0f32; patch_len];
                for t in 0..lt {
                    let frame = &patch[t * ly * lx..(t + 1) * ly * lx];
                    for y in 0..ly {
                        for x in 0..lx {
                            let (gt, gy, gx) = (o[0] as isize + t as isize - pad[0], o[1] as isize + y as isize - pad[1], o[2] as isize + x as isize - pad[2]);
                            under[y * lx + x] = coarse_at(coarse, layout, gt, gy, gx);
                        }
                    }
                    let [a, b, l, c] = gbr_fit(frame, under, lx);
                    for y in 0..ly {
                        for x in 0..lx {
                            let v = a * x as f64 + b * y as f64 + l * frame[y * lx + x] as f64 + c;
                            out[(t * ly + y) * lx + x] = (v * (wt[t] * wy[y] * wx[x]) as f64) as f32;
                        }
                    }
                }
                out
            })
            .collect();
        let [tt, hh, ww] = layout.shape;
        for (o, patch) in origins.iter().zip(&aligned) {
            for t in 0..lt {
                let gt = o[0] as isize + t as isize - pad[0];
                if gt < 0 || gt >= tt as isize {
                    continue;
                }
                for y in 0..ly {
                    let gy = o[1] as isize + y as isize - pad[1];
                    if gy < 0 || gy >= hh as isize {
                        continue;
                    }
                    for x in 0..lx {
                        let gx = o[2] as isize + x as isize - pad[2];
                        if gx >= 0 && gx < ww as isize {
                            self.video[(gt as usize * hh + gy as usize) * ww + gx as usize] += patch[(t * ly + y) * lx + x];
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The stitched video (T, H, W).
    pub fn finish(self) -> Vec<f32> {
        self.video
    }
}

/// Align every patch to the coarse depth and overlap-add them into (T, H, W).
pub fn stitch(patches: &[f32], origins: &[[usize; 3]], coarse: &[f32], layout: &Layout, window: Window) -> Result<Vec<f32>> {
    let mut stitcher = Stitcher::new(*layout, coarse.to_vec(), window)?;
    stitcher.add(patches, origins)?;
    Ok(stitcher.finish())
}

/// Least-squares plane `α x + β y + τ` of one frame (H·W values, row-major).
fn plane_fit(frame: &[f32], width: usize) -> [f64; 3] {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for (i, &v) in frame.iter().enumerate() {
        let row = nalgebra::Vector3::new((i % width) as f64, (i / width) as f64, 1.0);
        ata += row * row.transpose();
        atb += row * v as f64;
    }
    let svd = ata.svd(true, true);
    let eps = 1e-12 * svd.singular_values.max();
    svd.solve(&atb, eps).map(|x| [x[0], x[1], x[2]]).unwrap_or([0.0; 3])
}

fn plane_at(c: &[f64; 3], i: usize, width: usize) -> f64 {
    c[0] * (i % width) as f64 + c[1] * (i / width) as f64 + c[2]
}

/// ⟨r_a, r_b⟩ of two frames' reliefs (frame minus its plane).
fn relief_dot(a: &[f32], pa: &[f64; 3], b: &[f32], pb: &[f64; 3], width: usize) -> f64 {
    a.iter().zip(b).enumerate().map(|(i, (&u, &v))| (u as f64 - plane_at(pa, i, width)) * (v as f64 - plane_at(pb, i, width))).sum()
}

/// Give every frame of a depth video (T, H, W) frame 0's GBR (see the module
/// header), in place. Per-frame statistics run in parallel; the chain is a
/// scalar recurrence.
pub fn temporal_align(depth: &mut [f32], shape: [usize; 3]) -> Result<()> {
    let [t, h, w] = shape;
    let len = h * w;
    if len == 0 || depth.len() != t * len {
        return Err(InvalidArgument::new("depth", format!("expected {t}×{h}×{w} values, got {}", depth.len())));
    }
    if !depth.iter().all(|v| v.is_finite()) {
        return Err(InvalidArgument::new("depth", "expected finite values"));
    }
    let planes: Vec<[f64; 3]> = depth.par_chunks(len).map(|f| plane_fit(f, w)).collect();
    let norms: Vec<f64> = depth.par_chunks(len).zip(&planes).map(|(f, p)| relief_dot(f, p, f, p, w).sqrt()).collect();
    let flat = 1e-9 * norms.iter().cloned().fold(0.0, f64::max);
    // Λ_t by the recurrence, against the last frame that is not flat.
    let mut scales = vec![0.0f64; t];
    let mut reference: Option<usize> = None;
    for k in 0..t {
        if norms[k] <= flat {
            continue;
        }
        scales[k] = match reference {
            None => 1.0,
            Some(r) => {
                let (a, b) = (&depth[k * len..(k + 1) * len], &depth[r * len..(r + 1) * len]);
                let sign = if relief_dot(a, &planes[k], b, &planes[r], w) < 0.0 { -1.0 } else { 1.0 };
                sign * scales[r] * norms[r] / norms[k]
            }
        };
        reference = Some(k);
    }
    let base = planes[0];
    depth.par_chunks_mut(len).zip(&planes).zip(&scales).for_each(|((frame, plane), &scale)| {
        for (i, v) in frame.iter_mut().enumerate() {
            *v = (plane_at(&base, i, w) + scale * (*v as f64 - plane_at(plane, i, w))) as f32;
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_sum_to_one_everywhere_in_the_video_borders_included() {
        for window in [Window::Triangle, Window::Hann] {
            for (shape, patch) in [([16, 64, 64], [16, 64, 64]), ([21, 70, 45], [16, 64, 64]), ([5, 9, 13], [4, 8, 8]), ([1, 3, 2], [4, 8, 8])] {
                let layout = Layout::new(shape, patch).unwrap();
                let ones = vec![1.0f32; patch.iter().product::<usize>()];
                let origins = layout.origins();
                let patches: Vec<f32> = origins.iter().flat_map(|_| ones.iter().copied()).collect();
                // Ones aligned to a constant coarse depth of one stay ones: the output is the window sum.
                let coarse = vec![1.0f32; shape.iter().product()];
                let sum = stitch(&patches, &origins, &coarse, &layout, window).unwrap();
                let range = sum.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
                assert!(sum.iter().all(|v| (v - 1.0).abs() < 1e-5), "{window:?} {shape:?}: {range:?}");
            }
        }
    }

    #[test]
    fn chunked_stitching_gives_the_same_bytes() {
        let layout = Layout::new([9, 20, 27], [4, 8, 8]).unwrap();
        let origins = layout.origins();
        let len = 4 * 8 * 8;
        let patches: Vec<f32> = (0..origins.len() * len).map(|i| ((i * 37 % 101) as f32 * 0.1).sin()).collect();
        let coarse: Vec<f32> = (0..9 * 20 * 27).map(|i| ((i % 27) as f32 * 0.3).cos() + (i / 540) as f32 * 0.1).collect();
        let whole = stitch(&patches, &origins, &coarse, &layout, Window::Hann).unwrap();
        let mut stitcher = Stitcher::new(layout, coarse, Window::Hann).unwrap();
        for (chunk, o) in patches.chunks(7 * len).zip(origins.chunks(7)) {
            stitcher.add(chunk, o).unwrap();
        }
        assert_eq!(stitcher.finish(), whole);
    }

    #[test]
    fn windows_are_cola_at_half_hop_symmetric_and_the_hann_has_no_kinks() {
        for l in [4, 8, 16, 64] {
            for window in [Window::Triangle, Window::Hann] {
                let w = window.weights(l);
                for n in 0..l / 2 {
                    assert!((w[n] + w[n + l / 2] - 1.0).abs() < 1e-6, "{window:?} {l}");
                    assert_eq!(w[n], w[l - 1 - n], "{window:?} {l}");
                }
            }
            // How far the slope turns in one sample, against the steepest slope: the
            // triangle's turns by its whole size at its centre (a kink at any L), the
            // Hann's by about 2π/L of it (a continuous slope, also across the window's ends).
            let turn = |w: &[f32]| {
                let mut padded = vec![0.0f32];
                padded.extend_from_slice(w);
                padded.push(0.0);
                let slope: Vec<f32> = padded.windows(2).map(|p| p[1] - p[0]).collect();
                let steepest = slope.iter().fold(0.0f32, |m, d| m.max(d.abs()));
                slope.windows(2).fold(0.0f32, |m, d| m.max((d[1] - d[0]).abs())) / steepest
            };
            if l >= 16 {
                assert!(turn(&Window::Triangle.weights(l)) > 0.99, "{l}");
                assert!(turn(&Window::Hann.weights(l)) < 1.1 * std::f32::consts::TAU / l as f32, "{l}");
            }
        }
        assert_eq!(Window::from_name("hann").unwrap(), Window::Hann);
        assert_eq!(Window::from_name("triangle").unwrap(), Window::Triangle);
        assert_eq!(Window::from_name("hanning").err().unwrap().name, "window");
    }

    #[test]
    fn gbr_fit_recovers_a_transform() {
        let p: Vec<f32> = (0..64).map(|i| ((i * 7 % 13) as f32).sin()).collect();
        let c: Vec<f32> = p.iter().enumerate().map(|(i, &v)| 0.5 * (i % 8) as f32 - 0.25 * (i / 8) as f32 + 3.0 * v + 2.0).collect();
        let [a, b, l, t] = gbr_fit(&p, &c, 8);
        assert!((a - 0.5).abs() < 1e-6 && (b + 0.25).abs() < 1e-6 && (l - 3.0).abs() < 1e-6 && (t - 2.0).abs() < 1e-5);
        // A flat patch gets the best plane, not NaN.
        let flat = gbr_fit(&vec![0.0; 64], &c, 8);
        assert!(flat.iter().all(|v| v.is_finite()));
    }

    /// A fixed relief seen through a different GBR in every frame (sign flips
    /// included) comes back as frame 0 in every frame; frame 0 is unchanged.
    #[test]
    fn temporal_align_undoes_per_frame_gbr() {
        let (t, h, w) = (6, 9, 11);
        let relief: Vec<f32> = (0..h * w).map(|i| ((i % w) as f32 * 0.7).sin() * ((i / w) as f32 * 0.5).cos()).collect();
        let gbrs = [(0.0, 0.0, 1.0, 0.0), (0.3, -0.2, 2.0, 1.0), (-0.1, 0.4, -0.5, 3.0), (0.0, 0.1, 0.25, -2.0), (1.0, 1.0, -4.0, 0.5), (0.2, 0.0, 1.5, 0.0)];
        let mut video: Vec<f32> = gbrs
            .iter()
            .flat_map(|&(a, b, l, c)| relief.iter().enumerate().map(move |(i, &v)| a * (i % w) as f32 + b * (i / w) as f32 + l * v + c))
            .collect();
        let first = video[..h * w].to_vec();
        temporal_align(&mut video, [t, h, w]).unwrap();
        for frame in video.chunks(h * w) {
            let err = frame.iter().zip(&first).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            assert!(err < 1e-4, "{err}");
        }
        // A flat frame in the middle neither breaks the chain nor yields NaN.
        video[2 * h * w..3 * h * w].fill(7.0);
        temporal_align(&mut video, [t, h, w]).unwrap();
        assert!(video.iter().all(|v| v.is_finite()));
        let last = &video[5 * h * w..];
        assert!(last.iter().zip(&first).all(|(a, b)| (a - b).abs() < 1e-4));
        assert!(temporal_align(&mut video, [t, h, w + 1]).is_err());
    }
}
