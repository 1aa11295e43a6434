//! The bytes of the image outputs: PNG (with the supersampled still's reduction) and
//! depth (EXR or 16-bit PNG).

use dispmap::error::{Error, Result};
use std::path::Path;

use super::checks::{check_extension, extension};
use super::{Format, write_atomic};

/// An sRGB-encoded RGBA8 image of `size` pixels reduced by `k` in each direction: each
/// `k x k` block averaged in linear light (alpha linearly), rounded to the nearest
/// sRGB value. The anti-aliased still of `render --samples` (`size` a multiple of `k`).
pub fn downsample_srgb(rgba: &[u8], size: [usize; 2], k: usize) -> Vec<u8> {
    let to_linear = |c: u8| {
        let c = f64::from(c) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let to_srgb = |l: f64| {
        let c = if l <= 0.003_130_8 {
            l * 12.92
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        };
        (c * 255.0).round().clamp(0.0, 255.0) as u8
    };
    let k = k.max(1);
    let (w, h) = (size[0] / k, size[1] / k);
    let n = (k * k) as f64;
    let mut out = Vec::with_capacity(w * h * 4);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 4];
            for sy in 0..k {
                for sx in 0..k {
                    let i = 4 * ((y * k + sy) * size[0] + x * k + sx);
                    for (c, s) in sum.iter_mut().enumerate() {
                        let v = rgba[i + c];
                        *s += if c < 3 {
                            to_linear(v)
                        } else {
                            f64::from(v) / 255.0
                        };
                    }
                }
            }
            for (c, s) in sum.iter().enumerate() {
                let m = s / n;
                out.push(if c < 3 {
                    to_srgb(m)
                } else {
                    (m * 255.0).round() as u8
                });
            }
        }
    }
    out
}

/// Encodes an RGBA8 image as PNG; `path` names it in errors.
pub fn png_bytes(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>> {
    let mut encoded = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut encoded),
        rgba,
        width,
        height,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::Image {
        path: path.to_owned(),
        message: format!("cannot encode PNG: {e}"),
    })?;
    Ok(encoded)
}

/// Encodes an RGBA8 image as PNG and writes it atomically.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    write_atomic(path, &png_bytes(path, width, height, rgba)?)
}

/// Encodes a depth image (one `f32` per pixel, row by row) by the extension of `path`:
/// `.exr`, OpenEXR with 32-bit float RGB channels all holding the exact value (image's
/// EXR encoder has no single-channel mode); `.png`, 16-bit greyscale with
/// `round(clamp(depth, 0, 1) * 65535)` (quantised); a name without either (`-`, a
/// device) as OpenEXR. Any other extension is an error naming the path.
pub fn depth_bytes(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<Vec<u8>> {
    let ext = extension(path);
    let err = |message: String| Error::Image {
        path: path.to_owned(),
        message,
    };
    check_extension(path, Format::Depth)?;
    let (bytes, color, format) = match ext.as_deref() {
        Some("png") => {
            let grey: Vec<u16> = depth
                .iter()
                .map(|&d| (d.clamp(0.0, 1.0) * 65535.0).round() as u16)
                .collect();
            (
                bytemuck::cast_slice::<u16, u8>(&grey).to_vec(),
                image::ExtendedColorType::L16,
                image::ImageFormat::Png,
            )
        }
        _ => {
            let rgb: Vec<f32> = depth.iter().flat_map(|&d| [d, d, d]).collect();
            (
                bytemuck::cast_slice::<f32, u8>(&rgb).to_vec(),
                image::ExtendedColorType::Rgb32F,
                image::ImageFormat::OpenExr,
            )
        }
    };
    let mut encoded = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut encoded),
        &bytes,
        width,
        height,
        color,
        format,
    )
    .map_err(|e| err(format!("cannot encode the depth image: {e}")))?;
    Ok(encoded)
}

/// Writes a depth image atomically, encoded as [`depth_bytes`] says; nothing is written
/// for an unknown extension.
pub fn write_depth(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<()> {
    write_atomic(path, &depth_bytes(path, width, height, depth)?)
}
