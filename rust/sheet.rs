//! Sheets: isometric bends, rolls and folds of the patch (generalised cylinders).
//!
//! Paper and cloth bend without stretching. A sheet bent about an axis of
//! the patch plane stays straight along the axis direction `a` (in-plane
//! angle α(t)); across it, the coordinate `s = x·b` (b ⟂ a) runs along a
//! planar curve of arc length `s` and curvature `k(s, t)`:
//!
//! ```text
//! θ(s) = ∫₀ˢ k,   C(s) = ∫₀ˢ (cos θ, sin θ)            in the (b, z) plane
//! f(x) = (x·a) a + C_b(s) b + C_z(s) ẑ + h n(s),     n(s) = (−sin θ, cos θ)
//! k(s, t) = Σ_j A_j(t) · exp(−(s − c_j(t))² / (2 w_j²)) / (w_j √(2π))
//! ```
//!
//! With `h = 0` the map is an isometry of the flat sheet: the tangents along
//! `a` and along `s` keep unit length and stay orthogonal. Term `j` turns the
//! sheet by `A_j` radians, spread over a Gaussian of width `w_j` about `c_j`:
//! wide terms are bends and rolls, narrow ones folds (creases). `A_j`, `c_j`
//! and α move linearly over the clip (t in clip durations), so the
//! curvature changes smoothly in time; with `phases` P > 1 they pass
//! through P + 1 knots evenly spaced in time (each new knot: a turn drawn
//! afresh, a centre moved by a further drift and kept in the centre's
//! range, an axis turned by a further rate) and move linearly between them:
//! a long video bends the sheet P ways in turn. `h` is a small relief along the normal
//! (the coloured-noise surface of `synthesis`, its intensity scaled by
//! `relief`), which stretches the sheet by what that relief stretches.
//!
//! Units: lengths in half-widths of the patch, angles in radians. θ and C
//! are tabulated at `TABLE` samples of `s ∈ [−SPAN, SPAN]` (trapezoid rule,
//! from s = 0 outward, so the patch centre stays at the origin with its
//! tangent plane z = 0) and interpolated linearly; the rigid motion `E_t`
//! of the surface is applied after the bend.

use crate::error::{in_range, InvalidArgument, Result};
use crate::params::Range;
use crate::rng::SplitMix64;

/// Half-length of the tabulated cross-section: the patch's half-diagonal
/// plus the largest drift and relief displacement.
const SPAN: f64 = 2.0;
/// Samples of the cross-section table (odd, so s = 0 is a sample).
const TABLE: usize = 4097;

/// The ranges a clip's sheet is drawn from (uniform unless noted).
#[derive(Clone, Debug, PartialEq)]
pub struct SheetConfig {
    /// Share of clips that are sheets; the others are the coloured-noise
    /// surfaces alone. 0 draws nothing, so clips stay as they were.
    pub probability: f64,
    /// Number of wide terms (bends and rolls), inclusive.
    pub bends: (usize, usize),
    /// Turn of a bend at t = 0 and at t = 1, each drawn from this range.
    pub bend_angle: Range,
    /// Width w of a bend's curvature Gaussian.
    pub bend_width: Range,
    /// Probability of one narrow term (a fold).
    pub fold_probability: f64,
    /// Turn of a fold at t = 0 and at t = 1, each drawn from this range.
    pub fold_angle: Range,
    /// Width w of a fold's curvature Gaussian.
    pub fold_width: Range,
    /// Centre c of a term (along s) at t = 0.
    pub centre: Range,
    /// Change of a term's centre over the clip.
    pub centre_drift: Range,
    /// Change of the axis angle α over the clip (α at t = 0 is uniform).
    pub axis_rate: Range,
    /// Factor on the surface's coloured-noise intensity κ (small relief).
    pub relief: Range,
    /// Number of spans the clip is cut into, each bending the sheet a new
    /// way (new knots at their ends: the module header); 1 moves linearly
    /// from start to end.
    pub phases: usize,
    /// Whether every term's turn at t = 0 is 0: the clip starts from the
    /// flat sheet (its relief aside), as a real video of paper often does.
    pub flat_start: bool,
}

