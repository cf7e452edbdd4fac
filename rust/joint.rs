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
//! fitting the mirrored coarse depth scored worse on real video (docs/findings.md).
//! Normal equations: `G g = μ b` with `G_kk = Σ_Ωk (w_k − w_k² + μ) a_k a_kᵀ`,
//! `G_kl = −Σ_{Ωk∩Ωl} w_k w_l a_k a_lᵀ`, `b_k = Σ_Ωk a_k C`: block sparse, a
//! patch-frame meeting at most 17 others
//! (its 3 × 3 spatial neighbourhood in the frame's two temporal windows),
//! solved in f64 by conjugate gradients preconditioned with the 4 × 4
//! diagonal blocks (tied: below; a ridge of 1e-9 of a block's mean diagonal
//! keeps a flat patch's GBR finite), starting from each patch's GBR in the
//! frame before.
//!
//! A temporal tie (weight ν ≥ 0; ν = 0 leaves frames independent) keeps each
//! patch's reading steady where its own depth barely changes: the frames are
//! solved together with
//!
//! ```text
//! Σ_t Σ_k ν_k ‖g_k − g_k'‖²,   ν_k = ν |Ω_k| exp(−(1 − ρ_k) / 0.02),
//! ```
//!
//! k' the same patch at frame t − 1 and ρ_k the correlation of its
//! standardised frames t − 1 and t over Ω_k. A patch is read by a network
//! that sees all its frames, so its frames are nearly one reading; where
//! they are (ρ → 1) the tie stops each frame's fit from following the noise
//! of that frame's coarse depth and neighbours, and where the patch moves or
//! deforms (1 − ρ ≫ 0.02) it lets go. To stream, frames are solved in
//! temporal blocks of the hop (the frames that windows b − 1 and b cover,
//! complete together), block b with block b + 1 (`LOOKAHEAD`), then block b
//! kept; the ties of block b's first frame to the frame before pull toward
//! its solved GBRs. A tie in only one direction (frame by frame) lags the
//! surface and scored worse than none; solving ahead keeps the symmetric
//! tie's gain (docs/stitching.md). Ties add `ν_k I` to both diagonal blocks, `−ν_k I`
//! between them, and `ν_k ĝ_k` to `b_k` toward a solved GBR ĝ_k. Block b + 1's
//! equations are assembled once: the next span reuses them (only the anchor
//! is new) and starts from their solution. The ties couple a patch's frames
//! strongly, which slows block-Jacobi conjugate gradients about fivefold, so
//! the preconditioner solves each patch's chain of tied frames exactly
//! (block tridiagonal); untied it is block Jacobi.
//!
//! Pixels off the surface, marked NaN in the coarse depth (a mask the
//! caller gives), are left out of every sum: Ω_k holds only pixels on the
//! surface, so they count in neither term nor in the standardisation of
//! p̂_k, ρ_k is taken over the pixels on the surface in both frames, and the
//! stitched depth is NaN there. A patch-frame wholly off the surface keeps
//! only the ridge. Without NaN every pixel counts, with no test per pixel.
//!
//! Patches arrive in chunks in any order; frames are solved, in time order,
//! as soon as every patch covering them has arrived (the work of a frame or
//! block runs in parallel), and a patch is dropped once all its frames are
//! solved, so time-major input keeps two temporal windows of patches in
//! memory (three while tied). The coarse depth may come a few frames at a
//! time (`push_coarse`: a span is solved once its coarse depth is there too)
//! and the stitched frames be taken as they are solved (`take`, which
//! releases them and their coarse depth), so a video streams through in
//! memory that does not grow with its length. The bytes depend only on the
//! patches and the coarse depth, not on their order, chunking, the thread
//! count or streaming. Shapes as in `stitch`:
//! patches (N, Lt, Ls, Ls) at padded origins (t, y, x) on the layout's grid,
//! coarse and output (T, H, W), row-major f32.

use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

use crate::error::{InvalidArgument, Result};
use crate::stitch::{Layout, Window};

/// The tie's scale of 1 − ρ (module header): consecutive frames of a patch the
/// network reads as one shape correlate above 0.98.
const TIE_SCALE: f64 = 0.02;

/// Tied, blocks solved with a block's frames: this many blocks after it.
const LOOKAHEAD: usize = 1;

const OFF_SURFACE: &str = "expected finite values, or NaN off the surface";

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
    /// The patch's index in the grid (`JointStitcher::index`).
    index: usize,
    /// ν_k of its tie to the same patch in the frame before (0: none).
    tie: f64,
    /// Standardisation of the values.
    mean: f64,
    inv_std: f64,
}

/// Streaming joint stitcher: `add` patches in any grouping and order, then `finish`.
pub struct JointStitcher {
    layout: Layout,
    /// The coarse depth of frames `coarse_start ..` (as many as were given).
    coarse: Vec<f32>,
    coarse_start: usize,
    coarse_weight: f64,
    temporal_weight: f64,
    /// The stitched frames `video_start .. next`, not yet taken.
    video: Vec<f32>,
    video_start: usize,
    windows: [Vec<f32>; 3],
    /// Patches per axis of the grid.
    counts: [usize; 3],
    /// Received patches not yet released, by grid index.
    patches: Vec<Option<Vec<f32>>>,
    received: Vec<bool>,
    /// Per frame: covering patches still to arrive.
    missing: Vec<usize>,
    /// Frames before this one are solved.
    next: usize,
    /// Each held patch's GBR at the last solved frame it covers, by grid index.
    gbrs: Vec<Option<Vector4<f64>>>,
    /// Tied: the frames the last span solved ahead of what it kept, with their
    /// normal equations (without the anchor) and solution, for the next span.
    ahead: Vec<Ahead>,
}

