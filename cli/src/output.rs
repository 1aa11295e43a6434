//! Writing result files without ever leaving a partial one: everything is written to a
//! temporary file next to the target and renamed over it only when complete.

use dispmap::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Fails early (before any rendering) if `path`'s folder does not exist or `path` is a folder.
pub fn check_writable(path: &Path) -> Result<()> {
    let parent = parent_of(path);
    if !parent.is_dir() {
        return Err(Error::Io {
            path: path.to_owned(),
            source: std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("folder {} does not exist", parent.display()),
            ),
        });
    }
    if path.is_dir() {
        return Err(Error::Io {
            path: path.to_owned(),
            source: std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a folder"),
        });
    }
    Ok(())
}

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let tmp = parent_of(path).join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

/// Encodes an RGBA8 image as PNG and writes it atomically.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
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
    write_atomic(path, &encoded)
}

/// Writes a depth image (one `f32` per pixel, row by row) atomically, encoded by the
/// extension of `path`: `.exr`, OpenEXR with 32-bit float RGB channels all holding the
/// exact value (image's EXR encoder has no single-channel mode); `.png`, 16-bit greyscale
/// with `round(clamp(depth, 0, 1) * 65535)` (quantised). Any other extension is an error
/// naming the path; nothing is written then.
pub fn write_depth(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<()> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let err = |message: String| Error::Image {
        path: path.to_owned(),
        message,
    };
    let (bytes, color, format) = match ext.as_deref() {
        Some("exr") => {
            let rgb: Vec<f32> = depth.iter().flat_map(|&d| [d, d, d]).collect();
            (
                bytemuck::cast_slice::<f32, u8>(&rgb).to_vec(),
                image::ExtendedColorType::Rgb32F,
                image::ImageFormat::OpenExr,
            )
        }
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
            return Err(err(
                "unknown depth format: use .exr (32-bit float) or .png (16-bit)".into(),
            ));
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
    write_atomic(path, &encoded)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_partial_file_on_failure() {
        let missing = Path::new("/nonexistent-dir/x.png");
        assert!(check_writable(missing).is_err());
        assert!(write_png(missing, 1, 1, &[0, 0, 0, 255]).is_err());
        let dir = std::env::temp_dir().join("dispmap-output-test");
        std::fs::create_dir_all(&dir).unwrap();
        let ok = dir.join("ok.png");
        write_png(&ok, 1, 1, &[1, 2, 3, 255]).unwrap();
        let back = image::open(&ok).unwrap().to_rgba8();
        assert_eq!(back.get_pixel(0, 0).0, [1, 2, 3, 255]);
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty());
    }

    #[test]
    fn depth_round_trips() {
        let dir = std::env::temp_dir().join("dispmap-output-depth-test");
        std::fs::create_dir_all(&dir).unwrap();
        let depth = [0.0f32, 1.0, 0.123_456_79, 3.0e-5, 0.5, 0.75];
        let exr = dir.join("d.exr");
        write_depth(&exr, 3, 2, &depth).unwrap();
        let back = image::open(&exr).unwrap().to_rgb32f();
        let red: Vec<f32> = back.pixels().map(|p| p.0[0]).collect();
        assert_eq!(red, depth);
        let png = dir.join("d.png");
        write_depth(&png, 3, 2, &depth).unwrap();
        let back = image::open(&png).unwrap().to_luma16();
        let grey: Vec<u16> = back.pixels().map(|p| p.0[0]).collect();
        assert_eq!(grey, [0, 65535, 8091, 2, 32768, 49151]);
        let bad = dir.join("d.tif");
        assert!(write_depth(&bad, 3, 2, &depth).is_err());
        assert!(!bad.exists());
    }
}