impl Default for SheetConfig {
    fn default() -> Self {
        Self {
            probability: 0.0,
            bends: (1, 2),
            bend_angle: Range::new(-2.2, 2.2),
            bend_width: Range::new(0.3, 1.5),
            fold_probability: 0.3,
            fold_angle: Range::new(-1.2, 1.2),
            fold_width: Range::new(0.08, 0.2),
            centre: Range::new(-0.8, 0.8),
            centre_drift: Range::new(-0.3, 0.3),
            axis_rate: Range::new(-0.3, 0.3),
            relief: Range::new(0.0, 0.5),
            phases: 1,
            flat_start: false,
        }
    }
}

impl SheetConfig {
    pub fn validate(&self) -> Result<()> {
        in_range("config.sheet_probability", self.probability, 0.0, 1.0)?;
        let (lo, hi) = self.bends;
        if lo > hi || hi > 8 {
            return Err(InvalidArgument::new("config.sheet_bends", format!("expected 0 <= lo <= hi <= 8, got ({lo}, {hi})")));
        }
        let turn = std::f64::consts::TAU;
        self.bend_angle.check("config.sheet_bend_angle", -turn, turn)?;
        self.bend_width.check("config.sheet_bend_width", 0.01, 100.0)?;
        in_range("config.sheet_fold_probability", self.fold_probability, 0.0, 1.0)?;
        self.fold_angle.check("config.sheet_fold_angle", -turn, turn)?;
        self.fold_width.check("config.sheet_fold_width", 0.01, 100.0)?;
        self.centre.check("config.sheet_centre", -SPAN, SPAN)?;
        self.centre_drift.check("config.sheet_centre_drift", -SPAN, SPAN)?;
        self.axis_rate.check("config.sheet_axis_rate", -turn, turn)?;
        self.relief.check("config.sheet_relief", 0.0, 1.0)?;
        if !(1..=64).contains(&self.phases) {
            return Err(InvalidArgument::new("config.sheet_phases", format!("expected 1 <= phases <= 64, got {}", self.phases)));
        }
        Ok(())
    }

    /// Draw one sheet, or none with probability `1 − probability`.
    pub fn sample(&self, rng: &mut SplitMix64) -> Option<SheetParams> {
        if self.probability == 0.0 || rng.unit() >= self.probability {
            return None;
        }
        let (lo, hi) = self.bends;
        let bends = lo + (rng.next_u64() % (hi - lo + 1) as u64) as usize;
        let fold = rng.unit() < self.fold_probability;
        let mut term = |angle: Range, width: Range| BendTerm {
            angle: vec![rng.uniform(angle.lo, angle.hi), rng.uniform(angle.lo, angle.hi)],
            centre: {
                let c = rng.uniform(self.centre.lo, self.centre.hi);
                vec![c, c + rng.uniform(self.centre_drift.lo, self.centre_drift.hi)]
            },
            width: rng.uniform(width.lo, width.hi),
        };
        let mut terms: Vec<BendTerm> = (0..bends).map(|_| term(self.bend_angle, self.bend_width)).collect();
        if fold {
            terms.push(term(self.fold_angle, self.fold_width));
        }
        let axis = rng.uniform(0.0, std::f64::consts::PI);
        let mut axis = vec![axis, axis + rng.uniform(self.axis_rate.lo, self.axis_rate.hi)];
        let relief = rng.uniform(self.relief.lo, self.relief.hi);
        // Later phases' knots are drawn after everything else, so one phase draws what it always drew.
        for _ in 1..self.phases {
            for (j, term) in terms.iter_mut().enumerate() {
                let range = if j < bends { self.bend_angle } else { self.fold_angle };
                term.angle.push(rng.uniform(range.lo, range.hi));
                let c = term.centre[term.centre.len() - 1];
                term.centre.push((c + rng.uniform(self.centre_drift.lo, self.centre_drift.hi)).clamp(self.centre.lo, self.centre.hi));
            }
            axis.push(axis[axis.len() - 1] + rng.uniform(self.axis_rate.lo, self.axis_rate.hi));
        }
        if self.flat_start {  // after every draw: the same sheet, unbent at the start
            for term in &mut terms {
                term.angle[0] = 0.0;
            }
        }
        Some(SheetParams { axis, terms, relief })
    }
}

/// One term of the curvature profile.
#[derive(Clone, Debug, PartialEq)]
pub struct BendTerm {
    /// Turn A (radians) at the knots t = 0, 1/P, …, 1.
    pub angle: Vec<f64>,
    /// Centre c along s at the knots.
    pub centre: Vec<f64>,
    /// Width w of the curvature Gaussian.
    pub width: f64,
}