impl JointStitcher {
    /// `coarse`: the coarse depth (T, H, W), or its first frames, the rest
    /// to come by `push_coarse`; `coarse_weight`: μ > 0; `temporal_weight`:
    /// ν ≥ 0 (module header).
    pub fn new(layout: Layout, coarse: Vec<f32>, coarse_weight: f64, temporal_weight: f64, window: Window) -> Result<Self> {
        let frame = layout.shape[1] * layout.shape[2];
        if coarse.len() % frame != 0 || coarse.len() > layout.shape.iter().product::<usize>() {
            return Err(InvalidArgument::new("coarse", format!("expected at most {} frames of {:?}, got {} values", layout.shape[0], &layout.shape[1..], coarse.len())));
        }
        if coarse.iter().any(|v| v.is_infinite()) {
            return Err(InvalidArgument::new("coarse", OFF_SURFACE));
        }
        if !(coarse_weight.is_finite() && coarse_weight > 0.0) {
            return Err(InvalidArgument::new("coarse_weight", format!("expected a finite number > 0, got {coarse_weight}")));
        }
        if !(temporal_weight.is_finite() && temporal_weight >= 0.0) {
            return Err(InvalidArgument::new("temporal_weight", format!("expected a finite number ≥ 0, got {temporal_weight}")));
        }
        let counts: [usize; 3] = std::array::from_fn(|a| (layout.padded[a] - layout.patch[a]) / (layout.patch[a] / 2) + 1);
        let mut stitcher = Self {
            video: Vec::new(),
            video_start: 0,
            coarse,
            coarse_start: 0,
            coarse_weight,
            temporal_weight,
            windows: layout.patch.map(|l| window.weights(l)),
            patches: vec![None; counts.iter().product()],
            received: vec![false; counts.iter().product()],
            missing: vec![0; layout.shape[0]],
            next: 0,
            gbrs: vec![None; counts.iter().product()],
            ahead: Vec::new(),
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

    /// The temporal block of video frame t: the frames that windows b − 1 and b cover.
    fn block_of(&self, t: usize) -> usize {
        (t + self.layout.pad[0]) / (self.layout.patch[0] / 2)
    }

    /// The end of temporal block b (exclusive, at most the video's length).
    fn block_end(&self, b: usize) -> usize {
        ((b + 1) * (self.layout.patch[0] / 2)).saturating_sub(self.layout.pad[0]).min(self.layout.shape[0])
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
    /// layout's grid, each at most once); solve, in time order, every frame
    /// they complete.
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
        for (cell, patch) in cells.iter().zip(patches.chunks(patch_len)) {
            let index = self.index(*cell);
            self.received[index] = true;
            self.patches[index] = Some(patch.to_vec());
            for t in self.frames_of(cell[0]) {
                self.missing[t] -= 1;
            }
        }
        self.advance();
        Ok(())
    }

    /// Append the coarse depth of the next frames (whole frames, (n, H, W));
    /// solve, in time order, every frame this completes.
    pub fn push_coarse(&mut self, frames: &[f32]) -> Result<()> {
        let frame = self.layout.shape[1] * self.layout.shape[2];
        let have = self.coarse_start + self.coarse.len() / frame;
        if frames.len() % frame != 0 || have + frames.len() / frame > self.layout.shape[0] {
            return Err(InvalidArgument::new("coarse", format!("expected whole frames of {:?}, at most {} more, got {} values", &self.layout.shape[1..], self.layout.shape[0] - have, frames.len())));
        }
        if frames.iter().any(|v| v.is_infinite()) {
            return Err(InvalidArgument::new("coarse", OFF_SURFACE));
        }
        self.coarse.extend_from_slice(frames);
        self.advance();
        Ok(())
    }

    /// The frames stitched since the last `take` (n, H, W), in time order;
    /// they, and the coarse depth of every solved frame, are released.
    pub fn take(&mut self) -> Vec<f32> {
        let frame = self.layout.shape[1] * self.layout.shape[2];
        // The frame before the next stays: the tie reads which of its pixels are on the surface.
        let kept = self.next.saturating_sub(1).max(self.coarse_start);
        self.coarse.drain(..(kept - self.coarse_start) * frame);
        self.coarse_start = kept;
        self.video_start = self.next;
        std::mem::take(&mut self.video)
    }

    /// Solve every span whose patches and coarse depth have all arrived, in
    /// time order, then release the patches whose frames are all solved.
    fn advance(&mut self) {
        let frame = self.layout.shape[1] * self.layout.shape[2];
        let coarse_end = self.coarse_start + self.coarse.len() / frame;
        while self.next < self.layout.shape[0] {
            // Untied, a frame is solved on its own; tied, a block with the
            // blocks after it (module header).
            let (keep, end) = if self.temporal_weight == 0.0 {
                (self.next + 1, self.next + 1)
            } else {
                let block = self.block_of(self.next);
                (self.block_end(block), self.block_end(block + LOOKAHEAD))
            };
            if end > coarse_end || (self.next..end).any(|t| self.missing[t] > 0) {
                break;
            }
            self.solve_span(self.next..end, keep);
            self.next = keep;
        }
        // Release patches whose frames are all solved.
        let per_window = self.counts[1] * self.counts[2];
        for i in 0..self.counts[0] {
            if self.frames_of(i).all(|t| t < self.next) {
                for slot in i * per_window..(i + 1) * per_window {
                    self.patches[slot] = None;
                    self.gbrs[slot] = None;
                }
            }
        }
    }

    /// The stitched frames not yet taken (all of them, (T, H, W), without
    /// `take`); every patch of the layout and every frame's coarse depth must
    /// have been added.
    pub fn finish(mut self) -> Result<Vec<f32>> {
        let absent = self.received.iter().filter(|&&r| !r).count();
        if absent > 0 {
            return Err(InvalidArgument::new("patches", format!("{absent} of the layout's {} patches were never added", self.received.len())));
        }
        let frame = self.layout.shape[1] * self.layout.shape[2];
        let given = self.coarse_start + self.coarse.len() / frame;
        if given < self.layout.shape[0] {
            return Err(InvalidArgument::new("coarse", format!("{} of the video's {} frames were never given", self.layout.shape[0] - given, self.layout.shape[0])));
        }
        Ok(std::mem::take(&mut self.video))
    }

    /// Frame t's coarse depth (given, not yet released); NaN off the surface.
    fn coarse_frame(&self, t: usize) -> &[f32] {
        let len = self.layout.shape[1] * self.layout.shape[2];
        &self.coarse[(t - self.coarse_start) * len..(t - self.coarse_start + 1) * len]
    }

    /// The patch-frames covering frame t (all received). Pixels off the
    /// surface (NaN in the coarse depth) take part in nothing.
    fn patch_frames(&self, t: usize) -> Vec<PatchFrame<'_>> {
        let [_, hh, ww] = self.layout.shape;
        let [lt, ly, lx] = self.layout.patch;
        let pad = self.layout.pad;
        let coarse = self.coarse_frame(t);
        let tie_frames = self.temporal_weight > 0.0 && t > 0;
        let before_coarse = if tie_frames { self.coarse_frame(t - 1) } else { coarse };
        // Without pixels off the surface every pixel counts: no test per pixel.
        let masked = coarse.iter().any(|v| v.is_nan());
        let masked_before = tie_frames && before_coarse.iter().any(|v| v.is_nan());
        let cells: Vec<[usize; 3]> = self
            .windows_of(t)
            .flat_map(|i| (0..self.counts[1]).flat_map(move |j| (0..self.counts[2]).map(move |k| [i, j, k])))
            .collect();
        cells
            .par_iter()
            .map(|&[i, j, k]| {
                let f = t + pad[0] - i * lt / 2;
                let index = self.index([i, j, k]);
                let patch = self.patches[index].as_deref().expect("a frame is solved once all its patches arrived");
                let corner = [(j * ly / 2) as isize - pad[1] as isize, (k * lx / 2) as isize - pad[2] as isize];
                let span = |c: isize, l: usize, n: usize| (c.clamp(0, n as isize) as usize, (c + l as isize).clamp(0, n as isize) as usize);
                let (rows, cols) = (span(corner[0], ly, hh), span(corner[1], lx, ww));
                // Its pixels in the video and on the surface (`both`: in frame t − 1 too), as indices into the patch's frame.
                let pixels = |both: bool| Pixels {
                    rows,
                    cols,
                    corner,
                    lx,
                    ww,
                    coarse: masked.then_some(coarse),
                    before: (both && masked_before).then_some(before_coarse),
                };
                let count = |both: bool| if masked || both && masked_before { pixels(both).count() } else { (rows.1 - rows.0) * (cols.1 - cols.0) } as f64;
                // Mean and inverse standard deviation of a frame of the patch over its `n` pixels `pixels(both)`.
                let standardise = |values: &[f32], both: bool, n: f64| {
                    let (sum, sum2) = pixels(both).moments(values);
                    let mean = sum / n;
                    let var = (sum2 / n - mean * mean).max(0.0);
                    // A patch-frame flat to f32 rounding has no relief to align: p̂ = 0.
                    (mean, if var.sqrt() > 1e-6 * mean.abs() && var > 0.0 { 1.0 / var.sqrt() } else { 0.0 })
                };
                let frame = |f: usize| &patch[f * ly * lx..(f + 1) * ly * lx];
                let values = frame(f);
                let n = count(false);
                if n == 0.0 {
                    // Off the surface: no equations but the ridge, and no tie.
                    return PatchFrame { values, weight_t: self.windows[0][f] as f64, corner, rows, cols, cell: [j, k], index, tie: 0.0, mean: 0.0, inv_std: 0.0 };
                }
                let (mean, inv_std) = standardise(values, false, n);
                let m = if tie_frames && f > 0 { count(true) } else { 0.0 };
                let tie = if m > 0.0 {
                    // ρ over the pixels on the surface in both frames.
                    let before = frame(f - 1);
                    let (mean_t, inv_std_t) = if m == n { (mean, inv_std) } else { standardise(values, true, m) };
                    let (mean_b, inv_std_b) = standardise(before, true, m);
                    let rho = pixels(true).sum(|i| (values[i] as f64 - mean_t) * inv_std_t * (before[i] as f64 - mean_b) * inv_std_b) / m;
                    self.temporal_weight * m * (-(1.0 - rho) / TIE_SCALE).exp()
                } else {
                    0.0
                };
                PatchFrame { values, weight_t: self.windows[0][f] as f64, corner, rows, cols, cell: [j, k], index, tie, mean, inv_std }
            })
            .collect()
    }

    /// a_k at video pixel (y, x) of patch-frame `p`, and its weight w_k.
    #[inline]
    fn design(&self, p: &PatchFrame<'_>, y: usize, x: usize) -> (Vector4<f64>, f64) {
        let [_, ly, lx] = self.layout.patch;
        let (py, px) = ((y as isize - p.corner[0]) as usize, (x as isize - p.corner[1]) as usize);
        let value = (p.values[py * lx + px] as f64 - p.mean) * p.inv_std;
        let a = Vector4::new(coordinate(px, lx), coordinate(py, ly), value, 1.0);
        (a, p.weight_t * self.windows[1][py] as f64 * self.windows[2][px] as f64)
    }

    /// Frame t's part of the normal equations, its patch-frames `frames`
    /// (`patch_frames(t)`): blocks of G by row, (column, block) with the
    /// diagonal first, and the right-hand side, in the frame's own indices.
    /// Each tie adds ν_k I to its patch-frame's diagonal block; the pull toward
    /// a solved frame before (`b_k += ν_k ĝ_k`) is the span's (`solve_span`).
    fn assemble(&self, t: usize, frames: &[PatchFrame<'_>]) -> Normal {
        let [_, _, ww] = self.layout.shape;
        let [_, ly, lx] = self.layout.patch;
        let mu = self.coarse_weight;
        let coarse = self.coarse_frame(t);
        let masked = coarse.iter().any(|v| v.is_nan());
        let (wy, wx) = (&self.windows[1], &self.windows[2]);
        // u of each column of a patch, once, not a division for each pixel of each pair.
        let us: Vec<f64> = (0..lx).map(|px| coordinate(px, lx)).collect();
        let diagonal: Vec<(Matrix4<f64>, Vector4<f64>)> = frames
            .par_iter()
            .map(|p| {
                // Σ c a aᵀ (c = w − w² + μ) and Σ C a (C the coarse depth) with
                // a = (u, v, p̂, 1): v is the row's, so each row sums over x only
                // what varies along it.
                let [mut uu, mut uv, mut up, mut u1, mut vv, mut vp, mut v1, mut pp, mut p1, mut one] = [0.0; 10];
                let [mut bu, mut bv, mut bp, mut b1] = [0.0; 4];
                for y in p.rows.0..p.rows.1 {
                    let py = (y as isize - p.corner[0]) as usize;
                    let (v, weight_y) = (coordinate(py, ly), p.weight_t * wy[py] as f64);
                    let values = &p.values[py * lx..(py + 1) * lx];
                    let [mut c0, mut cu, mut cuu, mut cp, mut cup, mut cpp, mut d0, mut du, mut dp] = [0.0; 9];
                    for x in p.cols.0..p.cols.1 {
                        let px = (x as isize - p.corner[1]) as usize;
                        let (u, w) = (us[px], weight_y * wx[px] as f64);
                        let c = w - w * w + mu;
                        let value = (values[px] as f64 - p.mean) * p.inv_std;
                        let depth = coarse[y * ww + x] as f64;
                        if masked && depth.is_nan() {
                            continue;
                        }
                        c0 += c;
                        cu += c * u;
                        cuu += c * u * u;
                        cp += c * value;
                        cup += c * u * value;
                        cpp += c * value * value;
                        d0 += depth;
                        du += depth * u;
                        dp += depth * value;
                    }
                    (uu, uv, up, u1) = (uu + cuu, uv + v * cu, up + cup, u1 + cu);
                    (vv, vp, v1) = (vv + v * v * c0, vp + v * cp, v1 + v * c0);
                    (pp, p1, one) = (pp + cpp, p1 + cp, one + c0);
                    (bu, bv, bp, b1) = (bu + du, bv + v * d0, bp + dp, b1 + d0);
                }
                let mut diag = Matrix4::new(uu, uv, up, u1, uv, vv, vp, v1, up, vp, pp, p1, u1, v1, p1, one);
                diag += Matrix4::identity() * (1e-9 * (1.0 + diag.trace() / 4.0) + p.tie);
                (diag, mu * Vector4::new(bu, bv, bp, b1))
            })
            .collect();
        let mut blocks: Vec<Vec<(usize, Matrix4<f64>)>> = diagonal.iter().enumerate().map(|(k, d)| vec![(k, d.0)]).collect();
        let rhs: Vec<Vector4<f64>> = diagonal.iter().map(|d| d.1).collect();
        // Patch-frames come window by window, each window's row-major over the
        // grid, so a neighbour's index follows from its window and cell.
        let [cy, cx] = [self.counts[1], self.counts[2]];
        let neighbours = |k: usize| {
            let [j, i] = frames[k].cell;
            (0..frames.len() / (cy * cx)).flat_map(move |w| {
                (j.saturating_sub(1)..(j + 2).min(cy)).flat_map(move |y| (i.saturating_sub(1)..(i + 2).min(cx)).map(move |x| (w * cy + y) * cx + x))
            })
        };
        let coupling: Vec<Vec<(usize, Matrix4<f64>)>> = (0..frames.len())
            .into_par_iter()
            .map(|k| {
                let p = &frames[k];
                neighbours(k)
                    .filter(|&l| l > k)
                    .filter_map(|l| {
                        let q = &frames[l];
                        let rows = (p.rows.0.max(q.rows.0), p.rows.1.min(q.rows.1));
                        let cols = (p.cols.0.max(q.cols.0), p.cols.1.min(q.cols.1));
                        if rows.0 >= rows.1 || cols.0 >= cols.1 {
                            return None;
                        }
                        // −Σ w_k w_l a_k a_lᵀ: the weight is separable, w_t · ω(y) · ω(x),
                        // so the sums of the coordinates alone over a row are the
                        // same in every row, and each row sums over x only the
                        // terms with a depth.
                        // With pixels off the surface, each row sums its own.
                        let corner = |r: &PatchFrame<'_>, x: usize| (x as isize - r.corner[1]) as usize;
                        let on = |y: usize, x: usize| !masked || !coarse[y * ww + x].is_nan();
                        let coordinate_sums = |y: usize| {
                            let [mut x0, mut xu_k, mut xu_l, mut xuu] = [0.0; 4];
                            for x in (cols.0..cols.1).filter(|&x| on(y, x)) {
                                let (pk, pl) = (corner(p, x), corner(q, x));
                                let (uk, ul, o) = (us[pk], us[pl], (wx[pk] * wx[pl]) as f64);
                                (x0, xu_k, xu_l, xuu) = (x0 + o, xu_k + o * uk, xu_l + o * ul, xuu + o * uk * ul);
                            }
                            [x0, xu_k, xu_l, xuu]
                        };
                        let every_row = coordinate_sums(rows.0);
                        let mut e = [[0.0f64; 4]; 4];
                        for y in rows.0..rows.1 {
                            let [x0, xu_k, xu_l, xuu] = if masked { coordinate_sums(y) } else { every_row };
                            let (yk, yl) = ((y as isize - p.corner[0]) as usize, (y as isize - q.corner[0]) as usize);
                            let (vk, vl) = (coordinate(yk, ly), coordinate(yl, ly));
                            let weight_y = p.weight_t * q.weight_t * (wy[yk] * wy[yl]) as f64;
                            let (values_k, values_l) = (&p.values[yk * lx..(yk + 1) * lx], &q.values[yl * lx..(yl + 1) * lx]);
                            // Σ ω(x) times u_k p̂_l, p̂_l, p̂_k u_l, p̂_k, p̂_k p̂_l.
                            let [mut ukpl, mut pl0, mut pkul, mut pk0, mut pkpl] = [0.0; 5];
                            for x in cols.0..cols.1 {
                                if !on(y, x) {
                                    continue;
                                }
                                let (xk, xl) = (corner(p, x), corner(q, x));
                                let o = (wx[xk] * wx[xl]) as f64;
                                let value_k = (values_k[xk] as f64 - p.mean) * p.inv_std;
                                let value_l = (values_l[xl] as f64 - q.mean) * q.inv_std;
                                let (ok, ol) = (o * value_k, o * value_l);
                                ukpl += us[xk] * ol;
                                pl0 += ol;
                                pkul += us[xl] * ok;
                                pk0 += ok;
                                pkpl += ok * value_l;
                            }
                            let row = [
                                [xuu, vl * xu_k, ukpl, xu_k],
                                [vk * xu_l, vk * vl * x0, vk * pl0, vk * x0],
                                [pkul, vl * pk0, pkpl, pk0],
                                [xu_l, vl * x0, pl0, x0],
                            ];
                            for (e, row) in e.iter_mut().zip(row) {
                                for (e, r) in e.iter_mut().zip(row) {
                                    *e += weight_y * r;
                                }
                            }
                        }
                        Some((l, -Matrix4::from_fn(|i, j| e[i][j])))
                    })
                    .collect()
            })
            .collect();
        for (k, row) in coupling.into_iter().enumerate() {
            for (l, off) in row {
                blocks[k].push((l, off));
                blocks[l].push((k, off.transpose()));
            }
        }
        Normal { blocks, rhs }
    }

    /// Solve frames `span` together (frame `span.start` − 1 solved), tied
    /// frame to frame: write the stitched frames up to `keep`, keep their
    /// patches' GBRs, and keep the frames after `keep` (solved ahead) for the
    /// next span, which starts there: their normal equations are the same
    /// but for the anchor, and their solution is where its solve starts.
    fn solve_span(&mut self, span: std::ops::Range<usize>, keep: usize) {
        let [_, hh, ww] = self.layout.shape;
        let mut ahead: Vec<Option<Ahead>> = span.clone().map(|_| None).collect();
        for a in std::mem::take(&mut self.ahead) {
            if span.contains(&a.t) {
                let i = a.t - span.start;
                ahead[i] = Some(a);
            }
        }
        let (video, solved, ahead) = {
            let this = &*self;
            let systems: Vec<FrameSystem<'_>> = span
                .clone()
                .into_par_iter()
                .zip(ahead)
                .map(|(t, ahead)| {
                    let frames = this.patch_frames(t);
                    match ahead {
                        Some(a) => FrameSystem { t, frames, normal: a.normal, start: Some(a.solution) },
                        None => {
                            let normal = this.assemble(t, &frames);
                            FrameSystem { t, frames, normal, start: None }
                        }
                    }
                })
                .collect();
            let bases: Vec<usize> = systems.iter().scan(0, |n, s| Some(std::mem::replace(n, *n + s.frames.len()))).collect();
            let mut blocks: Vec<Vec<(usize, Matrix4<f64>)>> = Vec::new();
            let mut rhs = Vec::new();
            for (system, &base) in systems.iter().zip(&bases) {
                blocks.extend(system.normal.blocks.iter().map(|row| row.iter().map(|&(l, m)| (base + l, m)).collect::<Vec<_>>()));
                rhs.extend_from_slice(&system.normal.rhs);
            }
            // Ties between frames of the span: ν_k (g_k − g_k')ᵀ(g_k − g_k'), k' the
            // same patch one frame earlier; its own diagonal's ν_k I is in place.
            // The first frame's ties pull toward the GBRs solved before it.
            // The solve starts from the solution ahead where there is one, else
            // from the patch's latest GBR.
            // Each patch's frames tied in a row form a chain (the preconditioner's).
            let mut position = vec![usize::MAX; self.patches.len()];
            let mut chain_of = vec![usize::MAX; self.patches.len()];
            let mut chains: Vec<Vec<(usize, f64)>> = Vec::new();
            let mut latest = self.gbrs.clone();
            let mut start = Vec::with_capacity(rhs.len());
            for (i, (system, &base)) in systems.iter().zip(&bases).enumerate() {
                for (k, p) in system.frames.iter().enumerate() {
                    if p.tie > 0.0 && i == 0 {
                        rhs[k] += p.tie * self.gbrs[p.index].expect("a tie to a solved frame has its GBR");
                    }
                    if p.tie > 0.0 && i > 0 {
                        let before = position[p.index];
                        let tie = Matrix4::identity() * p.tie;
                        blocks[before][0].1 += tie;
                        blocks[before].push((base + k, -tie));
                        blocks[base + k].push((before, -tie));
                        chains[chain_of[p.index]].push((base + k, p.tie));
                    } else {
                        chain_of[p.index] = chains.len();
                        chains.push(vec![(base + k, 0.0)]);
                    }
                }
                for (k, p) in system.frames.iter().enumerate() {
                    position[p.index] = base + k;
                    let g = system.start.as_ref().map_or_else(|| latest[p.index].unwrap_or_else(Vector4::zeros), |s| s[k]);
                    latest[p.index] = Some(g);
                    start.push(g);
                }
            }
            let g = conjugate_gradients(&blocks, &chains, &rhs, start);
            let len = hh * ww;
            let mut video = vec![0.0f32; (keep - span.start) * len];
            let mut solved = Vec::new();
            let mut ahead = Vec::new();
            for (system, &base) in systems.into_iter().zip(&bases) {
                let g = &g[base..base + system.frames.len()];
                if system.t >= keep {
                    ahead.push(Ahead { t: system.t, normal: system.normal, solution: g.to_vec() });
                    continue;
                }
                // Row by row, each pixel summing its patch-frames in order.
                let frame = &mut video[(system.t - span.start) * len..(system.t - span.start + 1) * len];
                frame.par_chunks_mut(ww).enumerate().for_each_init(
                    || vec![0.0f64; ww],
                    |sums, (y, row)| {
                        sums.fill(0.0);
                        for (p, gk) in system.frames.iter().zip(g).filter(|(p, _)| (p.rows.0..p.rows.1).contains(&y)) {
                            for x in p.cols.0..p.cols.1 {
                                let (a, w) = this.design(p, y, x);
                                sums[x] += w * a.dot(gk);
                            }
                        }
                        let coarse = &this.coarse_frame(system.t)[y * ww..(y + 1) * ww];
                        for ((o, s), c) in row.iter_mut().zip(sums.iter()).zip(coarse) {
                            *o = if c.is_nan() { f32::NAN } else { *s as f32 };
                        }
                    },
                );
                solved.extend(system.frames.iter().map(|p| p.index).zip(g.iter().copied()));
            }
            (video, solved, ahead)
        };
        debug_assert_eq!(self.video_start + self.video.len() / (hh * ww), span.start);
        self.video.extend_from_slice(&video);
        self.ahead = ahead;
        // In time order, so each patch keeps its GBR at the last kept frame it covers.
        for (index, g) in solved {
            self.gbrs[index] = Some(g);
        }
    }
}

/// A patch-frame's pixels in the video, rows `rows` and columns `cols` (video
/// coordinates), less those off the surface (NaN in `coarse` or in `before`,
/// frames of width `ww`, where given), visited in row-major order as indices
/// into the patch's frame (top-left `corner`, `lx` wide): plain loops in the
/// order the iterator chain of `flat_map` and `filter` they replace took,
/// so its sums keep their bits.
struct Pixels<'a> {
    rows: (usize, usize),
    cols: (usize, usize),
    corner: [isize; 2],
    lx: usize,
    ww: usize,
    coarse: Option<&'a [f32]>,
    before: Option<&'a [f32]>,
}

impl Pixels<'_> {
    #[inline]
    fn for_each(&self, mut visit: impl FnMut(usize)) {
        for y in self.rows.0..self.rows.1 {
            let row = (y as isize - self.corner[0]) as usize * self.lx;
            let shift = self.corner[1];
            let off = |frame: Option<&[f32]>, x: usize| frame.is_some_and(|f| f[y * self.ww + x].is_nan());
            if self.coarse.is_none() && self.before.is_none() {
                for x in self.cols.0..self.cols.1 {
                    visit(row + (x as isize - shift) as usize);
                }
            } else {
                for x in self.cols.0..self.cols.1 {
                    if !(off(self.coarse, x) || off(self.before, x)) {
                        visit(row + (x as isize - shift) as usize);
                    }
                }
            }
        }
    }

