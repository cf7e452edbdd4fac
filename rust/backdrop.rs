//! Backdrops: views wider than the sheet, which show its border and what
//! lies behind it.
//!
//! A real frame of a held sheet shows its edges and a background, and a
//! real video's coarse pass sees the whole frame; the plain generator's
//! window always lies inside the patch. A backdrop clip draws a wider window
//! (world units; the patch is 2 wide) and a static background: a flat
//! intensity, or a procedural texture of the clip's families at one texel
//! per pixel, scaled by a drawn brightness (a fronto-parallel plane behind
//! the sheet, evenly lit, seen by the orthographic camera). The renderer
//! counts background subsamples as 0 and reports each pixel's coverage, so
//! compositing `image + (1 − coverage) · background` anti-aliases the border
//! exactly. The depth stays the sheet's: NaN at pixel centres off the sheet
//! (the mask a loss and a metric use); a clip is redrawn until every frame
//! has at least `min_cover` of its pixel centres on the sheet.

use crate::error::{in_range, Result};
use crate::params::Range;
use crate::raster::Texture;
use crate::rng::SplitMix64;
use crate::textures::{procedural, TextureFamily};

/// The ranges a clip's backdrop is drawn from (uniform).
#[derive(Clone, Debug, PartialEq)]
pub struct BackdropConfig {
    /// Share of clips that show the sheet's border and a background; 0 draws
    /// nothing, so clips stay as they were.
    pub probability: f64,
    /// Side of a backdrop clip's view window (the plain clip's is drawn and
    /// replaced).
    pub window_width: Range,
    /// Offset of its centre from the patch centre, x and y each.
    pub window_offset: Range,
    /// Least share of each frame's pixel centres on the sheet.
    pub min_cover: f64,
    /// Intensity of a flat background, or factor on a textured one.
    pub brightness: Range,
    /// Probability that the background is flat rather than textured.
    pub flat_probability: f64,
}

impl Default for BackdropConfig {
    fn default() -> Self {
        Self {
            probability: 0.0,
            window_width: Range::new(1.4, 2.8),
            window_offset: Range::new(-0.6, 0.6),
            min_cover: 0.3,
            brightness: Range::new(0.05, 0.9),
            flat_probability: 0.3,
        }
    }
}

/// What was drawn for one backdrop clip.
#[derive(Clone, Debug, PartialEq)]
pub struct BackdropParams {
    /// The view window (x0, y0, x1, y1), world units.
    pub window: [f32; 4],
    /// The background's texture (family, seed), or `None` for a flat one.
    pub texture: Option<(TextureFamily, u64)>,
    pub brightness: f64,
}

impl BackdropConfig {
    pub fn validate(&self) -> Result<()> {
        in_range("config.backdrop_probability", self.probability, 0.0, 1.0)?;
        self.window_width.check("config.backdrop_window_width", 1e-3, 8.0)?;
        self.window_offset.check("config.backdrop_window_offset", -4.0, 4.0)?;
        in_range("config.backdrop_min_cover", self.min_cover, 0.0, 1.0)?;
        self.brightness.check("config.backdrop_brightness", 0.0, 1.0)?;
        in_range("config.backdrop_flat_probability", self.flat_probability, 0.0, 1.0)?;
        Ok(())
    }

    /// Draw one backdrop from `families`, or none with probability `1 − probability`.
    pub fn sample(&self, families: &[TextureFamily], rng: &mut SplitMix64) -> Option<BackdropParams> {
        if self.probability == 0.0 || rng.unit() >= self.probability {
            return None;
        }
        let width = rng.uniform(self.window_width.lo, self.window_width.hi);
        let (cx, cy) = (rng.uniform(self.window_offset.lo, self.window_offset.hi), rng.uniform(self.window_offset.lo, self.window_offset.hi));
        let half = width / 2.0;
        let window = [(cx - half) as f32, (cy - half) as f32, (cx + half) as f32, (cy + half) as f32];
        let flat = rng.unit() < self.flat_probability;
        let family = families[(rng.next_u64() % families.len() as u64) as usize];
        let seed = rng.next_u64();
        let brightness = rng.uniform(self.brightness.lo, self.brightness.hi);
        Some(BackdropParams { window, texture: (!flat).then_some((family, seed)), brightness })
    }
}