/// Everything drawn for one sheet.
#[derive(Clone, Debug, PartialEq)]
pub struct SheetParams {
    /// Axis angle α (radians, in the patch plane from +x) at the knots
    /// t = 0, 1/P, …, 1 (as many as every term's).
    pub axis: Vec<f64>,
    pub terms: Vec<BendTerm>,
    /// Factor on the surface's coloured-noise intensity.
    pub relief: f64,
}

/// The value at time `t` ∈ [0, 1] of knots evenly spaced over [0, 1], linear between them.
fn lerp(knots: &[f64], t: f64) -> f64 {
    let spans = knots.len() - 1;
    let u = t * spans as f64;
    let k = (u.max(0.0) as usize).min(spans - 1);
    let (a, b) = (knots[k], knots[k + 1]);
    a + (u - k as f64) * (b - a)
}

/// The cross-section of one frame, tabulated: θ and C at `s_i = −SPAN + i·step`.
#[derive(Default)]
pub struct Bender {
    /// Curvature k at the samples (kept between frames, so a clip allocates once).
    k: Vec<f64>,
    theta: Vec<f64>,
    cb: Vec<f64>,
    cz: Vec<f64>,
}

impl Bender {
    /// Tabulate the cross-section of `sheet` at time `t`.
    fn tabulate(&mut self, sheet: &SheetParams, t: f64) {
        let step = 2.0 * SPAN / (TABLE - 1) as f64;
        let mid = TABLE / 2;
        let curvature = |s: f64| -> f64 {
            sheet
                .terms
                .iter()
                .map(|term| {
                    let (a, c, w) = (lerp(&term.angle, t), lerp(&term.centre, t), term.width);
                    a * (-0.5 * ((s - c) / w).powi(2)).exp() / (w * (std::f64::consts::TAU).sqrt())
                })
                .sum()
        };
        self.k.clear();
        self.k.extend((0..TABLE).map(|i| curvature(-SPAN + i as f64 * step)));
        let k = &self.k;
        for table in [&mut self.theta, &mut self.cb, &mut self.cz] {
            table.clear();
            table.resize(TABLE, 0.0);
        }
        // Outward from s = 0 in both directions, trapezoid rule on θ, then on (cos θ, sin θ).
        for dir in [1isize, -1] {
            let mut i = mid as isize;
            while (0..TABLE as isize).contains(&(i + dir)) {
                let (p, q) = (i as usize, (i + dir) as usize);
                let ds = dir as f64 * step;
                self.theta[q] = self.theta[p] + 0.5 * ds * (k[p] + k[q]);
                self.cb[q] = self.cb[p] + 0.5 * ds * (self.theta[p].cos() + self.theta[q].cos());
                self.cz[q] = self.cz[p] + 0.5 * ds * (self.theta[p].sin() + self.theta[q].sin());
                i += dir;
            }
        }
    }

    /// (θ, C_b, C_z) at `s`, linearly interpolated (clamped to the table).
    fn at(&self, s: f64) -> (f64, f64, f64) {
        let step = 2.0 * SPAN / (TABLE - 1) as f64;
        let p = ((s + SPAN) / step).clamp(0.0, (TABLE - 1) as f64);
        let i = (p as usize).min(TABLE - 2);
        let f = p - i as f64;
        let mix = |v: &[f64]| v[i] + f * (v[i + 1] - v[i]);
        (mix(&self.theta), mix(&self.cb), mix(&self.cz))
    }

