//! Surface parameters of the paper's deformation model (eq. vdm_Fourier) and
//! the ranges they are drawn from.
//!
//! Units: lengths in half-widths of the undeformed patch (the patch is the
//! bi-unit square [-1, 1]²), spatial frequencies in cycles per unit length,
//! angles in radians, time `t` in clip durations (t = 0 at the first frame,
//! t = 1 at the last). See `synthesis.rs` for how each parameter enters.

use crate::error::{in_range, InvalidArgument, Result};
use crate::rng::SplitMix64;

/// Every parameter of one deforming surface, named as the paper names it.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceParams {
    /// κ, *intensity*: RMS of each displacement channel before the constraint
    /// envelope and the folding factor. [0, 1].
    pub intensity: f64,
    /// ν, *constraint*: spatial envelope `G_ν(x) = exp(-ν|x|²)` anchoring the border. [0, 50].
    pub constraint: f64,
    /// ζ, *folding*: factor on the two in-plane displacement channels. [0, 2].
    pub folding: f64,
    /// ξ, *flexibility*: standard deviation, in cycles per unit, of the radial
    /// Gaussian `G_ξ(u) = exp(-|u|²/(2ξ²))`. [0.001, 16].
    pub flexibility: f64,
    /// Σ, *orientation*: `(Σxx, Σxy, Σyy)` of the SPD matrix in `G_Σ(u) = exp(-uᵀΣu)`.
    pub orientation: [f64; 3],
    /// Speed scale of each channel (dx, dy, dz) in radians per clip; the speed
    /// of frequency u is `φ_i(u) = speeds[i] · ρ_i(u)` with ρ_i ~ U[0.5, 1.5].
    pub speeds: [f64; 3],
    /// Seed of the per-frequency random functions: initial phases θ_i(u),
    /// spatial phases ψ_i(u) and speed factors ρ_i(u).
    pub phase_seed: u64,
    /// Rigid motion E_t: rotation vector at t = 0 (radians, axis × angle).
    pub rotation: [f64; 3],
    /// Rigid motion E_t: change of the rotation vector over the clip (radians per clip).
    pub rotation_rate: [f64; 3],
    /// Rigid motion E_t: translation over the clip (units per clip); zero at t = 0.
    pub drift: [f64; 3],
}

impl SurfaceParams {
    /// Check every field against its documented domain.
    pub fn validate(&self) -> Result<()> {
        in_range("params.intensity", self.intensity, 0.0, 1.0)?;
        in_range("params.constraint", self.constraint, 0.0, 50.0)?;
        in_range("params.folding", self.folding, 0.0, 2.0)?;
        in_range("params.flexibility", self.flexibility, 1e-3, 16.0)?;
        let [sxx, sxy, syy] = self.orientation;
        for v in self.orientation {
            in_range("params.orientation", v, -100.0, 100.0)?;
        }
        if !(sxx > 0.0 && sxx * syy - sxy * sxy > 0.0) {
            return Err(InvalidArgument::new(
                "params.orientation",
                format!("expected (Σxx, Σxy, Σyy) of a symmetric positive definite matrix, got ({sxx}, {sxy}, {syy})"),
            ));
        }
        for v in self.speeds {
            in_range("params.speeds", v, -1000.0, 1000.0)?;
        }
        let two_pi = std::f64::consts::TAU;
        for v in self.rotation {
            in_range("params.rotation", v, -two_pi, two_pi)?;
        }
        for v in self.rotation_rate {
            in_range("params.rotation_rate", v, -two_pi, two_pi)?;
        }
        for v in self.drift {
            in_range("params.drift", v, -10.0, 10.0)?;
        }
        Ok(())
    }

    /// Σ as a matrix.
    pub fn sigma(&self) -> [[f64; 2]; 2] {
        let [sxx, sxy, syy] = self.orientation;
        [[sxx, sxy], [sxy, syy]]
    }
}

/// A closed interval to draw a parameter from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub lo: f64,
    pub hi: f64,
}

impl Range {
    pub const fn new(lo: f64, hi: f64) -> Self {
        Self { lo, hi }
    }

    /// Both ends inside [lo, hi] and ordered; errors name `name[0]`, `name[1]` or `name`.
    pub(crate) fn check(&self, name: &str, lo: f64, hi: f64) -> Result<()> {
        in_range(&format!("{name}[0]"), self.lo, lo, hi)?;
        in_range(&format!("{name}[1]"), self.hi, lo, hi)?;
        if self.lo > self.hi {
            return Err(InvalidArgument::new(name, format!("expected lo <= hi, got ({}, {})", self.lo, self.hi)));
        }
        Ok(())
    }
}

/// The ranges `sample` draws a `SurfaceParams` from (uniform unless noted).
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceConfig {
    pub intensity: Range,
    pub constraint: Range,
    pub folding: Range,
    pub flexibility: Range,
    /// Eigenvalues of Σ, drawn log-uniformly and independently; the
    /// eigenvector angle is uniform in [0, π).
    pub orientation_eigenvalues: Range,
    /// Per-channel speed scale (radians per clip).
    pub speed: Range,
    /// Initial rotation about the x and y axes (out-of-plane tilt).
    pub tilt: Range,
    /// Initial rotation about the z axis (in-plane spin).
    pub spin: Range,
    /// Change of tilt over the clip.
    pub tilt_rate: Range,
    /// Change of spin over the clip.
    pub spin_rate: Range,
    /// In-plane drift over the clip (x and y).
    pub drift_xy: Range,
    /// Drift along the optical axis over the clip.
    pub drift_z: Range,
}