    fn count(&self) -> usize {
        let mut n = 0;
        self.for_each(|_| n += 1);
        n
    }

    /// Σ `term(i)` over the pixels in order, from −0.0 as `Iterator::sum` starts: the same bits.
    #[inline]
    fn sum(&self, mut term: impl FnMut(usize) -> f64) -> f64 {
        let mut total = -0.0;
        self.for_each(|i| total += term(i));
        total
    }

    /// Σ v and Σ v² of `values` over the pixels, in one pass: the two sums
    /// do not wait on each other.
    #[inline]
    fn moments(&self, values: &[f32]) -> (f64, f64) {
        let (mut sum, mut sum2) = (-0.0, -0.0);
        self.for_each(|i| {
            let v = values[i] as f64;
            sum += v;
            sum2 += v.powi(2);
        });
        (sum, sum2)
    }
}

/// Σ_l G_kl x_l over a row of blocks: each product's components summed
/// over the columns in order, the products in the row's order from zero, as
/// nalgebra's `m * x` and `Sum` give them (the same bits), in plain loops
/// the compiler keeps in registers.
#[inline]
fn row_times(row: &[(usize, Matrix4<f64>)], x: &[Vector4<f64>]) -> Vector4<f64> {
    let mut sum = [0.0f64; 4];
    for (l, m) in row {
        let v = &x[*l];
        for (i, s) in sum.iter_mut().enumerate() {
            *s += ((m[(i, 0)] * v[0] + m[(i, 1)] * v[1]) + m[(i, 2)] * v[2]) + m[(i, 3)] * v[3];
        }
    }
    Vector4::from(sum)
}

