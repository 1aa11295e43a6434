//! Writing result files without ever leaving a partial one. Every output of a run is
//! checked before any work ([`Outputs::check`]: the folder exists and is writable, the
//! file system is not read-only, the name is a file name and its extension matches the
//! format written, no two outputs are the same file), its bytes are kept in memory until
//! the run has produced all of them ([`Outputs::stage`]), and [`Outputs::commit`] writes
//! them together: each regular file to a temporary file beside it, then, only when every
//! one of them is complete and synced, devices are written through and the temporary
//! files are renamed over their targets. A failure before the renames removes every
//! temporary file and leaves every target as it was (or absent).

mod checks;
mod encode;
mod temporary;

pub use checks::{
    Format, check_folder_files, check_folder_writable, check_format, check_writable,
    check_writable_as, refuse_standard_output,
};
use checks::{Target, check_extension, identity, io_error, target_of};
pub use encode::{depth_bytes, downsample_srgb, png_bytes, write_depth, write_png};
pub use temporary::{CLEANED_UP_SIGNALS, clean_up_on_signals};
use temporary::{register_temporary, temporary_name, unregister_temporary};

use dispmap::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

struct Entry {
    /// What the user named it by (`--metrics`), for messages.
    label: String,
    /// As given.
    path: PathBuf,
    target: Target,
    bytes: Option<Vec<u8>>,
}

/// The outputs of one run, checked before any work and committed together at its end
/// (see the module's documentation).
#[derive(Default)]
pub struct Outputs {
    entries: Vec<Entry>,
    /// Folders [`Outputs::commit`] creates first (the benchmark's `--out`).
    folders: Vec<PathBuf>,
}

impl Outputs {
    /// No outputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Checks that `path` can take an output in `format` (see [`check_writable`]; the
    /// extension must match the format) and is not the file of an output already
    /// checked; `label` (e.g. `--out`) names it in errors.
    pub fn check(&mut self, label: &str, path: &Path, format: Format) -> Result<()> {
        self.add(label, path, format, None)
    }

    fn add(
        &mut self,
        label: &str,
        path: &Path,
        format: Format,
        bytes: Option<Vec<u8>>,
    ) -> Result<()> {
        check_extension(path, format)?;
        let target = target_of(path)?;
        let id = identity(&target);
        let shareable = |t: &Target, given: &Path| {
            matches!(t, Target::WriteThrough { device: true, .. }) && given != Path::new("-")
        };
        if let Some(other) = self.entries.iter().find(|e| {
            identity(&e.target) == id || (e.path == Path::new("-") && path == Path::new("-"))
        }) && !(shareable(&target, path) && shareable(&other.target, &other.path))
        {
            return Err(io_error(
                path,
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "is the same file as {} ({}): each output needs its own file",
                    other.label,
                    other.path.display()
                ),
            ));
        }
        self.entries.push(Entry {
            label: label.to_owned(),
            path: path.to_owned(),
            target,
            bytes,
        });
        Ok(())
    }

    /// Keeps `bytes` for the output checked as `path`, to be written by [`Outputs::commit`].
    pub fn stage(&mut self, path: &Path, bytes: Vec<u8>) -> Result<()> {
        let entry = self
            .entries
            .iter_mut()
            .find(|e| e.path == path)
            .ok_or_else(|| Error::Internal(format!("output {} was not checked", path.display())))?;
        entry.bytes = Some(bytes);
        Ok(())
    }

    /// Checks and keeps a file named `name` in the folder `dir`, which is created (with
    /// its missing parents) when the outputs are committed.
    pub fn stage_in(&mut self, dir: &Path, name: &str, bytes: Vec<u8>) -> Result<()> {
        if !self.folders.iter().any(|d| d == dir) {
            check_folder_writable(dir)?;
            self.folders.push(dir.to_owned());
        }
        let path = dir.join(name);
        if dir.is_dir() {
            self.add(&path.display().to_string(), &path, Format::Any, Some(bytes))
        } else {
            // The folder is created at commit: the file is new.
            self.entries.push(Entry {
                label: path.display().to_string(),
                path: path.clone(),
                target: Target::Replace { path, mode: None },
                bytes: Some(bytes),
            });
            Ok(())
        }
    }

    /// The paths staged, in the order they were checked.
    pub fn paths(&self) -> Vec<PathBuf> {
        self.entries
            .iter()
            .filter(|e| e.bytes.is_some())
            .map(|e| e.path.clone())
            .collect()
    }

    /// Writes every staged output: first each regular file's bytes to a temporary file
    /// beside it (synced), then devices written through, then the temporary files renamed
    /// over their targets. Until the renames nothing is replaced: a failure (no space,
    /// `EFBIG` under a file size limit) removes every temporary file, and folders this
    /// call created, and leaves the targets as they were. Outputs checked but never
    /// staged are not written.
    pub fn commit(self) -> Result<()> {
        let mut created = Vec::new();
        for dir in &self.folders {
            let mut missing = Vec::new();
            let mut d = dir.as_path();
            while !d.as_os_str().is_empty() && !d.exists() {
                missing.push(d.to_owned());
                d = match d.parent() {
                    Some(p) => p,
                    None => break,
                };
            }
            let made = std::fs::create_dir_all(dir).map_err(|source| Error::Io {
                path: dir.clone(),
                source,
            });
            missing.reverse();
            created.extend(missing);
            if let Err(e) = made {
                remove_folders(&created);
                return Err(e);
            }
        }
        let mut temps: Vec<(PathBuf, &Entry, Option<usize>)> = Vec::new();
        let cleanup = |temps: &[(PathBuf, &Entry, Option<usize>)]| {
            for (tmp, _, slot) in temps {
                let _ = std::fs::remove_file(tmp);
                unregister_temporary(*slot);
            }
            remove_folders(&created);
        };
        for (k, entry) in self
            .entries
            .iter()
            .filter(|e| e.bytes.is_some())
            .enumerate()
        {
            let Target::Replace { path: target, mode } = &entry.target else {
                continue;
            };
            let tmp = temporary_name(target, k);
            let bytes = entry.bytes.as_deref().unwrap_or_default();
            // Registered before it exists, so a signal never misses it.
            let slot = register_temporary(&tmp);
            temps.push((tmp.clone(), entry, slot));
            let written = std::fs::File::create(&tmp).and_then(|mut file| {
                file.write_all(bytes)?;
                if let Some(mode) = mode {
                    file.set_permissions(mode.clone())?;
                }
                file.sync_all()
            });
            if let Err(source) = written {
                cleanup(&temps);
                return Err(Error::Io {
                    path: entry.path.clone(),
                    source,
                });
            }
        }
        for entry in self.entries.iter().filter(|e| e.bytes.is_some()) {
            let Target::WriteThrough { path: target, .. } = &entry.target else {
                continue;
            };
            let bytes = entry.bytes.as_deref().unwrap_or_default();
            let written = std::fs::OpenOptions::new()
                .write(true)
                .open(target)
                .and_then(|mut file| file.write_all(bytes).and_then(|()| file.flush()));
            if let Err(source) = written {
                cleanup(&temps);
                return Err(Error::Io {
                    path: entry.path.clone(),
                    source,
                });
            }
        }
        for (i, (tmp, entry, slot)) in temps.iter().enumerate() {
            let Target::Replace { path: target, .. } = &entry.target else {
                continue;
            };
            if let Err(source) = std::fs::rename(tmp, target) {
                cleanup(&temps[i..]);
                return Err(Error::Io {
                    path: entry.path.clone(),
                    source,
                });
            }
            unregister_temporary(*slot);
        }
        Ok(())
    }
}