impl BackdropParams {
    /// The background of a `size`² frame into `out` (row-major); `texture` is scratch.
    pub fn background_into(&self, size: usize, texture: &mut Texture, out: &mut Vec<f32>) {
        out.clear();
        match self.texture {
            None => out.resize(size * size, self.brightness as f32),
            Some((family, seed)) => {
                procedural(family, seed, size, texture);
                out.extend((0..size).flat_map(|r| texture.row(r).iter().map(|&v| v * self.brightness as f32)));
            }
        }
    }
}

/// `image += (1 − coverage) · background`, pixel by pixel: the background
/// behind a frame whose uncovered subsamples the renderer counted as 0.
pub fn composite(image: &mut [f32], coverage: &[f32], background: &[f32]) {
    for ((pixel, &covered), &behind) in image.iter_mut().zip(coverage).zip(background) {
        *pixel += (1.0 - covered) * behind;
    }
}

/// Whether at least `min_cover` of a frame's pixel centres lie on the sheet
/// (finite depth).
pub fn covers(depth: &[f32], min_cover: f64) -> bool {
    let on_sheet = depth.iter().filter(|d| d.is_finite()).count();
    on_sheet > 0 && on_sheet as f64 >= min_cover * depth.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::textures::FAMILIES;

    #[test]
    fn probability_zero_draws_nothing_and_one_draws_inside_the_ranges() {
        let mut rng = SplitMix64::new(3);
        let before = rng.clone().next_u64();
        assert_eq!(BackdropConfig::default().sample(&FAMILIES, &mut rng), None);
        assert_eq!(rng.next_u64(), before, "no draw at probability 0");
        let config = BackdropConfig { probability: 1.0, flat_probability: 0.5, ..BackdropConfig::default() };
        let (mut flat, mut textured) = (0, 0);
        for seed in 0..200 {
            let b = config.sample(&FAMILIES, &mut SplitMix64::new(seed)).unwrap();
            let width = (b.window[2] - b.window[0]) as f64;
            assert!((config.window_width.lo - 1e-6..=config.window_width.hi + 1e-6).contains(&width));
            assert!((b.window[3] - b.window[1] - b.window[2] + b.window[0]).abs() < 1e-6, "square");
            assert!((config.brightness.lo..=config.brightness.hi).contains(&b.brightness));
            if b.texture.is_some() { textured += 1 } else { flat += 1 }
        }
        assert!(flat > 60 && textured > 60, "flat {flat}, textured {textured}");
    }

    #[test]
    fn composite_fills_exactly_the_uncovered_share() {
        let coverage = [1.0, 0.0, 0.25, 0.5];
        let mut image = [0.7, 0.0, 0.1, 0.2];
        composite(&mut image, &coverage, &[0.4; 4]);
        assert_eq!(image, [0.7, 0.4, 0.1 + 0.75 * 0.4, 0.2 + 0.5 * 0.4]);
    }

    #[test]
    fn a_background_is_flat_or_the_scaled_texture() {
        let (mut texture, mut out) = (Texture::default(), Vec::new());
        BackdropParams { window: [0.0; 4], texture: None, brightness: 0.3 }.background_into(8, &mut texture, &mut out);
        assert_eq!(out, vec![0.3f32; 64]);
        let textured = BackdropParams { window: [0.0; 4], texture: Some((TextureFamily::Stripes, 5)), brightness: 0.5 };
        textured.background_into(16, &mut texture, &mut out);
        let mut plain = Texture::default();
        procedural(TextureFamily::Stripes, 5, 16, &mut plain);
        let expected: Vec<f32> = plain.to_vec().iter().map(|v| v * 0.5).collect();
        assert_eq!(out, expected);
    }

    #[test]
    fn cover_counts_finite_depths() {
        let depth = [1.0, f32::NAN, 2.0, f32::NAN];
        assert!(covers(&depth, 0.5));
        assert!(!covers(&depth, 0.51));
        assert!(!covers(&[f32::NAN; 4], 0.0), "an empty frame never covers");
    }

    #[test]
    fn a_bad_config_is_named() {
        let bad = BackdropConfig { min_cover: 1.5, ..BackdropConfig::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("config.backdrop_min_cover"));
        let bad = BackdropConfig { window_width: Range::new(2.0, 1.0), ..BackdropConfig::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("config.backdrop_window_width"));
    }
}