    /// Bend the local positions of one frame in place: each `(x, y, h)`
    /// (in-plane position and relief along the normal) becomes `f(x)` above.
    pub fn bend_frame(&mut self, sheet: &SheetParams, t: f64, positions: &mut [[f64; 3]]) {
        self.tabulate(sheet, t);
        let alpha = lerp(&sheet.axis, t);
        let (a, b) = ([alpha.cos(), alpha.sin()], [-alpha.sin(), alpha.cos()]);
        for p in positions {
            let (u, s, h) = (p[0] * a[0] + p[1] * a[1], p[0] * b[0] + p[1] * b[1], p[2]);
            let (theta, cb, cz) = self.at(s);
            let (nb, nz) = (-theta.sin(), theta.cos());
            let across = cb + h * nb;
            *p = [u * a[0] + across * b[0], u * a[1] + across * b[1], cz + h * nz];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthesis::grid_coordinate;

    fn flat_grid(grid: usize) -> Vec<[f64; 3]> {
        (0..grid * grid).map(|k| [grid_coordinate(k % grid, grid), grid_coordinate(k / grid, grid), 0.0]).collect()
    }

    /// Largest relative change of a mesh edge's length (rows, columns and
    /// diagonals of the grid) between `flat` and `bent`.
    fn stretch(flat: &[[f64; 3]], bent: &[[f64; 3]], grid: usize) -> f64 {
        let len = |v: &[[f64; 3]], i: usize, j: usize| ((0..3).map(|c| (v[i][c] - v[j][c]).powi(2)).sum::<f64>()).sqrt();
        let mut worst: f64 = 0.0;
        for r in 0..grid - 1 {
            for c in 0..grid - 1 {
                let k = r * grid + c;
                for (i, j) in [(k, k + 1), (k, k + grid), (k, k + grid + 1)] {
                    worst = worst.max((len(bent, i, j) / len(flat, i, j) - 1.0).abs());
                }
            }
        }
        worst
    }

    #[test]
    fn bends_and_folds_stretch_the_sheet_by_under_half_a_percent() {
        // The default ranges at the training mesh (64 vertices a side): a mesh
        // edge is the chord of the bent arc, so the bound is the chord's
        // shortening across the narrowest fold, plus the table's rounding.
        let config = SheetConfig { probability: 1.0, fold_probability: 1.0, ..SheetConfig::default() };
        let grid = 64;
        let flat = flat_grid(grid);
        let mut bender = Bender::default();
        let mut worst: f64 = 0.0;
        let mut folded = 0.0f64;
        for seed in 0..64 {
            let sheet = config.sample(&mut SplitMix64::new(seed)).unwrap();
            for t in [0.0, 0.5, 1.0] {
                let mut bent = flat.clone();
                bender.bend_frame(&sheet, t, &mut bent);
                worst = worst.max(stretch(&flat, &bent, grid));
                folded = folded.max(bent.iter().map(|p| p[2].abs()).fold(0.0, f64::max));
            }
        }
        assert!(worst < 5e-3, "stretch {worst}");
        assert!(folded > 0.3, "the sheets barely bend: largest |z| {folded}");
        // Finer meshes converge on the isometry.
        let grid = 257;
        let flat = flat_grid(grid);
        let sheet = config.sample(&mut SplitMix64::new(7)).unwrap();
        let mut bent = flat.clone();
        bender.bend_frame(&sheet, 0.3, &mut bent);
        assert!(stretch(&flat, &bent, grid) < 3e-4);
    }

    #[test]
    fn phases_pass_through_their_knots_and_keep_one_phases_draws() {
        let one = SheetConfig { probability: 1.0, fold_probability: 1.0, ..SheetConfig::default() };
        let four = SheetConfig { phases: 4, ..one.clone() };
        let grid = 64;
        let flat = flat_grid(grid);
        let mut bender = Bender::default();
        for seed in 0..16 {
            let (a, b) = (one.sample(&mut SplitMix64::new(seed)).unwrap(), four.sample(&mut SplitMix64::new(seed)).unwrap());
            // The first phase's knots are one phase's endpoints: later knots are drawn after everything else.
            assert_eq!(b.axis.len(), 5);
            assert_eq!((b.axis[0], b.axis[1], b.relief), (a.axis[0], a.axis[1], a.relief));
            for (p, q) in a.terms.iter().zip(&b.terms) {
                assert_eq!((&q.angle[..2], &q.centre[..2], q.width), (&p.angle[..], &p.centre[..], p.width));
                assert!(q.centre[2..].iter().all(|c| (one.centre.lo..=one.centre.hi).contains(c)));
            }
            // At knot k (t = k/4) the sheet is the one-phase sheet made of knots k and k + 1 at its start.
            for k in 0..4 {
                let span = SheetParams {
                    axis: b.axis[k..k + 2].to_vec(),
                    terms: b.terms.iter().map(|q| BendTerm { angle: q.angle[k..k + 2].to_vec(), centre: q.centre[k..k + 2].to_vec(), width: q.width }).collect(),
                    relief: b.relief,
                };
                for (u, t) in [(0.0, k as f64 / 4.0), (0.5, (k as f64 + 0.5) / 4.0)] {
                    let (mut p, mut q) = (flat.clone(), flat.clone());
                    bender.bend_frame(&span, u, &mut p);
                    bender.bend_frame(&b, t, &mut q);
                    let gap = p.iter().zip(&q).flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs())).fold(0.0, f64::max);
                    assert!(gap < 1e-12, "seed {seed} knot {k} at {u}: {gap}");
                    assert!(stretch(&flat, &q, grid) < 5e-3);
                }
            }
        }
        assert_eq!(SheetConfig { phases: 0, ..one }.validate().unwrap_err().name, "config.sheet_phases");
    }