/// Pixel `i` of a patch `l` pixels wide: its centre in patch widths from the
/// patch's centre, in [−½, ½] (the u and v of a_k).
#[inline]
fn coordinate(i: usize, l: usize) -> f64 {
    (i as f64 + 0.5) / l as f64 - 0.5
}

/// One frame of a span: its patch-frames, its part of the normal equations,
/// and where its solve starts when it was solved ahead.
struct FrameSystem<'a> {
    t: usize,
    frames: Vec<PatchFrame<'a>>,
    normal: Normal,
    start: Option<Vec<Vector4<f64>>>,
}

/// A frame's part of the normal equations (`assemble`), in its own indices.
struct Normal {
    blocks: Vec<Vec<(usize, Matrix4<f64>)>>,
    rhs: Vec<Vector4<f64>>,
}

/// A frame solved ahead of the frames kept (`solve_span`).
struct Ahead {
    t: usize,
    normal: Normal,
    solution: Vec<Vector4<f64>>,
}

/// Solve the block-sparse SPD system `G x = b` (rows of (column, 4×4 block),
/// the diagonal block first) by conjugate gradients from `start`, to a
/// residual of 1e-10 of ‖b‖ or 2000 iterations. Preconditioned with G's
/// part along `chains` (each a patch's frames tied in a row: (unknown, ν to
/// the one before)), a block-tridiagonal system solved exactly: without ties,
/// block Jacobi (some 50–60 iterations a frame at μ = 0.005, growing about as
/// 1/√μ); with them it keeps the tie's strong coupling of frames from slowing
/// the solve (`benches/stitching.rs`'s first span: 62 iterations, 317 with
/// block Jacobi).
fn conjugate_gradients(blocks: &[Vec<(usize, Matrix4<f64>)>], chains: &[Vec<(usize, f64)>], b: &[Vector4<f64>], start: Vec<Vector4<f64>>) -> Vec<Vector4<f64>> {
    let n = b.len();
    let precondition = ChainPreconditioner::new(blocks, chains);
    let apply = |x: &[Vector4<f64>], out: &mut [Vector4<f64>]| {
        out.par_iter_mut().zip(blocks).with_min_len(256).for_each(|(o, row)| *o = row_times(row, x));
    };
    let dot = |a: &[Vector4<f64>], c: &[Vector4<f64>]| a.iter().zip(c).map(|(u, v)| u.dot(v)).sum::<f64>();
    let mut x = start;
    let mut r = vec![Vector4::zeros(); n];
    apply(&x, &mut r);
    for (r, b) in r.iter_mut().zip(b) {
        *r = b - *r;
    }
    let mut z = vec![Vector4::zeros(); n];
    precondition.apply(&r, &mut z);
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
        }
        precondition.apply(&r, &mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    x
}

