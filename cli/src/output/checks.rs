//! What an output path names and whether it may be written: the checks every output
//! passes before any work (folder, permissions, file system, name, extension).

use dispmap::error::{Error, Result};
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::temporary::name_max;

/// What an output path names, with symlinks followed: where the bytes go and how.
#[derive(Clone, Debug)]
pub(super) enum Target {
    /// A regular file (or nothing yet): written to a temporary file beside it and renamed
    /// over it, so a failed run leaves the old file (or none); `mode`: the permissions of
    /// the file replaced, kept.
    Replace {
        path: PathBuf,
        mode: Option<std::fs::Permissions>,
    },
    /// Not a regular file (a device such as `/dev/null`, a FIFO, `/dev/stdout`): opened
    /// and written through, never replaced. `device`: a character device (may be named
    /// by two outputs, e.g. `/dev/null`).
    WriteThrough { path: PathBuf, device: bool },
}

/// The format an output holds, for the extension check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// A PNG image: `.png` or no extension.
    Png,
    /// JSON: `.json` or no extension.
    Json,
    /// A depth image: `.exr` (32-bit float) or `.png` (16-bit), required.
    Depth,
    /// Anything (the file's name fixes it, e.g. the benchmark's files).
    Any,
}

pub(super) fn io_error(path: &Path, kind: std::io::ErrorKind, message: impl Into<String>) -> Error {
    Error::Io {
        path: path.to_owned(),
        source: std::io::Error::new(kind, message.into()),
    }
}

/// The lower-case extension of `path`, if any.
pub(super) fn extension(path: &Path) -> Option<String> {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// Refuses a name the format does not match (`out.jpg` for a PNG); `-` and names
/// without an extension (`/dev/null`) take any format but a depth image's.
pub(super) fn check_extension(path: &Path, format: Format) -> Result<()> {
    let ext = extension(path);
    let err = |message: String| {
        Err(Error::Image {
            path: path.to_owned(),
            message,
        })
    };
    match (format, ext.as_deref()) {
        (Format::Any, _)
        | (Format::Png, None | Some("png"))
        | (Format::Json, None | Some("json")) => Ok(()),
        (Format::Depth, Some("exr" | "png")) => Ok(()),
        (Format::Depth, _) if path == Path::new("-") || is_device(path) => Ok(()),
        (Format::Depth, _) => err(
            "unknown depth format: the name must end in .exr (32-bit float) or .png (16-bit)"
                .into(),
        ),
        (Format::Png, Some(e)) => err(format!(
            "the extension .{e} does not match the format written (PNG): use .png"
        )),
        (Format::Json, Some(e)) => err(format!(
            "the extension .{e} does not match the format written (JSON): use .json"
        )),
    }
}

/// Checks, before any work, that `path` can take an output in `format`: the extension
/// matches it (`shot.jpg` is refused for a PNG) and [`check_writable`] holds.
pub fn check_writable_as(path: &Path, format: Format) -> Result<()> {
    check_extension(path, format)?;
    check_writable(path)
}

/// Refuses a name whose extension does not match `format` (see [`check_writable_as`]),
/// without looking at the file system beyond whether the path is a device.
pub fn check_format(path: &Path, format: Format) -> Result<()> {
    check_extension(path, format)
}

pub(super) fn is_device(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| {
        let t = m.file_type();
        t.is_char_device() || t.is_block_device() || t.is_fifo() || t.is_socket()
    })
}

/// Whether this process may write `path` (`access(2)` with `W_OK`, plus `X_OK` for a
/// folder): permission, a read-only file system. The error names `what` and the cause.
pub(super) fn check_access(path: &Path, folder: bool, shown: &Path) -> Result<()> {
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).map_err(|_| {
        io_error(
            shown,
            std::io::ErrorKind::InvalidInput,
            "the path contains a NUL byte",
        )
    })?;
    let mode = if folder {
        libc::W_OK | libc::X_OK
    } else {
        libc::W_OK
    };
    // SAFETY: `c` is a NUL-terminated string that outlives the call; access(2) only reads
    // it and touches no memory of this process otherwise.
    let rc = unsafe { libc::access(c.as_ptr(), mode) };
    if rc == 0 {
        return Ok(());
    }
    let e = std::io::Error::last_os_error();
    let message = match e.raw_os_error() {
        Some(libc::EROFS) => format!("{} is on a read-only file system", path.display()),
        Some(libc::EACCES | libc::EPERM) if folder => {
            format!(
                "permission denied: cannot create files in folder {}",
                path.display()
            )
        }
        Some(libc::EACCES | libc::EPERM) => {
            format!("permission denied: cannot write {}", path.display())
        }
        _ => format!("cannot write {}: {e}", path.display()),
    };
    Err(io_error(shown, e.kind(), message))
}

