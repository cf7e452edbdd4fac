//! Joint alignment of overlapping patch depths (beyond the paper).
//!
//! The paper aligns each patch on its own to the coarse depth, so the coarse
//! pass alone sets the stitched video's large-scale shape. Here all the
//! patch-frames that cover a video frame are aligned together: they must
//! agree with one another where they overlap, and are tied to the coarse
//! depth by a weight μ. For frame t, with patch-frames k (patch n at padded
//! origin o, its frame f = t + pad_t − o_t), a_k = (u, v, p̂_k, 1) at each
//! pixel (u, v: the pixel's centre in patch widths from the patch's centre,
//! in [−½, ½]; p̂_k: the patch-frame's depth standardised over Ω_k) and GBRs
//! g_k ∈ ℝ⁴, it minimises
//!
//! ```text
//! E(g) = Σ_pix Σ_k w_k (a_kᵀg_k − S)²  +  μ Σ_k Σ_{pix ∈ Ω_k} (a_kᵀg_k − C)²,   S = Σ_k w_k a_kᵀg_k
//! ```
//!
//! over the video's pixels only (Ω_k: patch-frame k's pixels inside the
//! video; w_k: its separable window weight (`stitch::Window`), and Σ_k w_k = 1 at every
//! pixel, see `stitch`; C: the coarse depth). The first term is the
//! patches' disagreement about the stitched depth S, which is the output;
//! the second keeps the whole from drifting (the first alone is blind to any
//! common GBR and is zero for flat patches). μ → ∞ fits each patch to the
//! coarse depth on its own over its pixels in the video (tested); the
//! paper's fit also counts the padding, against the coarse depth mirrored
//! there. Neither term counts the padding: a video mirrored top to bottom
//! is lit from below there, so the network reads its relief inverted, and
//! fitting the mirrored coarse depth scored worse on real video (README).
//! Normal equations: `G g = μ b` with `G_kk = Σ_Ωk (w_k − w_k² + μ) a_k a_kᵀ`,
//! `G_kl = −Σ_{Ωk∩Ωl} w_k w_l a_k a_lᵀ`, `b_k = Σ_Ωk a_k C`: block sparse, a
//! patch-frame meeting at most 17 others
//! (its 3 × 3 spatial neighbourhood in the frame's two temporal windows),
//! solved in f64 by conjugate gradients preconditioned with the 4 × 4
//! diagonal blocks (a ridge of 1e-9 of a block's mean diagonal keeps a flat
//! patch's GBR finite).
//!
//! Frames are independent given their patches. Patches arrive in chunks in
//! any order; a frame is solved as soon as every patch covering it has
//! arrived, frames solved together run in parallel, and a patch is dropped
//! once all its frames are solved, so time-major input keeps two temporal
//! windows of patches in memory. The bytes depend only on the patches, not
//! on their order, chunking or the thread count. Shapes as in `stitch`:
//! patches (N, Lt, Ls, Ls) at padded origins (t, y, x) on the layout's grid,
//! coarse and output (T, H, W), row-major f32.

use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

use crate::error::{InvalidArgument, Result};
use crate::stitch::{Layout, Window};

/// One patch-frame of the frame being solved.
struct PatchFrame<'a> {
    /// The patch's frame f (Ly·Lx values, row-major).
    values: &'a [f32],
    /// Temporal window weight w_t[f].
    weight_t: f64,
    /// The patch's top-left corner in video coordinates (may be negative).
    corner: [isize; 2],
    /// Its pixels inside the video: rows y0..y1, columns x0..x1 (video coordinates).
    rows: (usize, usize),
    cols: (usize, usize),
    /// Spatial grid index (row, column) of the patch.
    cell: [usize; 2],
    /// Standardisation of the values.
    mean: f64,
    inv_std: f64,
}