/// The part of a block-sparse SPD system along chains of unknowns, each
/// block tridiagonal with −ν I between neighbours (the temporal ties),
/// factorised by block elimination along each chain (the Thomas algorithm):
/// `inverses[u]` is the inverse of u's diagonal block less what eliminating
/// the chain before it took, D'_j = D_j − ν_j² D'_{j−1}⁻¹ (a Schur complement
/// of an SPD matrix, so SPD).
struct ChainPreconditioner<'a> {
    chains: &'a [Vec<(usize, f64)>],
    inverses: Vec<Matrix4<f64>>,
}

impl<'a> ChainPreconditioner<'a> {
    fn new(blocks: &[Vec<(usize, Matrix4<f64>)>], chains: &'a [Vec<(usize, f64)>]) -> Self {
        let mut inverses = vec![Matrix4::zeros(); blocks.len()];
        for chain in chains {
            let mut before: Option<Matrix4<f64>> = None;
            for &(u, nu) in chain {
                let d = match before {
                    Some(inverse) => blocks[u][0].1 - nu * nu * inverse,
                    None => blocks[u][0].1,
                };
                inverses[u] = d.try_inverse().unwrap_or_else(Matrix4::zeros);
                before = Some(inverses[u]);
            }
        }
        Self { chains, inverses }
    }

    /// z = M⁻¹ r: forward elimination r'_j = r_j + ν_j D'_{j−1}⁻¹ r'_{j−1},
    /// then back substitution z_j = D'_j⁻¹ (r'_j + ν_{j+1} z_{j+1}).
    fn apply(&self, r: &[Vector4<f64>], z: &mut [Vector4<f64>]) {
        for chain in self.chains {
            let mut carried = Vector4::zeros();
            for (j, &(u, nu)) in chain.iter().enumerate() {
                z[u] = if j == 0 { r[u] } else { r[u] + nu * (self.inverses[chain[j - 1].0] * carried) };
                carried = z[u];
            }
            let mut after = Vector4::zeros();
            let mut nu_after = 0.0;
            for &(u, nu) in chain.iter().rev() {
                after = self.inverses[u] * (z[u] + nu_after * after);
                z[u] = after;
                nu_after = nu;
            }
        }
    }
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

    /// The plain loops give the bits of the iterator chains they replaced:
    /// pixels off the surface in either frame left out, a patch hanging over
    /// the video's corner, sums from −0.0, block products through nalgebra.
    #[test]
    fn plain_loops_sum_as_the_iterators_did() {
        let (hh, ww, lx) = (40, 50, 16);
        let values: Vec<f32> = (0..lx * lx).map(|i| 3.0 * pseudo(i) + 0.25).collect();
        let frame = |seed: usize| -> Vec<f32> { (0..hh * ww).map(|i| if pseudo(i * 7 + seed) > 0.3 { f32::NAN } else { pseudo(i + seed) }).collect() };
        let (coarse, before) = (frame(1), frame(2));
        for corner in [[-5isize, -3isize], [10, 20], [30, 40]] {
            let span = |c: isize, n: usize| (c.clamp(0, n as isize) as usize, (c + lx as isize).clamp(0, n as isize) as usize);
            let (rows, cols) = (span(corner[0], hh), span(corner[1], ww));
            for (on_coarse, on_before) in [(false, false), (true, false), (false, true), (true, true)] {
                let pixels = Pixels { rows, cols, corner, lx, ww, coarse: on_coarse.then_some(&coarse[..]), before: on_before.then_some(&before[..]) };
                let chain = || {
                    (rows.0..rows.1)
                        .flat_map(|y| (cols.0..cols.1).map(move |x| (y, x)))
                        .filter(|&(y, x)| !(on_coarse && coarse[y * ww + x].is_nan() || on_before && before[y * ww + x].is_nan()))
                        .map(|(y, x)| (y as isize - corner[0]) as usize * lx + (x as isize - corner[1]) as usize)
                };
                let sum: f64 = chain().map(|i| values[i] as f64).sum();
                let sum2: f64 = chain().map(|i| (values[i] as f64).powi(2)).sum();
                let (s, s2) = pixels.moments(&values);
                assert_eq!((s.to_bits(), s2.to_bits()), (sum.to_bits(), sum2.to_bits()));
                let term = |i: usize| (values[i] as f64 - 0.1) * 1.7;
                assert_eq!(pixels.sum(term).to_bits(), chain().map(term).sum::<f64>().to_bits());
                assert_eq!(pixels.count(), chain().count());
            }
        }
        let x: Vec<Vector4<f64>> = (0..6).map(|k| Vector4::from_fn(|i, _| pseudo(10 * k + i) as f64 * 1e3)).collect();
        for n in [0, 1, 5, 17] {
            let row: Vec<(usize, Matrix4<f64>)> = (0..n).map(|k| ((k * 5) % 6, Matrix4::from_fn(|i, j| pseudo(100 * k + 4 * i + j) as f64 / 3.0))).collect();
            let by_nalgebra: Vector4<f64> = row.iter().map(|(l, m)| m * x[*l]).sum();
            assert_eq!(row_times(&row, &x).map(f64::to_bits), by_nalgebra.map(f64::to_bits));
        }
    }

    /// A smooth depth video and its patches (over the video padded by
    /// mirroring), each frame of each patch seen through its own
    /// pseudo-random GBR (sign flips included).
    fn scene(shape: [usize; 3], patch: [usize; 3]) -> (Layout, Vec<f32>, Vec<f32>, Vec<[usize; 3]>) {
        scene_of(shape, patch, false)
    }

