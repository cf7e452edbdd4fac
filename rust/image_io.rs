//! Image files: atomic PNG writing (write to a temporary name, then rename, so
//! an interrupted run never leaves a truncated picture). 8-bit RGB for
//! pictures, 16-bit grayscale for depth maps (row-major, native `u16`s; the
//! PNG itself is big-endian as the format requires).

use std::path::Path;

use crate::error::{InvalidArgument, Result};

/// Write an 8-bit RGB image of `height × width` (row-major, 3 bytes a pixel) as PNG.
pub fn write_png_rgb(path: &Path, rgb: &[u8], height: usize, width: usize) -> Result<()> {
    if height == 0 || width == 0 || rgb.len() != height * width * 3 {
        return Err(InvalidArgument::new("image", format!("expected {height}×{width}×3 bytes, got {}", rgb.len())));
    }
    let image = image::RgbImage::from_raw(width as u32, height as u32, rgb.to_vec());
    save_atomic(path, image.map(image::DynamicImage::from))
}

/// Write a 16-bit grayscale image of `height × width` (row-major) as PNG.
pub fn write_png_gray16(path: &Path, gray: &[u16], height: usize, width: usize) -> Result<()> {
    if height == 0 || width == 0 || gray.len() != height * width {
        return Err(InvalidArgument::new("image", format!("expected {height}×{width} values, got {}", gray.len())));
    }
    let image = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(width as u32, height as u32, gray.to_vec());
    save_atomic(path, image.map(image::DynamicImage::from))
}

fn save_atomic(path: &Path, image: Option<image::DynamicImage>) -> Result<()> {
    let image = image.ok_or_else(|| InvalidArgument::new("image", "size does not match the pixel count"))?;
    let tmp = path.with_extension("png.partial");
    let io_err = |e: &dyn std::fmt::Display| InvalidArgument::new("path", format!("cannot write {}: {e}", path.display()));
    image.save_with_format(&tmp, image::ImageFormat::Png).map_err(|e| io_err(&e))?;
    std::fs::rename(&tmp, path).map_err(|e| io_err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray16_round_trips_every_bit() {
        let dir = std::env::temp_dir().join(format!("nrdepth-png16-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("depth.png");
        let values: Vec<u16> = (0..6 * 7).map(|i| (i as u16).wrapping_mul(1571) ^ 0x8001).collect();
        write_png_gray16(&path, &values, 6, 7).unwrap();
        let back = image::open(&path).unwrap().into_luma16();
        assert_eq!(back.dimensions(), (7, 6));
        assert_eq!(back.into_raw(), values);
        assert!(!path.with_extension("png.partial").exists());
        assert!(write_png_gray16(&path, &values, 7, 7).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