impl Default for SurfaceConfig {
    fn default() -> Self {
        Self {
            intensity: Range::new(0.03, 0.12),
            constraint: Range::new(0.0, 2.0),
            folding: Range::new(0.05, 0.5),
            flexibility: Range::new(0.3, 1.5),
            orientation_eigenvalues: Range::new(0.02, 1.0),
            speed: Range::new(0.5, 4.0),
            tilt: Range::new(-0.2, 0.2),
            spin: Range::new(-std::f64::consts::PI, std::f64::consts::PI),
            tilt_rate: Range::new(-0.2, 0.2),
            spin_rate: Range::new(-0.3, 0.3),
            drift_xy: Range::new(-0.1, 0.1),
            drift_z: Range::new(-0.1, 0.1),
        }
    }
}

impl SurfaceConfig {
    /// Every range must be ordered and inside the domain of the parameter it feeds.
    pub fn validate(&self) -> Result<()> {
        let two_pi = std::f64::consts::TAU;
        self.intensity.check("config.intensity", 0.0, 1.0)?;
        self.constraint.check("config.constraint", 0.0, 50.0)?;
        self.folding.check("config.folding", 0.0, 2.0)?;
        self.flexibility.check("config.flexibility", 1e-3, 16.0)?;
        self.orientation_eigenvalues.check("config.orientation_eigenvalues", 1e-4, 100.0)?;
        self.speed.check("config.speed", -1000.0, 1000.0)?;
        self.tilt.check("config.tilt", -two_pi, two_pi)?;
        self.spin.check("config.spin", -two_pi, two_pi)?;
        self.tilt_rate.check("config.tilt_rate", -two_pi, two_pi)?;
        self.spin_rate.check("config.spin_rate", -two_pi, two_pi)?;
        self.drift_xy.check("config.drift_xy", -10.0, 10.0)?;
        self.drift_z.check("config.drift_z", -10.0, 10.0)?;
        Ok(())
    }

    /// Draw one parameter set; a pure function of (self, seed).
    pub fn sample(&self, seed: u64) -> Result<SurfaceParams> {
        self.validate()?;
        let mut rng = SplitMix64::new(seed);
        let mut draw = |r: Range| rng.uniform(r.lo, r.hi);
        let intensity = draw(self.intensity);
        let constraint = draw(self.constraint);
        let folding = draw(self.folding);
        let flexibility = draw(self.flexibility);
        let angle = draw(Range::new(0.0, std::f64::consts::PI));
        let speeds = [draw(self.speed), draw(self.speed), draw(self.speed)];
        let rotation = [draw(self.tilt), draw(self.tilt), draw(self.spin)];
        let rotation_rate = [draw(self.tilt_rate), draw(self.tilt_rate), draw(self.spin_rate)];
        let drift = [draw(self.drift_xy), draw(self.drift_xy), draw(self.drift_z)];
        let e = self.orientation_eigenvalues;
        let (l1, l2) = (rng.log_uniform(e.lo, e.hi), rng.log_uniform(e.lo, e.hi));
        let phase_seed = rng.next_u64();
        let (c, s) = (angle.cos(), angle.sin());
        let orientation = [l1 * c * c + l2 * s * s, (l1 - l2) * c * s, l1 * s * s + l2 * c * c];
        let params = SurfaceParams {
            intensity,
            constraint,
            folding,
            flexibility,
            orientation,
            speeds,
            phase_seed,
            rotation,
            rotation_rate,
            drift,
        };
        params.validate()?;
        Ok(params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_lie_in_their_ranges_and_depend_on_the_seed() {
        let cfg = SurfaceConfig::default();
        for seed in 0..200 {
            let p = cfg.sample(seed).unwrap();
            assert!((cfg.intensity.lo..=cfg.intensity.hi).contains(&p.intensity));
            assert!((cfg.flexibility.lo..=cfg.flexibility.hi).contains(&p.flexibility));
            assert!(p.validate().is_ok());
            assert_eq!(p, cfg.sample(seed).unwrap());
            assert_ne!(p, cfg.sample(seed + 1).unwrap());
        }
    }

    #[test]
    fn bad_config_and_params_name_the_field() {
        let mut cfg = SurfaceConfig::default();
        cfg.flexibility = Range::new(2.0, 1.0);
        assert_eq!(cfg.sample(0).unwrap_err().name, "config.flexibility");
        let mut p = SurfaceConfig::default().sample(0).unwrap();
        p.orientation = [1.0, 2.0, 1.0];
        assert_eq!(p.validate().unwrap_err().name, "params.orientation");
        p = SurfaceConfig::default().sample(0).unwrap();
        p.intensity = f64::NAN;
        assert_eq!(p.validate().unwrap_err().name, "params.intensity");
    }
}