    /// `steady`: the depth holds still and each patch keeps one GBR over its
    /// frames, its values jittered by noise of 2 % of the relief per frame.
    fn scene_of(shape: [usize; 3], patch: [usize; 3], steady: bool) -> (Layout, Vec<f32>, Vec<f32>, Vec<[usize; 3]>) {
        let layout = Layout::new(shape, patch).unwrap();
        let [tt, hh, ww] = shape;
        let depth = |t: isize, y: isize, x: isize| {
            let (t, y, x) = (if steady { 0.0 } else { t as f32 }, y as f32, x as f32);
            (0.9 * x + 0.3 * t).sin() * (0.7 * y).cos() + (0.25 * x - 0.15 * y).sin() + 0.2 * x * y / (hh * ww) as f32 + 0.1 * (0.5 * t).cos()
        };
        let truth: Vec<f32> = (0..tt * hh * ww).map(|i| depth((i / (hh * ww)) as isize, (i / ww % hh) as isize, (i % ww) as isize)).collect();
        let origins = layout.origins();
        let [lt, ly, lx] = patch;
        let mut patches = Vec::new();
        for (n, o) in origins.iter().enumerate() {
            for f in 0..lt {
                let s = if steady { n * lt } else { n * lt + f };
                let g = [pseudo(4 * s), pseudo(4 * s + 1), 1.0 + pseudo(4 * s + 2), 3.0 * pseudo(4 * s + 3)];
                let g = if !steady && (n + f) % 3 == 0 { [g[0], g[1], -g[2], g[3]] } else { g };
                for y in 0..ly {
                    for x in 0..lx {
                        let (t, gy, gx) = (o[0] as isize + f as isize - layout.pad[0] as isize, o[1] as isize + y as isize - layout.pad[1] as isize, o[2] as isize + x as isize - layout.pad[2] as isize);
                        // The padding mirrors the video, as `reconstruct` pads it.
                        let v = coarse_at(&truth, &layout, t, gy, gx);
                        let noise = if steady { 0.02 * pseudo(1_000_003 + patches.len()) } else { 0.0 };
                        patches.push(g[0] * x as f32 + g[1] * y as f32 + g[2] * (v + noise) + g[3]);
                    }
                }
            }
        }
        (layout, truth, patches, origins)
    }

    const WINDOWS: [Window; 2] = [Window::Triangle, Window::Hann];