/// Removes the folders in `created` (parents first in the list), innermost first, where
/// they are empty.
fn remove_folders(created: &[PathBuf]) {
    for dir in created.iter().rev() {
        let _ = std::fs::remove_dir(dir);
    }
}

/// Writes `bytes` to `path` alone (an [`Outputs`] of one): a regular file (or a new one)
/// through a temporary file in the same folder renamed over it (atomic: a failed or
/// interrupted run leaves the old file or none, and the temporary file is removed on
/// error), keeping the replaced file's permissions; a symlink's target the same way (the
/// link stays); anything else (device, FIFO) by writing through it. Errors (e.g.
/// `/dev/full`: no space left) name the path.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut outputs = Outputs::new();
    outputs.add("output", path, Format::Any, Some(bytes.to_vec()))?;
    outputs.commit()
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
                matches!(
                    target_of(Path::new(device)),
                    Ok(Target::WriteThrough { .. })
                ),
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

    /// A character device made by the test (`mknod`, as root): `/dev/full`'s numbers
    /// (1, 7) in `dir`; `None` when not root or mknod fails.
    fn full_device(dir: &Path) -> Option<PathBuf> {
        let node = dir.join("full");
        let _ = std::fs::remove_file(&node);
        let ok = std::process::Command::new("mknod")
            .arg(&node)
            .args(["c", "1", "7"])
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then_some(node)
    }

    #[test]
    fn outputs_are_checked_before_and_committed_together() {
        let dir = std::env::temp_dir().join(format!("dispmap-output-plan-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let a = dir.join("a.png");
        let b = dir.join("b.json");
        // A name ending in '/', a wrong extension, the same file twice.
        let mut o = Outputs::new();
        let slash = format!("{}/", a.display());
        let err = o
            .check("--out", Path::new(&slash), Format::Png)
            .unwrap_err()
            .to_string();
        assert!(err.contains("ends in '/'"), "{err}");
        let err = o
            .check("--out", &dir.join("a.jpg"), Format::Png)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("a.jpg") && err.contains(".jpg does not match"),
            "{err}"
        );
        let err = o
            .check("--metrics", &dir.join("m.png"), Format::Json)
            .unwrap_err()
            .to_string();
        assert!(err.contains("(JSON)"), "{err}");
        o.check("--out", &a, Format::Png).unwrap();
        let err = o
            .check("--heatmap", &dir.join(".").join("a.png"), Format::Png)
            .unwrap_err()
            .to_string();
        assert!(err.contains("same file as --out"), "{err}");
        o.check("--metrics", &b, Format::Json).unwrap();
        o.stage(&a, b"image".to_vec()).unwrap();
        o.stage(&b, b"{}".to_vec()).unwrap();
        o.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"image");
        assert_eq!(std::fs::read(&b).unwrap(), b"{}");
        // One output failing at commit (a full device) leaves the others untouched.
        if let Some(full) = full_device(&dir) {
            let mut o = Outputs::new();
            o.check("--out", &a, Format::Png).unwrap();
            o.check("--metrics", &full, Format::Json).unwrap();
            o.stage(&a, b"new".to_vec()).unwrap();
            o.stage(&full, vec![0; 4096]).unwrap();
            let err = o.commit().unwrap_err().to_string();
            assert!(err.contains("full") && err.contains("space"), "{err}");
            assert_eq!(std::fs::read(&a).unwrap(), b"image");
            std::fs::remove_file(&full).unwrap();
        }
        // A folder staged into is created at commit only, and removed if the commit fails.
        let mut o = Outputs::new();
        let folder = dir.join("bench/inner");
        o.stage_in(&folder, "report.md", b"r".to_vec()).unwrap();
        assert!(!dir.join("bench").exists());
        o.commit().unwrap();
        assert_eq!(std::fs::read(folder.join("report.md")).unwrap(), b"r");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