/// Why `-` (standard output) cannot take an output, when it cannot
/// ([`refuse_standard_output`]).
static STDOUT_REFUSED: Mutex<Option<String>> = Mutex::new(None);

/// Makes every output named `-` (standard output) an error saying `why`, e.g. when
/// standard output was closed at the process's start (the Rust runtime then opens it on
/// `/dev/null`, where a file would be lost).
pub fn refuse_standard_output(why: &str) {
    *STDOUT_REFUSED.lock().unwrap_or_else(|p| p.into_inner()) = Some(why.to_owned());
}

/// Where `path` leads (a symlink to its target) and how it is written; an error for a
/// folder, a missing or unwritable folder, a read-only file (which is not replaced), a
/// name that ends in `/` or names no file.
pub(super) fn target_of(path: &Path) -> Result<Target> {
    if path == Path::new("-") {
        if let Some(why) = STDOUT_REFUSED
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .as_ref()
        {
            return Err(io_error(path, std::io::ErrorKind::BrokenPipe, why.clone()));
        }
        return Ok(Target::WriteThrough {
            path: PathBuf::from("/dev/stdout"),
            device: false,
        });
    }
    if path.as_os_str().as_bytes().ends_with(b"/") {
        return Err(io_error(
            path,
            std::io::ErrorKind::InvalidInput,
            "ends in '/' (a folder name), not a file name",
        ));
    }
    let Some(name) = path.file_name() else {
        return Err(io_error(
            path,
            std::io::ErrorKind::InvalidInput,
            "names no file",
        ));
    };
    let max = name_max(&parent_of(path));
    if name.len() > max {
        return Err(io_error(
            path,
            std::io::ErrorKind::InvalidInput,
            format!(
                "the file name has {} bytes, more than the {max} its file system allows \
                 (NAME_MAX)",
                name.len()
            ),
        ));
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
        Ok(m) => {
            check_access(&resolved, false, path)?;
            Ok(Target::WriteThrough {
                path: resolved,
                device: m.file_type().is_char_device(),
            })
        }
        Err(_) => {
            check_folder(path, &resolved)?;
            Ok(Target::Replace {
                path: resolved,
                mode: None,
            })
        }
    }
}

/// The folder of `resolved` exists and this process can create files in it.
pub(super) fn check_folder(path: &Path, resolved: &Path) -> Result<()> {
    let parent = parent_of(resolved);
    if !parent.is_dir() {
        return Err(io_error(
            path,
            std::io::ErrorKind::NotFound,
            format!("folder {} does not exist", parent.display()),
        ));
    }
    check_access(&parent, true, path)
}

/// Checks, before any work, that `path` can take an output: its folder exists and is
/// writable, it is not a folder and not a read-only file; `-` is standard output. A
/// symlink is followed (its target is written, the link kept); a device or FIFO is
/// written through (`/dev/null` discards).
pub fn check_writable(path: &Path) -> Result<()> {
    target_of(path).map(|_| ())
}

/// Checks, before any work, that the folder `dir` can take the files `names`
/// ([`check_folder_writable`]) and that none of them that exists already is in the way
/// (a folder, a read-only file: [`check_writable`]).
pub fn check_folder_files(dir: &Path, names: &[String]) -> Result<()> {
    check_folder_writable(dir)?;
    if dir.is_dir() {
        for name in names {
            target_of(&dir.join(name))?;
        }
    }
    Ok(())
}

/// Checks that `dir` can take the files of [`Outputs::stage_in`](super::Outputs::stage_in): an existing writable
/// folder, or a missing one whose nearest existing ancestor is a writable folder (it is
/// created only when the outputs are committed).
pub fn check_folder_writable(dir: &Path) -> Result<()> {
    if dir.as_os_str().is_empty() {
        return Ok(());
    }
    let mut existing = dir.to_owned();
    loop {
        match std::fs::metadata(&existing) {
            Ok(m) if m.is_dir() => return check_access(&existing, true, dir),
            Ok(_) => {
                return Err(io_error(
                    dir,
                    std::io::ErrorKind::NotADirectory,
                    format!("{} is not a folder", existing.display()),
                ));
            }
            Err(_) => match existing.parent() {
                Some(p) if !p.as_os_str().is_empty() => existing = p.to_owned(),
                _ => return check_access(Path::new("."), true, dir),
            },
        }
    }
}

pub(super) fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The identity of a target, for the same-file check: the canonical folder and the name.
pub(super) fn identity(target: &Target) -> PathBuf {
    match target {
        Target::Replace { path, .. } => {
            let folder = std::fs::canonicalize(parent_of(path)).unwrap_or_else(|_| parent_of(path));
            folder.join(path.file_name().unwrap_or_default())
        }
        Target::WriteThrough { path, .. } => {
            std::fs::canonicalize(path).unwrap_or_else(|_| path.clone())
        }
    }
}
