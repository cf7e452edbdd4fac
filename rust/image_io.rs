//! Image files: atomic PNG writing (write to a temporary name, then rename, so
//! an interrupted run never leaves a truncated picture).

use std::path::Path;

use crate::error::{InvalidArgument, Result};

/// Write an 8-bit RGB image of `height × width` (row-major, 3 bytes a pixel) as PNG.
pub fn write_png_rgb(path: &Path, rgb: &[u8], height: usize, width: usize) -> Result<()> {
    if height == 0 || width == 0 || rgb.len() != height * width * 3 {
        return Err(InvalidArgument::new("image", format!("expected {height}×{width}×3 bytes, got {}", rgb.len())));
    }
    let tmp = path.with_extension("png.partial");
    let io_err = |e: &dyn std::fmt::Display| InvalidArgument::new("path", format!("cannot write {}: {e}", path.display()));
    image::save_buffer_with_format(&tmp, rgb, width as u32, height as u32, image::ColorType::Rgb8, image::ImageFormat::Png)
        .map_err(|e| io_err(&e))?;
    std::fs::rename(&tmp, path).map_err(|e| io_err(&e))
}
