//! Writing result files without ever leaving a partial one: everything is written to a
//! temporary file next to the target and renamed over it only when complete.

use dispmap::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// What an output path names, with symlinks followed: where the bytes go and how.
enum Target {
    /// A regular file (or nothing yet): written to a temporary file beside it and renamed
    /// over it, so a failed run leaves the old file (or none); `mode`: the permissions of
    /// the file replaced, kept.
    Replace {
        path: PathBuf,
        mode: Option<std::fs::Permissions>,
    },
    /// Not a regular file (a device such as `/dev/null`, a FIFO, `/dev/stdout`): opened
    /// and written through, never replaced.
    WriteThrough(PathBuf),
}

fn io_error(path: &Path, kind: std::io::ErrorKind, message: impl Into<String>) -> Error {
    Error::Io {
        path: path.to_owned(),
        source: std::io::Error::new(kind, message.into()),
    }
}

/// Where `path` leads (a symlink to its target) and how it is written; an error for a
/// folder, a missing folder or a read-only file (which is not replaced).
fn target_of(path: &Path) -> Result<Target> {
    if path == Path::new("-") {
        return Ok(Target::WriteThrough(PathBuf::from("/dev/stdout")));
    }
    let resolved = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path).unwrap_or_else(|_| {
            // A dangling link: its target (relative to the link's folder) is created.
            match std::fs::read_link(path) {
                Ok(t) if t.is_absolute() => t,
                Ok(t) => parent_of(path).join(t),
                Err(_) => path.to_owned(),
            }
        }),
        _ => path.to_owned(),
    };
    match std::fs::metadata(&resolved) {
        Ok(m) if m.is_dir() => Err(io_error(
            path,
            std::io::ErrorKind::IsADirectory,
            "is a folder",
        )),
        Ok(m) if m.is_file() => {
            if m.permissions().readonly() {
                return Err(io_error(
                    path,
                    std::io::ErrorKind::PermissionDenied,
                    "is read-only (not replaced)",
                ));
            }
            check_folder(path, &resolved)?;
            Ok(Target::Replace {
                path: resolved,
                mode: Some(m.permissions()),
            })
        }
        Ok(_) => Ok(Target::WriteThrough(resolved)),
        Err(_) => {
            check_folder(path, &resolved)?;
            Ok(Target::Replace {
                path: resolved,
                mode: None,
            })
        }
    }
}

fn check_folder(path: &Path, resolved: &Path) -> Result<()> {
    let parent = parent_of(resolved);
    if !parent.is_dir() {
        return Err(io_error(
            path,
            std::io::ErrorKind::NotFound,
            format!("folder {} does not exist", parent.display()),
        ));
    }
    Ok(())
}

/// Checks, before any work, that `path` can take an output: its folder exists, it is not
/// a folder and not a read-only file; `-` is standard output. A symlink is followed (its target is written,
/// the link kept); a device or FIFO is written through (`/dev/null` discards).
pub fn check_writable(path: &Path) -> Result<()> {
    target_of(path).map(|_| ())
}

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// Writes `bytes` to `path`: a regular file (or a new one) through a temporary file in
/// the same folder renamed over it (atomic: a failed or interrupted run leaves the old
/// file or none, and the temporary file is removed on error), keeping the replaced
/// file's permissions; a symlink's target the same way (the link stays); anything else
/// (device, FIFO) by writing through it. Errors (e.g. `/dev/full`: no space left) name
/// the path.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    match target_of(path)? {
        Target::WriteThrough(target) => {
            let mut file = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .map_err(io)?;
            file.write_all(bytes)
                .and_then(|()| file.flush())
                .map_err(io)
        }
        Target::Replace { path: target, mode } => {
            let name = target
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "output".into());
            let tmp = parent_of(&target).join(format!(".{name}.{}.tmp", std::process::id()));
            let result = (|| {
                let mut file = std::fs::File::create(&tmp)?;
                file.write_all(bytes)?;
                if let Some(mode) = mode {
                    file.set_permissions(mode)?;
                }
                file.sync_all()?;
                std::fs::rename(&tmp, &target)
            })();
            if result.is_err() {
                let _ = std::fs::remove_file(&tmp);
            }
            result.map_err(io)
        }
    }
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
    fn devices_symlinks_and_read_only_files_are_not_replaced() {
        use std::os::unix::fs::{FileTypeExt, PermissionsExt};
        let dir = std::env::temp_dir().join(format!("dispmap-output-kinds-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A device is written through and stays a device. (Checked before writing: a
        // regression must fail here, not replace the machine's /dev/null as root.)
        for device in ["/dev/null", "/dev/full", "-"] {
            assert!(
                matches!(target_of(Path::new(device)), Ok(Target::WriteThrough(_))),
                "{device} would be replaced"
            );
        }
        write_atomic(Path::new("/dev/null"), b"discarded").unwrap();
        let null = std::fs::symlink_metadata("/dev/null").unwrap();
        assert!(null.file_type().is_char_device());
        // A full device reports it, naming the path.
        let err = write_atomic(Path::new("/dev/full"), &[0; 4096])
            .unwrap_err()
            .to_string();
        assert!(err.contains("/dev/full") && err.contains("space"), "{err}");
        // A read-only file is refused before any work, and left as it was.
        let ro = dir.join("ro.png");
        std::fs::write(&ro, b"old").unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o444)).unwrap();
        let err = check_writable(&ro).unwrap_err().to_string();
        assert!(err.contains("ro.png") && err.contains("read-only"), "{err}");
        assert!(write_atomic(&ro, b"new").is_err());
        assert_eq!(std::fs::read(&ro).unwrap(), b"old");
        // A symlink's target is replaced; the link stays a link.
        let target = dir.join("target.png");
        std::fs::write(&target, b"old").unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
        let link = dir.join("link.png");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        // The replaced file's permissions are kept.
        let mode = std::fs::metadata(&target).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
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