/// Streaming joint stitcher: `add` patches in any grouping and order, then `finish`.
pub struct JointStitcher {
    layout: Layout,
    coarse: Vec<f32>,
    coarse_weight: f64,
    video: Vec<f32>,
    windows: [Vec<f32>; 3],
    /// Patches per axis of the grid.
    counts: [usize; 3],
    /// Received patches not yet released, by grid index.
    patches: Vec<Option<Vec<f32>>>,
    received: Vec<bool>,
    /// Per frame: covering patches still to arrive.
    missing: Vec<usize>,
}

impl JointStitcher {
    /// `coarse`: the coarse depth (T, H, W); `coarse_weight`: μ > 0.
    pub fn new(layout: Layout, coarse: Vec<f32>, coarse_weight: f64, window: Window) -> Result<Self> {
        if coarse.len() != layout.shape.iter().product::<usize>() {
            return Err(InvalidArgument::new("coarse", format!("expected shape {:?}", layout.shape)));
        }
        if !coarse.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("coarse", "expected finite values"));
        }
        if !(coarse_weight.is_finite() && coarse_weight > 0.0) {
            return Err(InvalidArgument::new("coarse_weight", format!("expected a finite number > 0, got {coarse_weight}")));
        }
        let counts: [usize; 3] = std::array::from_fn(|a| (layout.padded[a] - layout.patch[a]) / (layout.patch[a] / 2) + 1);
        let mut stitcher = Self {
            video: vec![0.0; coarse.len()],
            coarse,
            coarse_weight,
            windows: layout.patch.map(|l| window.weights(l)),
            patches: vec![None; counts.iter().product()],
            received: vec![false; counts.iter().product()],
            missing: vec![0; layout.shape[0]],
            counts,
            layout,
        };
        for t in 0..layout.shape[0] {
            stitcher.missing[t] = stitcher.windows_of(t).count() * counts[1] * counts[2];
        }
        Ok(stitcher)
    }

    /// Temporal window indices i whose patches cover video frame t.
    fn windows_of(&self, t: usize) -> impl Iterator<Item = usize> {
        let (hop, pad, lt, n) = (self.layout.patch[0] / 2, self.layout.pad[0], self.layout.patch[0], self.counts[0]);
        let tp = t + pad;
        (0..n).filter(move |&i| i * hop <= tp && tp < i * hop + lt)
    }

    /// Video frames covered by temporal window i.
    fn frames_of(&self, i: usize) -> std::ops::Range<usize> {
        let start = (i * self.layout.patch[0] / 2) as isize - self.layout.pad[0] as isize;
        let end = start + self.layout.patch[0] as isize;
        start.clamp(0, self.layout.shape[0] as isize) as usize..end.clamp(0, self.layout.shape[0] as isize) as usize
    }

    fn index(&self, cell: [usize; 3]) -> usize {
        (cell[0] * self.counts[1] + cell[1]) * self.counts[2] + cell[2]
    }

    /// Patches held in memory (received and not yet released).
    pub fn buffered(&self) -> usize {
        self.patches.iter().filter(|p| p.is_some()).count()
    }

    /// Add patches (N, Lt, Ls, Ls) at `origins` (padded (t, y, x), on the
    /// layout's grid, each at most once); solve every frame they complete.
    pub fn add(&mut self, patches: &[f32], origins: &[[usize; 3]]) -> Result<()> {
        let patch_len = self.layout.patch.iter().product::<usize>();
        if patches.len() != origins.len() * patch_len {
            return Err(InvalidArgument::new("patches", format!("expected {} patches of {:?}, got {} values", origins.len(), self.layout.patch, patches.len())));
        }
        if !patches.iter().all(|v| v.is_finite()) {
            return Err(InvalidArgument::new("patches", "expected finite values"));
        }
        let mut cells = Vec::with_capacity(origins.len());
        for o in origins {
            let hop = self.layout.patch.map(|l| l / 2);
            let cell: [usize; 3] = std::array::from_fn(|a| o[a] / hop[a]);
            if (0..3).any(|a| o[a] % hop[a] != 0 || cell[a] >= self.counts[a]) {
                return Err(InvalidArgument::new("origins", format!("expected origins of the layout's grid (multiples of {hop:?} within {:?}), got {o:?}", self.layout.padded)));
            }
            let index = self.index(cell);
            if self.received[index] || cells.contains(&cell) {
                return Err(InvalidArgument::new("origins", format!("patch at {o:?} given twice")));
            }
            cells.push(cell);
        }
        let mut ready = Vec::new();
        for (cell, patch) in cells.iter().zip(patches.chunks(patch_len)) {
            let index = self.index(*cell);
            self.received[index] = true;
            self.patches[index] = Some(patch.to_vec());
            for t in self.frames_of(cell[0]) {
                self.missing[t] -= 1;
                if self.missing[t] == 0 {
                    ready.push(t);
                }
            }
        }
        ready.sort_unstable();
        let this = &*self;
        let frames: Vec<Vec<f32>> = ready.par_iter().map(|&t| this.solve_frame(t)).collect();
        let len = self.layout.shape[1] * self.layout.shape[2];
        for (&t, frame) in ready.iter().zip(frames) {
            self.video[t * len..(t + 1) * len].copy_from_slice(&frame);
        }
        // Release patches whose frames are all solved.
        for i in 0..self.counts[0] {
            if self.frames_of(i).all(|t| self.missing[t] == 0) {
                for j in 0..self.counts[1] * self.counts[2] {
                    self.patches[i * self.counts[1] * self.counts[2] + j] = None;
                }
            }
        }
        Ok(())
    }

    /// The stitched video (T, H, W); every patch of the layout must have been added.
    pub fn finish(self) -> Result<Vec<f32>> {
        let absent = self.received.iter().filter(|&&r| !r).count();
        if absent > 0 {
            return Err(InvalidArgument::new("patches", format!("{absent} of the layout's {} patches were never added", self.received.len())));
        }
        Ok(self.video)
    }

    /// The patch-frames covering frame t (all received).
    fn patch_frames(&self, t: usize) -> Vec<PatchFrame<'_>> {
        let [_, hh, ww] = self.layout.shape;
        let [lt, ly, lx] = self.layout.patch;
        let pad = self.layout.pad;
        let mut out = Vec::new();
        for i in self.windows_of(t) {
            let f = t + pad[0] - i * lt / 2;
            for j in 0..self.counts[1] {
                for k in 0..self.counts[2] {
                    let patch = self.patches[self.index([i, j, k])].as_deref().expect("a frame is solved once all its patches arrived");
                    let values = &patch[f * ly * lx..(f + 1) * ly * lx];
                    let corner = [(j * ly / 2) as isize - pad[1] as isize, (k * lx / 2) as isize - pad[2] as isize];
                    let span = |c: isize, l: usize, n: usize| (c.clamp(0, n as isize) as usize, (c + l as isize).clamp(0, n as isize) as usize);
                    let (rows, cols) = (span(corner[0], ly, hh), span(corner[1], lx, ww));
                    let inside = (rows.0..rows.1).flat_map(|y| (cols.0..cols.1).map(move |x| (y, x)));
                    let at = |(y, x): (usize, usize)| values[(y as isize - corner[0]) as usize * lx + (x as isize - corner[1]) as usize] as f64;
                    let n = ((rows.1 - rows.0) * (cols.1 - cols.0)) as f64;
                    let sum: f64 = inside.clone().map(at).sum();
                    let sum2: f64 = inside.map(|c| at(c).powi(2)).sum();
                    let mean = sum / n;
                    let var = (sum2 / n - mean * mean).max(0.0);
                    // A patch-frame flat to f32 rounding has no relief to align: p̂ = 0.
                    let inv_std = if var.sqrt() > 1e-6 * mean.abs() && var > 0.0 { 1.0 / var.sqrt() } else { 0.0 };
                    out.push(PatchFrame { values, weight_t: self.windows[0][f] as f64, corner, rows, cols, cell: [j, k], mean, inv_std });
                }
            }
        }
        out
    }

    /// a_k at video pixel (y, x) of patch-frame `p`, and its weight w_k.
    #[inline]
    fn design(&self, p: &PatchFrame<'_>, y: usize, x: usize) -> (Vector4<f64>, f64) {
        let [_, ly, lx] = self.layout.patch;
        let (py, px) = ((y as isize - p.corner[0]) as usize, (x as isize - p.corner[1]) as usize);
        let value = (p.values[py * lx + px] as f64 - p.mean) * p.inv_std;
        let a = Vector4::new((px as f64 + 0.5) / lx as f64 - 0.5, (py as f64 + 0.5) / ly as f64 - 0.5, value, 1.0);
        (a, p.weight_t * self.windows[1][py] as f64 * self.windows[2][px] as f64)
    }

    /// Solve frame t: its stitched depth (H·W values).
    fn solve_frame(&self, t: usize) -> Vec<f32> {
        let [_, hh, ww] = self.layout.shape;
        let mu = self.coarse_weight;
        let frames = self.patch_frames(t);
        // Blocks of G by row: (column, block), the diagonal first.
        let mut blocks: Vec<Vec<(usize, Matrix4<f64>)>> = Vec::with_capacity(frames.len());
        let mut rhs = Vec::with_capacity(frames.len());
        let coarse = &self.coarse[t * hh * ww..(t + 1) * hh * ww];
        for p in &frames {
            let (mut diag, mut b) = (Matrix4::zeros(), Vector4::zeros());
            for y in p.rows.0..p.rows.1 {
                for x in p.cols.0..p.cols.1 {
                    let (a, w) = self.design(p, y, x);
                    diag += (w - w * w + mu) * a * a.transpose();
                    b += mu * coarse[y * ww + x] as f64 * a;
                }
            }
            diag += Matrix4::identity() * 1e-9 * (1.0 + diag.trace() / 4.0);
            blocks.push(vec![(blocks.len(), diag)]);
            rhs.push(b);
        }
        // Patch-frames come window by window, each window's row-major over the
        // grid, so a neighbour's index follows from its window and cell.
        let [cy, cx] = [self.counts[1], self.counts[2]];
        let neighbours = |k: usize| {
            let [j, i] = frames[k].cell;
            (0..frames.len() / (cy * cx)).flat_map(move |w| {
                (j.saturating_sub(1)..(j + 2).min(cy)).flat_map(move |y| (i.saturating_sub(1)..(i + 2).min(cx)).map(move |x| (w * cy + y) * cx + x))
            })
        };
        for k in 0..frames.len() {
            for l in neighbours(k).filter(|&l| l > k) {
                let (p, q) = (&frames[k], &frames[l]);
                let rows = (p.rows.0.max(q.rows.0), p.rows.1.min(q.rows.1));
                let cols = (p.cols.0.max(q.cols.0), p.cols.1.min(q.cols.1));
                if rows.0 >= rows.1 || cols.0 >= cols.1 {
                    continue;
                }
                let mut off = Matrix4::zeros();
                for y in rows.0..rows.1 {
                    for x in cols.0..cols.1 {
                        let ((a, wa), (c, wc)) = (self.design(p, y, x), self.design(q, y, x));
                        off -= wa * wc * a * c.transpose();
                    }
                }
                blocks[k].push((l, off));
                blocks[l].push((k, off.transpose()));
            }
        }
        let g = conjugate_gradients(&blocks, &rhs);
        let mut out = vec![0.0f64; hh * ww];
        for (p, gk) in frames.iter().zip(&g) {
            for y in p.rows.0..p.rows.1 {
                for x in p.cols.0..p.cols.1 {
                    let (a, w) = self.design(p, y, x);
                    out[y * ww + x] += w * a.dot(gk);
                }
            }
        }
        out.into_iter().map(|v| v as f32).collect()
    }
}