    #[test]
    fn a_flat_start_unbends_only_the_first_knot() {
        let bent = SheetConfig { probability: 1.0, fold_probability: 1.0, phases: 3, ..SheetConfig::default() };
        let flat_start = SheetConfig { flat_start: true, ..bent.clone() };
        let flat = flat_grid(16);
        let mut bender = Bender::default();
        for seed in 0..16 {
            let (a, b) = (bent.sample(&mut SplitMix64::new(seed)).unwrap(), flat_start.sample(&mut SplitMix64::new(seed)).unwrap());
            assert_eq!((&a.axis, a.relief, a.terms.len()), (&b.axis, b.relief, b.terms.len()));
            for (p, q) in a.terms.iter().zip(&b.terms) {
                assert_eq!((&p.angle[1..], &p.centre, p.width, q.angle[0]), (&q.angle[1..], &q.centre, q.width, 0.0));
            }
            let mut start = flat.clone();
            bender.bend_frame(&b, 0.0, &mut start);
            assert!(start.iter().zip(&flat).all(|(p, q)| (0..3).all(|c| (p[c] - q[c]).abs() < 1e-9)), "seed {seed}: not flat at t = 0");
        }
    }

    #[test]
    fn a_constant_curvature_rolls_the_sheet_onto_a_circle() {
        // One very wide term: curvature A/(w√2π) nearly constant over the patch.
        let (angle, width) = (1.0, 40.0);
        let sheet = SheetParams { axis: vec![0.3, 0.3], terms: vec![BendTerm { angle: vec![angle; 2], centre: vec![0.0; 2], width }], relief: 0.0 };
        let k = angle / (width * std::f64::consts::TAU.sqrt());
        let radius = 1.0 / k;
        let mut points = flat_grid(9);
        Bender::default().bend_frame(&sheet, 0.0, &mut points);
        for p in &points {
            // Distance from the axis line through (0, 0, radius), along a = (cos α, sin α, 0).
            let a = [0.3f64.cos(), 0.3f64.sin()];
            let u = p[0] * a[0] + p[1] * a[1];
            let d = [p[0] - u * a[0], p[1] - u * a[1], p[2] - radius];
            let distance = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            assert!((distance - radius).abs() < 1e-4 * radius, "{distance} vs {radius}");
        }
    }

    #[test]
    fn relief_is_carried_along_the_normal_and_no_sheet_is_drawn_at_probability_zero() {
        let sheet = SheetConfig { probability: 1.0, ..SheetConfig::default() }.sample(&mut SplitMix64::new(3)).unwrap();
        let mut bender = Bender::default();
        let mut base = vec![[0.2, -0.4, 0.0]];
        let mut lifted = vec![[0.2, -0.4, 0.05]];
        bender.bend_frame(&sheet, 0.5, &mut base);
        bender.bend_frame(&sheet, 0.5, &mut lifted);
        let d: f64 = (0..3).map(|c| (lifted[0][c] - base[0][c]).powi(2)).sum::<f64>().sqrt();
        assert!((d - 0.05).abs() < 1e-12);
        let mut rng = SplitMix64::new(1);
        assert!(SheetConfig::default().sample(&mut rng).is_none());
        assert_eq!(rng.next_u64(), SplitMix64::new(1).next_u64(), "probability 0 must draw nothing");
    }

    #[test]
    fn bad_config_is_named() {
        let mut c = SheetConfig { probability: 1.5, ..SheetConfig::default() };
        assert_eq!(c.validate().unwrap_err().name, "config.sheet_probability");
        c = SheetConfig { fold_width: Range::new(0.0, 0.1), ..SheetConfig::default() };
        assert_eq!(c.validate().unwrap_err().name, "config.sheet_fold_width[0]");
        c = SheetConfig { bends: (3, 1), ..SheetConfig::default() };
        assert_eq!(c.validate().unwrap_err().name, "config.sheet_bends");
    }
}