    fn joint(layout: &Layout, coarse: &[f32], mu: f64, nu: f64, window: Window, patches: &[f32], origins: &[[usize; 3]]) -> Vec<f32> {
        let mut s = JointStitcher::new(*layout, coarse.to_vec(), mu, nu, window).unwrap();
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
                let out = joint(&layout, &truth, mu, 0.0, window, &patches, &origins);
                let err = out.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
                assert!(err < 2e-3, "{shape:?} μ={mu} {window:?}: {err}");
            }
        }
    }

    /// Off the surface (NaN in the coarse depth) the stitched depth is NaN,
    /// and what the patches hold there changes nothing: patches that see the
    /// truth through their own GBRs on the surface give it back there, with
    /// noise off it, whole patch-frames off it included; tied or not, the
    /// bytes do not depend on that noise.
    #[test]
    fn pixels_off_the_surface_take_no_part() {
        let (layout, truth, patches, origins) = scene([9, 24, 28], [4, 8, 8]);
        let [tt, hh, ww] = layout.shape;
        let [lt, ly, lx] = layout.patch;
        // A disc that drifts, so patches and patch-frames wholly off it occur.
        let on = |t: usize, y: isize, x: isize| {
            let (cy, cx) = (12.0 + 0.5 * t as f32, 13.0 - 0.4 * t as f32);
            (y as f32 - cy).powi(2) + (x as f32 - cx).powi(2) < 81.0
        };
        let coarse: Vec<f32> = truth.iter().enumerate().map(|(i, &v)| if on(i / (hh * ww), (i / ww % hh) as isize, (i % ww) as isize) { v } else { f32::NAN }).collect();
        let noisy = |seed: usize| -> Vec<f32> {
            let mut out = patches.clone();
            for (n, o) in origins.iter().enumerate() {
                for f in 0..lt {
                    for y in 0..ly {
                        for x in 0..lx {
                            let (t, gy, gx) = (o[0] + f, (o[1] + y) as isize - layout.pad[1] as isize, (o[2] + x) as isize - layout.pad[2] as isize);
                            let t = t.saturating_sub(layout.pad[0]).min(tt - 1);
                            if !on(t, gy.clamp(0, hh as isize - 1), gx.clamp(0, ww as isize - 1)) {
                                out[((n * lt + f) * ly + y) * lx + x] = 40.0 * pseudo(seed + ((n * lt + f) * ly + y) * lx + x);
                            }
                        }
                    }
                }
            }
            out
        };
        let (a, b) = (noisy(5), noisy(1_000_033));
        assert!(a != b);
        for nu in [0.0, 0.5] {
            let out = joint(&layout, &coarse, 1e-2, nu, Window::Hann, &a, &origins);
            assert_eq!(out.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), joint(&layout, &coarse, 1e-2, nu, Window::Hann, &b, &origins).iter().map(|v| v.to_bits()).collect::<Vec<_>>(), "ν={nu}");
            for (i, (o, c)) in out.iter().zip(&coarse).enumerate() {
                if c.is_nan() {
                    assert!(o.is_nan(), "ν={nu} {i}: {o}");
                } else if nu == 0.0 {
                    // (A tie trades the patches' own GBRs, drawn anew each frame, against their agreement.)
                    assert!((o - c).abs() < 2e-3, "{i}: {o} vs {c}");
                }
            }
        }
        // Patch-frames with none of their pixels in the video on the surface.
        let mut whole_frames_off = 0;
        for o in &origins {
            for f in 0..lt {
                let Some(t) = (o[0] + f).checked_sub(layout.pad[0]).filter(|&t| t < tt) else { continue };
                let rows = (o[1] as isize - layout.pad[1] as isize..(o[1] + ly) as isize - layout.pad[1] as isize).filter(|&y| (0..hh as isize).contains(&y));
                let pixels: Vec<(isize, isize)> = rows.flat_map(|y| (o[2] as isize - layout.pad[2] as isize..(o[2] + lx) as isize - layout.pad[2] as isize).filter(|&x| (0..ww as isize).contains(&x)).map(move |x| (y, x))).collect();
                whole_frames_off += (!pixels.is_empty() && !pixels.iter().any(|&(y, x)| on(t, y, x))) as usize;
            }
        }
        assert!(whole_frames_off > 0, "some patch-frames lie wholly off the surface");
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
            let out = joint(&layout, &coarse, 1e-5, 0.0, window, &patches, &origins);
            let (joint_err, coarse_err) = (frame_error(&out), frame_error(&coarse));
            assert!(joint_err < 0.1 * coarse_err, "{window:?}: joint {joint_err}, coarse {coarse_err}");
        }
    }

    /// The solution is the minimiser of E(g) (module header), frame after
    /// frame with the temporal tie to the frame before, checked against a
    /// dense least-squares solve of the same objective on a small video (the
    /// tie's weights computed here from the patches).
    #[test]
    fn matches_a_dense_least_squares_solve() {
        for window in WINDOWS {
            for (steady, nu, masked) in [(false, 0.0, false), (false, 0.5, false), (true, 0.5, false), (false, 0.0, true), (true, 0.5, true)] {
                matches_a_dense_least_squares_solve_with(window, steady, nu, masked);
            }
        }
    }

    /// `masked`: pixels off the surface (NaN in the coarse depth) scattered
    /// over the frames and a block in a corner, so that rows differ but every
    /// patch-frame keeps some pixels: they take no part in the objective.
    fn matches_a_dense_least_squares_solve_with(window: Window, steady: bool, nu: f64, masked: bool) {
        let (layout, truth, patches, origins) = scene_of([6, 12, 10], [4, 8, 8], steady);
        let [_, hh, ww] = layout.shape;
        let [lt, ly, lx] = layout.patch;
        let off = |i: usize| masked && ((i % ww + 2 * (i / ww % hh) + i / (hh * ww)).is_multiple_of(5) || (i % ww < 3 && i / ww % hh < 3));
        let coarse: Vec<f32> = truth.iter().enumerate().map(|(i, v)| if off(i) { f32::NAN } else { 0.5 * v + pseudo(i + 99) * 0.3 }).collect();
        let mu = 0.05;
        let out = joint(&layout, &coarse, mu, nu, window, &patches, &origins);
        let plen = 4 * 8 * 8;
        let mut tied = 0;
        let mut stitcher = {
            let mut s = JointStitcher::new(layout, coarse.clone(), mu, nu, window).unwrap();
            for (i, o) in origins.iter().enumerate() {
                let cell: [usize; 3] = std::array::from_fn(|a| o[a] / (layout.patch[a] / 2));
                let index = s.index(cell);
                s.patches[index] = Some(patches[i * plen..(i + 1) * plen].to_vec());
            }
            s
        };
        let by_index: std::collections::HashMap<usize, usize> = origins
            .iter()
            .enumerate()
            .map(|(i, o)| (stitcher.index(std::array::from_fn(|a| o[a] / (layout.patch[a] / 2))), i))
            .collect();
        // Untied, frame by frame; tied, blocks of the temporal hop, each solved
        // with the block after it and kept alone (module header).
        let hop = lt / 2;
        let block_end = |b: usize| ((b + 1) * hop).saturating_sub(layout.pad[0]).min(layout.shape[0]);
        let mut spans = Vec::new();
        let mut next = 0;
        while next < layout.shape[0] {
            let b = (next + layout.pad[0]) / hop;
            let (keep, end) = if nu == 0.0 { (next + 1, next + 1) } else { (block_end(b), block_end(b + LOOKAHEAD)) };
            spans.push((next..end, keep));
            next = keep;
        }
        assert!(nu == 0.0 || spans.iter().any(|(span, keep)| span.end > *keep && span.len() > 1), "the video is long enough to test solving ahead");
        for (span, keep) in spans {
            let systems: Vec<Vec<PatchFrame<'_>>> = span.clone().map(|t| stitcher.patch_frames(t)).collect();
            let bases: Vec<usize> = systems.iter().scan(0, |n, f| Some(std::mem::replace(n, *n + f.len()))).collect();
            let k = systems.iter().map(|f| f.len()).sum::<usize>();
            let mut rows: Vec<(DVector<f64>, f64)> = Vec::new();
            for ((t, frames), &base) in span.clone().zip(&systems).zip(&bases) {
                // The tie's weights, from the patches' frames f − 1 and f over their pixels in the video.
                let ties: Vec<f64> = frames
                    .iter()
                    .map(|p| {
                        let f = t + layout.pad[0] - p.index / (stitcher.counts[1] * stitcher.counts[2]) * lt / 2;
                        if nu == 0.0 || f == 0 || t == 0 {
                            return 0.0;
                        }
                        let patch = &patches[by_index[&p.index] * plen..][..plen];
                        let standardised = |f: usize| {
                            let v: Vec<f64> = (p.rows.0..p.rows.1)
                                .flat_map(|y| (p.cols.0..p.cols.1).map(move |x| (y, x)))
                                .filter(|&(y, x)| !off((t * hh + y) * ww + x) && !off(((t - 1) * hh + y) * ww + x))
                                .map(|(y, x)| patch[(f * ly + (y as isize - p.corner[0]) as usize) * lx + (x as isize - p.corner[1]) as usize] as f64)
                                .collect();
                            let n = v.len() as f64;
                            let mean = v.iter().sum::<f64>() / n;
                            let std = (v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / n).sqrt();
                            v.into_iter().map(|a| (a - mean) / std).collect::<Vec<f64>>()
                        };
                        let (a, b) = (standardised(f - 1), standardised(f));
                        let rho = a.iter().zip(&b).map(|(u, v)| u * v).sum::<f64>() / a.len() as f64;
                        nu * a.len() as f64 * (-(1.0 - rho) / TIE_SCALE).exp()
                    })
                    .collect();
                for (p, tie) in frames.iter().zip(&ties) {
                    assert!((p.tie - tie).abs() <= 1e-9 * tie.max(1.0), "t={t}: tie {} vs {tie}", p.tie);
                    tied += (*tie > 1e-3 * nu * 64.0) as usize;
                }
                // Rows: √w_k (a_kᵀg_k − S) per pixel on the surface and patch-frame, then √μ (a_kᵀg_k − C).
                for y in 0..hh {
                    for x in (0..ww).filter(|&x| !off((t * hh + y) * ww + x)) {
                        let cover: Vec<(usize, Vector4<f64>, f64)> = frames
                            .iter()
                            .enumerate()
                            .filter(|(_, p)| (p.rows.0..p.rows.1).contains(&y) && (p.cols.0..p.cols.1).contains(&x))
                            .map(|(i, p)| {
                                let (a, w) = stitcher.design(p, y, x);
                                (base + i, a, w)
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
                // √ν_k (g_k − g_k'), k' the same patch at frame t − 1: solved before
                // the span (its GBR), or in it (unknown).
                for (i, (p, tie)) in frames.iter().zip(&ties).enumerate().filter(|(_, (_, tie))| **tie > 0.0) {
                    for d in 0..4 {
                        let mut row = DVector::zeros(4 * k);
                        row[4 * (base + i) + d] = tie.sqrt();
                        if t == span.start {
                            rows.push((row, tie.sqrt() * stitcher.gbrs[p.index].unwrap()[d]));
                        } else {
                            let before = systems[t - span.start - 1].iter().position(|q| q.index == p.index).unwrap();
                            row[4 * (bases[t - span.start - 1] + before) + d] = -tie.sqrt();
                            rows.push((row, 0.0));
                        }
                    }
                }
            }
            let a = DMatrix::from_fn(rows.len(), 4 * k, |r, c| rows[r].0[c]);
            let b = DVector::from_iterator(rows.len(), rows.iter().map(|r| r.1));
            let g = (a.transpose() * &a).cholesky().expect("the dense system is positive definite").solve(&(a.transpose() * b));
            let mut solved = Vec::new();
            for ((t, frames), &base) in span.clone().zip(&systems).zip(&bases).filter(|((t, _), _)| *t < keep) {
                let gk = |i: usize| g.fixed_rows::<4>(4 * (base + i)).into_owned();
                for y in 0..hh {
                    for x in 0..ww {
                        let s: f64 = frames
                            .iter()
                            .enumerate()
                            .filter(|(_, p)| (p.rows.0..p.rows.1).contains(&y) && (p.cols.0..p.cols.1).contains(&x))
                            .map(|(i, p)| {
                                let (a, w) = stitcher.design(p, y, x);
                                w * a.dot(&gk(i))
                            })
                            .sum();
                        let got = out[(t * hh + y) * ww + x] as f64;
                        if off((t * hh + y) * ww + x) {
                            assert!(got.is_nan(), "off the surface, t={t} y={y} x={x}: {got}");
                            continue;
                        }
                        assert!((got - s).abs() < 1e-4 * (1.0 + s.abs()), "{window:?} ν={nu} t={t} y={y} x={x}: {got} vs {s}");
                    }
                }
                solved.extend(frames.iter().enumerate().map(|(i, p)| (p.index, gk(i))));
            }
            drop(systems);
            for (index, g) in solved {
                stitcher.gbrs[index] = Some(g);
            }
        }
        // The steady scene's ties hold; the changing one's mostly let go.
        if nu > 0.0 {
            assert!(steady == (tied > 0), "steady {steady}: {tied} patch-frames tied");
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
            let out = joint(&layout, &coarse, 1e9, 0.0, window, &patches, &origins);
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

    /// Where a patch's frames are one reading (up to a little noise) and the
    /// coarse depth flickers (each frame its own smooth error, as a network's
    /// coarse pass), the tie steadies the stitched video: a still scene comes
    /// back far stiller over time, and closer to the truth.
    #[test]
    fn the_temporal_tie_steadies_a_still_scene() {
        let (layout, truth, patches, origins) = scene_of([12, 24, 24], [4, 8, 8], true);
        let coarse: Vec<f32> = (0..truth.len())
            .map(|i| {
                let (t, y, x) = ((i / 576) as f32, (i / 24 % 24) as f32, (i % 24) as f32);
                0.5 * truth[i] + 0.3 * (0.3 * x + 1.7 * t).sin() * (0.2 * y + 0.9 * t).cos()
            })
            .collect();
        let len = 24 * 24;
        let change = |d: &[f32]| d[len..].iter().zip(d).map(|(a, b)| (a - b).abs() as f64).sum::<f64>() / (d.len() - len) as f64;
        let error = |d: &[f32]| d.iter().zip(&truth).map(|(a, b)| (a - b).abs() as f64).sum::<f64>() / d.len() as f64;
        for window in WINDOWS {
            let free = joint(&layout, &coarse, 0.01, 0.0, window, &patches, &origins);
            let tied = joint(&layout, &coarse, 0.01, 0.5, window, &patches, &origins);
            assert!(change(&tied) < 0.5 * change(&free), "{window:?}: frame-to-frame change {} tied, {} free", change(&tied), change(&free));
            assert!(error(&tied) < error(&free), "{window:?}: error {} tied, {} free", error(&tied), error(&free));
        }
    }

    #[test]
    fn order_chunking_and_threads_give_the_same_bytes_and_patches_are_released() {
        for (steady, nu) in [(false, 0.0), (true, 0.5)] {
            order_chunking_and_threads_with(steady, nu);
        }
    }

    fn order_chunking_and_threads_with(steady: bool, nu: f64) {
        let (layout, truth, patches, origins) = scene_of([20, 16, 24], [4, 8, 8], steady);
        let whole = joint(&layout, &truth, 0.01, nu, Window::Hann, &patches, &origins);
        let plen = 4 * 8 * 8;
        let mut stitcher = JointStitcher::new(layout, truth.clone(), 0.01, nu, Window::Hann).unwrap();
        let mut most = 0;
        for (chunk, o) in patches.chunks(5 * plen).zip(origins.chunks(5)) {
            stitcher.add(chunk, o).unwrap();
            most = most.max(stitcher.buffered());
        }
        assert!(most < origins.len() / 2, "time-major input holds {most} of {} patches", origins.len());
        assert_eq!(stitcher.finish().unwrap(), whole);
        // One thread.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(pool.install(|| joint(&layout, &truth, 0.01, nu, Window::Hann, &patches, &origins)), whole);
        // Reversed order, one patch at a time.
        let mut stitcher = JointStitcher::new(layout, truth, 0.01, nu, Window::Hann).unwrap();
        for i in (0..origins.len()).rev() {
            stitcher.add(&patches[i * plen..(i + 1) * plen], &origins[i..i + 1]).unwrap();
        }
        assert_eq!(stitcher.finish().unwrap(), whole);
    }

    #[test]
    fn streamed_coarse_depth_and_taken_frames_give_the_same_bytes() {
        // Masked: a band off the surface that moves each frame, so the tie reads frame t − 1's mask across a `take`.
        for (steady, nu, masked) in [(false, 0.0, false), (true, 0.5, false), (true, 0.5, true)] {
            let (layout, truth, patches, origins) = scene_of([21, 16, 24], [4, 8, 8], steady);
            let truth: Vec<f32> = truth.iter().enumerate().map(|(i, &v)| if masked && (i % 24 + i / (16 * 24)) % 9 < 3 { f32::NAN } else { v }).collect();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let whole = joint(&layout, &truth, 0.01, nu, Window::Hann, &patches, &origins);
            assert_eq!(masked, whole.iter().any(|v| v.is_nan()));
            let (plen, frame) = (4 * 8 * 8, 16 * 24);
            // The coarse depth three frames at a time, a step ahead of the patches; frames taken as they come.
            let mut stitcher = JointStitcher::new(layout, truth[..2 * frame].to_vec(), 0.01, nu, Window::Hann).unwrap();
            let (mut given, mut out, mut most) = (2, Vec::new(), 0);
            for (chunk, o) in patches.chunks(6 * plen).zip(origins.chunks(6)) {
                let want = (o.last().unwrap()[0] + 3).min(21);
                if want > given {
                    stitcher.push_coarse(&truth[given * frame..want * frame]).unwrap();
                    given = want;
                }
                stitcher.add(chunk, o).unwrap();
                let taken = stitcher.take();
                assert_eq!(taken.len() % frame, 0);
                out.extend(taken);
                most = most.max(stitcher.video.len() + stitcher.coarse.len());
            }
            assert_eq!(given, 21);
            out.extend(stitcher.finish().unwrap());
            assert_eq!(bits(&out), bits(&whole));
            // All the patches first, then the coarse depth five frames at a time.
            let mut stitcher = JointStitcher::new(layout, Vec::new(), 0.01, nu, Window::Hann).unwrap();
            assert!(stitcher.push_coarse(&truth[..frame + 1]).is_err(), "whole frames only");
            let mut out = Vec::new();
            for (chunk, o) in patches.chunks(6 * plen).zip(origins.chunks(6)) {
                stitcher.add(chunk, o).unwrap();
            }
            for part in truth.chunks(5 * frame) {
                stitcher.push_coarse(part).unwrap();
                out.extend(stitcher.take());
            }
            assert!(stitcher.push_coarse(&truth[..frame]).is_err(), "no frames past the video");
            out.extend(stitcher.finish().unwrap());
            assert_eq!(bits(&out), bits(&whole));
            let mut stitcher = JointStitcher::new(layout, truth[..frame].to_vec(), 0.01, nu, Window::Hann).unwrap();
            stitcher.add(&patches, &origins).unwrap();
            assert!(stitcher.finish().is_err(), "finish needs every frame's coarse depth");
            assert!(most < truth.len() / 2, "streamed, the stitcher held {most} values of a video of {}", truth.len());
        }
    }

    #[test]
    fn the_chain_preconditioner_solves_its_chains_exactly() {
        // Unknowns 0..8 in chains of 1, 3 and 4, tied by ν; a coupling outside
        // the chains (unknowns 2 and 3) is not the preconditioner's.
        let chains = vec![vec![(2, 0.0)], vec![(0, 0.0), (3, 0.7), (5, 1.3)], vec![(1, 0.0), (4, 0.4), (6, 2.0), (7, 0.9)]];
        let n = 8;
        let mut blocks: Vec<Vec<(usize, Matrix4<f64>)>> = (0..n)
            .map(|u| {
                let a = Matrix4::from_fn(|i, j| pseudo(u * 16 + i * 4 + j) as f64);
                vec![(u, a * a.transpose() + Matrix4::identity() * 5.0)]
            })
            .collect();
        blocks[2].push((3, Matrix4::identity()));
        blocks[3].push((2, Matrix4::identity()));
        let mut m = DMatrix::<f64>::zeros(4 * n, 4 * n);
        for (u, row) in blocks.iter().enumerate() {
            m.fixed_view_mut::<4, 4>(4 * u, 4 * u).copy_from(&row[0].1);
        }
        for chain in &chains {
            for pair in chain.windows(2) {
                let ((u, _), (v, nu)) = (pair[0], pair[1]);
                m.fixed_view_mut::<4, 4>(4 * u, 4 * v).copy_from(&(-nu * Matrix4::identity()));
                m.fixed_view_mut::<4, 4>(4 * v, 4 * u).copy_from(&(-nu * Matrix4::identity()));
            }
        }
        let r: Vec<Vector4<f64>> = (0..n).map(|u| Vector4::from_fn(|i, _| pseudo(500 + 4 * u + i) as f64)).collect();
        let mut z = vec![Vector4::zeros(); n];
        ChainPreconditioner::new(&blocks, &chains).apply(&r, &mut z);
        let z = DVector::from_iterator(4 * n, z.iter().flat_map(|v| v.iter().copied()));
        let r = DVector::from_iterator(4 * n, r.iter().flat_map(|v| v.iter().copied()));
        assert!((&m * z - &r).norm() <= 1e-12 * r.norm(), "M z = r along the chains");
    }

    #[test]
    fn bad_input_is_named() {
        let (layout, truth, patches, origins) = scene([5, 16, 16], [4, 8, 8]);
        let plen = 4 * 8 * 8;
        let err = |r: Result<()>| r.unwrap_err().name;
        assert_eq!(JointStitcher::new(layout, truth.clone(), 0.0, 0.0, Window::Hann).err().unwrap().name, "coarse_weight");
        assert_eq!(JointStitcher::new(layout, truth.clone(), f64::NAN, 0.0, Window::Hann).err().unwrap().name, "coarse_weight");
        assert_eq!(JointStitcher::new(layout, truth.clone(), 1.0, -1.0, Window::Hann).err().unwrap().name, "temporal_weight");
        assert_eq!(JointStitcher::new(layout, truth.clone(), 1.0, f64::INFINITY, Window::Hann).err().unwrap().name, "temporal_weight");
        assert_eq!(JointStitcher::new(layout, truth[1..].to_vec(), 1.0, 0.0, Window::Hann).err().unwrap().name, "coarse");
        let mut infinite = truth.clone();
        infinite[7] = f32::NEG_INFINITY;
        assert_eq!(JointStitcher::new(layout, infinite.clone(), 1.0, 0.0, Window::Hann).err().unwrap().name, "coarse");
        let mut streamed = JointStitcher::new(layout, Vec::new(), 1.0, 0.0, Window::Hann).unwrap();
        assert_eq!(err(streamed.push_coarse(&infinite[..16 * 16])), "coarse");
        let mut s = JointStitcher::new(layout, truth.clone(), 1.0, 0.0, Window::Hann).unwrap();
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