/// Solve the block-sparse SPD system `G x = b` (rows of (column, 4×4 block),
/// the diagonal block first) by conjugate gradients preconditioned with the
/// inverse diagonal blocks, to a residual of 1e-10 of ‖b‖ or 2000 iterations
/// (a few hundred at μ = 1e-3; the count grows about as 1/√μ).
fn conjugate_gradients(blocks: &[Vec<(usize, Matrix4<f64>)>], b: &[Vector4<f64>]) -> Vec<Vector4<f64>> {
    let n = b.len();
    let precondition: Vec<Matrix4<f64>> = blocks.iter().map(|row| row[0].1.try_inverse().unwrap_or_else(Matrix4::zeros)).collect();
    let apply = |x: &[Vector4<f64>], out: &mut [Vector4<f64>]| {
        for (o, row) in out.iter_mut().zip(blocks) {
            *o = row.iter().map(|(l, m)| m * x[*l]).sum();
        }
    };
    let dot = |a: &[Vector4<f64>], c: &[Vector4<f64>]| a.iter().zip(c).map(|(u, v)| u.dot(v)).sum::<f64>();
    let mut x = vec![Vector4::zeros(); n];
    let mut r = b.to_vec();
    let mut z: Vec<Vector4<f64>> = r.iter().zip(&precondition).map(|(v, m)| m * v).collect();
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let tolerance = 1e-20 * dot(b, b);
    let mut gp = vec![Vector4::zeros(); n];
    for _ in 0..2000 {
        if dot(&r, &r) <= tolerance {
            break;
        }
        apply(&p, &mut gp);
        let curvature = dot(&p, &gp);
        if curvature.is_nan() || curvature <= 0.0 {
            break;
        }
        let step = rz / curvature;
        for i in 0..n {
            x[i] += step * p[i];
            r[i] -= step * gp[i];
            z[i] = precondition[i] * r[i];
        }
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stitch::coarse_at;
    use nalgebra::{DMatrix, DVector};

    fn pseudo(i: usize) -> f32 {
        let x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
        x as f32 / (1u64 << 24) as f32 - 0.5
    }

    /// A smooth depth video and its patches (over the video padded by
    /// mirroring), each frame of each patch seen through its own
    /// pseudo-random GBR (sign flips included).
    fn scene(shape: [usize; 3], patch: [usize; 3]) -> (Layout, Vec<f32>, Vec<f32>, Vec<[usize; 3]>) {
        let layout = Layout::new(shape, patch).unwrap();
        let [tt, hh, ww] = shape;
        let depth = |t: isize, y: isize, x: isize| {
            let (t, y, x) = (t as f32, y as f32, x as f32);
            (0.9 * x + 0.3 * t).sin() * (0.7 * y).cos() + (0.25 * x - 0.15 * y).sin() + 0.2 * x * y / (hh * ww) as f32 + 0.1 * (0.5 * t).cos()
        };
        let truth: Vec<f32> = (0..tt * hh * ww).map(|i| depth((i / (hh * ww)) as isize, (i / ww % hh) as isize, (i % ww) as isize)).collect();
        let origins = layout.origins();
        let [lt, ly, lx] = patch;
        let mut patches = Vec::new();
        for (n, o) in origins.iter().enumerate() {
            for f in 0..lt {
                let g = [pseudo(4 * (n * lt + f)), pseudo(4 * (n * lt + f) + 1), 1.0 + pseudo(4 * (n * lt + f) + 2), 3.0 * pseudo(4 * (n * lt + f) + 3)];
                let g = if (n + f) % 3 == 0 { [g[0], g[1], -g[2], g[3]] } else { g };
                for y in 0..ly {
                    for x in 0..lx {
                        let (t, gy, gx) = (o[0] as isize + f as isize - layout.pad[0] as isize, o[1] as isize + y as isize - layout.pad[1] as isize, o[2] as isize + x as isize - layout.pad[2] as isize);
                        // The padding mirrors the video, as `reconstruct` pads it.
                        let v = coarse_at(&truth, &layout, t, gy, gx);
                        patches.push(g[0] * x as f32 + g[1] * y as f32 + g[2] * v + g[3]);
                    }
                }
            }
        }
        (layout, truth, patches, origins)
    }

    const WINDOWS: [Window; 2] = [Window::Triangle, Window::Hann];

    fn joint(layout: &Layout, coarse: &[f32], mu: f64, window: Window, patches: &[f32], origins: &[[usize; 3]]) -> Vec<f32> {
        let mut s = JointStitcher::new(*layout, coarse.to_vec(), mu, window).unwrap();
        s.add(patches, origins).unwrap();
        s.finish().unwrap()
    }

    /// Patches that each see the truth through their own GBR come back as the
    /// truth when the coarse depth is any GBR of it (here the truth): nothing
    /// disagrees and nothing departs from the coarse depth.
    #[test]
    fn consistent_patches_give_back_the_truth() {
        for (shape, patch) in [([9, 20, 27], [4, 8, 8]), ([5, 16, 16], [4, 8, 8])] {
            let (layout, truth, patches, origins) = scene(shape, patch);
            for (mu, window) in [1e-3, 1.0, 1e3].into_iter().flat_map(|mu| WINDOWS.map(|w| (mu, w))) {
                let out = joint(&layout, &truth, mu, window, &patches, &origins);
                let err = out.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
                assert!(err < 2e-3, "{shape:?} μ={mu} {window:?}: {err}");
            }
        }
    }

    /// With a coarse depth that is only a blurred, tilted guess, the joint
    /// alignment at a small weight μ still recovers the relief from the
    /// patches' agreement: far closer to the truth (after one GBR per frame)
    /// than the coarse depth.
    #[test]
    fn agreement_recovers_what_the_coarse_depth_lacks() {
        let (layout, truth, patches, origins) = scene([8, 24, 24], [4, 8, 8]);
        let [tt, hh, ww] = layout.shape;
        let coarse: Vec<f32> = (0..tt * hh * ww)
            .map(|i| {
                let (t, y, x) = (i / (hh * ww), i / ww % hh, i % ww);
                let blur = |dy: isize, dx: isize| truth[(t * hh + (y as isize + dy).clamp(0, hh as isize - 1) as usize) * ww + (x as isize + dx).clamp(0, ww as isize - 1) as usize];
                let mean = (-3..=3).flat_map(|dy| (-3..=3).map(move |dx| (dy, dx))).map(|(dy, dx)| blur(dy, dx)).sum::<f32>() / 49.0;
                0.3 * mean + 0.05 * x as f32
            })
            .collect();
        let frame_error = |d: &[f32]| -> f64 {
            // Residual of the best per-frame GBR onto the truth, relative to the truth's spread.
            (0..tt)
                .map(|t| {
                    let (p, g) = (&d[t * hh * ww..(t + 1) * hh * ww], &truth[t * hh * ww..(t + 1) * hh * ww]);
                    let a = DMatrix::from_fn(hh * ww, 4, |i, c| [(i % ww) as f64, (i / ww) as f64, p[i] as f64, 1.0][c]);
                    let y = DVector::from_iterator(hh * ww, g.iter().map(|&v| v as f64));
                    let fit = a.clone().svd(true, true).solve(&y, 1e-12).unwrap();
                    let mean = y.mean();
                    ((a * fit - &y).norm_squared() / y.iter().map(|v| (v - mean).powi(2)).sum::<f64>()).sqrt()
                })
                .sum::<f64>()
                / tt as f64
        };
        for window in WINDOWS {
            let out = joint(&layout, &coarse, 1e-5, window, &patches, &origins);
            let (joint_err, coarse_err) = (frame_error(&out), frame_error(&coarse));
            assert!(joint_err < 0.1 * coarse_err, "{window:?}: joint {joint_err}, coarse {coarse_err}");
        }
    }

    /// The solution is the minimiser of E(g) (module header), checked against
    /// a dense least-squares solve of the same objective on a small video.
    #[test]
    fn matches_a_dense_least_squares_solve() {
        for window in WINDOWS {
            matches_a_dense_least_squares_solve_with(window);
        }
    }

    fn matches_a_dense_least_squares_solve_with(window: Window) {
        let (layout, truth, patches, origins) = scene([3, 12, 10], [4, 8, 8]);
        let [_, hh, ww] = layout.shape;
        let coarse: Vec<f32> = truth.iter().enumerate().map(|(i, v)| 0.5 * v + pseudo(i + 99) * 0.3).collect();
        let mu = 0.05;
        let out = joint(&layout, &coarse, mu, window, &patches, &origins);
        let plen = 4 * 8 * 8;
        let stitcher = {
            let mut s = JointStitcher::new(layout, coarse.clone(), mu, window).unwrap();
            for (i, o) in origins.iter().enumerate() {
                let cell: [usize; 3] = std::array::from_fn(|a| o[a] / (layout.patch[a] / 2));
                let index = s.index(cell);
                s.patches[index] = Some(patches[i * plen..(i + 1) * plen].to_vec());
            }
            s
        };
        for t in 0..layout.shape[0] {
            let frames = stitcher.patch_frames(t);
            let k = frames.len();
            // Rows: √w_k (a_kᵀg_k − S) per pixel and patch-frame, then √μ (a_kᵀg_k − C).
            let mut rows: Vec<(DVector<f64>, f64)> = Vec::new();
            for y in 0..hh {
                for x in 0..ww {
                    let cover: Vec<(usize, Vector4<f64>, f64)> = frames
                        .iter()
                        .enumerate()
                        .filter(|(_, p)| (p.rows.0..p.rows.1).contains(&y) && (p.cols.0..p.cols.1).contains(&x))
                        .map(|(i, p)| {
                            let (a, w) = stitcher.design(p, y, x);
                            (i, a, w)
                        })
                        .collect();
                    for &(i, ref a, w) in &cover {
                        let mut row = DVector::zeros(4 * k);
                        for &(j, ref c, wj) in &cover {
                            for d in 0..4 {
                                row[4 * j + d] -= w.sqrt() * wj * c[d];
                            }
                        }
                        for d in 0..4 {
                            row[4 * i + d] += w.sqrt() * a[d];
                        }
                        rows.push((row, 0.0));
                        let mut anchor = DVector::zeros(4 * k);
                        for d in 0..4 {
                            anchor[4 * i + d] = mu.sqrt() * a[d];
                        }
                        rows.push((anchor, mu.sqrt() * coarse[(t * hh + y) * ww + x] as f64));
                    }
                }
            }
            let a = DMatrix::from_fn(rows.len(), 4 * k, |r, c| rows[r].0[c]);
            let b = DVector::from_iterator(rows.len(), rows.iter().map(|r| r.1));
            let g = a.svd(true, true).solve(&b, 1e-14).unwrap();
            for y in 0..hh {
                for x in 0..ww {
                    let s: f64 = frames
                        .iter()
                        .enumerate()
                        .filter(|(_, p)| (p.rows.0..p.rows.1).contains(&y) && (p.cols.0..p.cols.1).contains(&x))
                        .map(|(i, p)| {
                            let (a, w) = stitcher.design(p, y, x);
                            w * a.dot(&g.fixed_rows::<4>(4 * i).into_owned())
                        })
                        .sum();
                    let got = out[(t * hh + y) * ww + x] as f64;
                    assert!((got - s).abs() < 1e-4 * (1.0 + s.abs()), "{window:?} t={t} y={y} x={x}: {got} vs {s}");
                }
            }
        }
    }

    /// A large μ fits each patch on its own to the coarse depth over its
    /// pixels in the video: inside the video's interior, where patches have
    /// no padding, that is the paper's alignment (`stitch::stitch`).
    #[test]
    fn a_large_coarse_weight_fits_each_patch_on_its_own() {
        let (layout, truth, patches, origins) = scene([9, 24, 32], [4, 8, 8]);
        let coarse: Vec<f32> = truth.iter().enumerate().map(|(i, v)| 0.5 * v + pseudo(i + 7)).collect();
        let [tt, hh, ww] = layout.shape;
        for window in WINDOWS {
            let paper = crate::stitch::stitch(&patches, &origins, &coarse, &layout, window).unwrap();
            let out = joint(&layout, &coarse, 1e9, window, &patches, &origins);
            for t in 0..tt {
                for y in 8..hh - 8 {
                    for x in 8..ww - 8 {
                        let i = (t * hh + y) * ww + x;
                        assert!((out[i] - paper[i]).abs() < 1e-4, "{window:?} t={t} y={y} x={x}: {} vs {}", out[i], paper[i]);
                    }
                }
            }
        }
    }

    #[test]
    fn order_chunking_and_threads_give_the_same_bytes_and_patches_are_released() {
        let (layout, truth, patches, origins) = scene([20, 16, 24], [4, 8, 8]);
        let whole = joint(&layout, &truth, 0.01, Window::Hann, &patches, &origins);
        let plen = 4 * 8 * 8;
        let mut stitcher = JointStitcher::new(layout, truth.clone(), 0.01, Window::Hann).unwrap();
        let mut most = 0;
        for (chunk, o) in patches.chunks(5 * plen).zip(origins.chunks(5)) {
            stitcher.add(chunk, o).unwrap();
            most = most.max(stitcher.buffered());
        }
        assert!(most < origins.len() / 2, "time-major input holds {most} of {} patches", origins.len());
        assert_eq!(stitcher.finish().unwrap(), whole);
        // One thread.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(pool.install(|| joint(&layout, &truth, 0.01, Window::Hann, &patches, &origins)), whole);
        // Reversed order, one patch at a time.
        let mut stitcher = JointStitcher::new(layout, truth, 0.01, Window::Hann).unwrap();
        for i in (0..origins.len()).rev() {
            stitcher.add(&patches[i * plen..(i + 1) * plen], &origins[i..i + 1]).unwrap();
        }
        assert_eq!(stitcher.finish().unwrap(), whole);
    }

    #[test]
    fn bad_input_is_named() {
        let (layout, truth, patches, origins) = scene([5, 16, 16], [4, 8, 8]);
        let plen = 4 * 8 * 8;
        let err = |r: Result<()>| r.unwrap_err().name;
        assert_eq!(JointStitcher::new(layout, truth.clone(), 0.0, Window::Hann).err().unwrap().name, "coarse_weight");
        assert_eq!(JointStitcher::new(layout, truth.clone(), f64::NAN, Window::Hann).err().unwrap().name, "coarse_weight");
        assert_eq!(JointStitcher::new(layout, truth[1..].to_vec(), 1.0, Window::Hann).err().unwrap().name, "coarse");
        let mut s = JointStitcher::new(layout, truth.clone(), 1.0, Window::Hann).unwrap();
        assert_eq!(err(s.add(&patches[..plen], &[[1, 0, 0]])), "origins");
        assert_eq!(err(s.add(&patches[..2 * plen], &[origins[0], origins[0]])), "origins");
        assert_eq!(err(s.add(&patches[..plen - 1], &origins[..1])), "patches");
        let mut nan = patches[..plen].to_vec();
        nan[3] = f32::NAN;
        assert_eq!(err(s.add(&nan, &origins[..1])), "patches");
        s.add(&patches[..plen], &origins[..1]).unwrap();
        assert_eq!(err(s.add(&patches[..plen], &origins[..1])), "origins");
        assert_eq!(s.finish().unwrap_err().name, "patches");
    }
}
