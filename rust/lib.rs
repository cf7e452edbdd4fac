//! nrdepth core: per-pixel and per-triangle work of the nrdepth pipeline.
//!
//! One module per stage, usable from Rust without Python; `python` (behind the
//! `python` cargo feature) is the only place pyo3 appears.

pub mod backdrop;
pub mod bvh;
pub mod error;
pub mod generate;
pub mod geometry;
pub mod image_io;
mod lanes;
pub mod mesh;
pub mod params;
pub mod raster;
pub mod rng;
pub mod sheet;
pub mod spread;
pub mod joint;
pub mod stitch;
pub mod synthesis;
pub mod textures;

#[cfg(feature = "python")]
mod python;

pub use error::InvalidArgument;
pub use params::{Range, SurfaceConfig, SurfaceParams};
pub use synthesis::{synthesize, synthesize_batch, Synthesizer};
