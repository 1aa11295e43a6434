//! Writing result files without ever leaving a partial one. Every output of a run is
//! checked before any work ([`Outputs::check`]: the folder exists and is writable, the
//! file system is not read-only, the name is a file name and its extension matches the
//! format written, no two outputs are the same file), its bytes are kept in memory until
//! the run has produced all of them ([`Outputs::stage`]), and [`Outputs::commit`] writes
//! them together: each regular file to a temporary file beside it, then, only when every
//! one of them is complete and synced, devices are written through and the temporary
//! files are renamed over their targets. A failure before the renames removes every
//! temporary file and leaves every target as it was (or absent).

use dispmap::error::{Error, Result};
use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicPtr, Ordering};

/// What an output path names, with symlinks followed: where the bytes go and how.
#[derive(Clone, Debug)]
enum Target {
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

fn io_error(path: &Path, kind: std::io::ErrorKind, message: impl Into<String>) -> Error {
    Error::Io {
        path: path.to_owned(),
        source: std::io::Error::new(kind, message.into()),
    }
}

/// The lower-case extension of `path`, if any.
fn extension(path: &Path) -> Option<String> {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// Refuses a name the format does not match (`out.jpg` for a PNG); `-` and names
/// without an extension (`/dev/null`) take any format but a depth image's.
fn check_extension(path: &Path, format: Format) -> Result<()> {
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

fn is_device(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| {
        let t = m.file_type();
        t.is_char_device() || t.is_block_device() || t.is_fifo() || t.is_socket()
    })
}

/// Whether this process may write `path` (`access(2)` with `W_OK`, plus `X_OK` for a
/// folder): permission, a read-only file system. The error names `what` and the cause.
fn check_access(path: &Path, folder: bool, shown: &Path) -> Result<()> {
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
fn target_of(path: &Path) -> Result<Target> {
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
fn check_folder(path: &Path, resolved: &Path) -> Result<()> {
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

/// Checks that `dir` can take the files of [`Outputs::stage_in`]: an existing writable
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

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The longest file name the file system of `folder` takes (`pathconf(_PC_NAME_MAX)`);
/// 255 (Linux's `NAME_MAX`) where it cannot be asked (a missing folder).
fn name_max(folder: &Path) -> usize {
    const DEFAULT: usize = 255;
    let Ok(c) = std::ffi::CString::new(folder.as_os_str().as_bytes()) else {
        return DEFAULT;
    };
    // SAFETY: `c` is a NUL-terminated string that outlives the call; pathconf(3) only
    // reads it.
    let max = unsafe { libc::pathconf(c.as_ptr(), libc::_PC_NAME_MAX) };
    usize::try_from(max)
        .ok()
        .filter(|&m| m > 0)
        .unwrap_or(DEFAULT)
}

/// The temporary file of `target`: `.<name>.<pid>.tmp` beside it, or, where that is
/// longer than the folder's `NAME_MAX`, the name cut to fit and marked with `~<k>` (`k`:
/// the output's number in the commit, so two cut names never meet). Always a name the
/// file system takes, as long as the target's own name is one.
fn temporary_name(target: &Path, k: usize) -> PathBuf {
    let folder = parent_of(target);
    let name = target
        .file_name()
        .map(|n| n.as_bytes().to_vec())
        .unwrap_or_else(|| b"output".to_vec());
    let pid = std::process::id();
    let plain = [b".", &name[..], format!(".{pid}.tmp").as_bytes()].concat();
    let max = name_max(&folder);
    let bytes = if plain.len() <= max {
        plain
    } else {
        let tail = format!("~{k}.{pid}.tmp");
        let keep = max.saturating_sub(1 + tail.len()).min(name.len());
        [b".", &name[..keep], tail.as_bytes()].concat()
    };
    folder.join(std::ffi::OsStr::from_bytes(&bytes))
}

/// The temporary files of a commit in progress, for [`clean_up_on_signals`]'s handler:
/// NUL-terminated paths, null where free. A path is never freed once registered (a
/// handler on another thread may be reading it); each is a few dozen bytes per output.
static TEMPORARIES: [AtomicPtr<libc::c_char>; MAX_TEMPORARIES] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; MAX_TEMPORARIES];
const MAX_TEMPORARIES: usize = 256;

/// Registers `tmp` for removal by the signal handler; the slot, or `None` when all are
/// taken (the file is then only removed on error, not on a signal).
fn register_temporary(tmp: &Path) -> Option<usize> {
    let c = std::ffi::CString::new(tmp.as_os_str().as_bytes()).ok()?;
    let raw = c.into_raw();
    for (i, slot) in TEMPORARIES.iter().enumerate() {
        if slot
            .compare_exchange(
                std::ptr::null_mut(),
                raw,
                Ordering::SeqCst,
                Ordering::SeqCst,
            )
            .is_ok()
        {
            return Some(i);
        }
    }
    // SAFETY: `raw` came from `CString::into_raw` above and was published nowhere.
    drop(unsafe { std::ffi::CString::from_raw(raw) });
    None
}

/// Frees the slot of a temporary file renamed or removed (its path is leaked, see
/// [`TEMPORARIES`]).
fn unregister_temporary(slot: Option<usize>) {
    if let Some(i) = slot {
        TEMPORARIES[i].store(std::ptr::null_mut(), Ordering::SeqCst);
    }
}

extern "C" fn remove_temporaries_and_die(signal: libc::c_int) {
    for slot in &TEMPORARIES {
        let path = slot.load(Ordering::SeqCst);
        if !path.is_null() {
            // SAFETY: a registered path is a NUL-terminated string that is never freed;
            // unlink(2) is async-signal-safe.
            unsafe {
                libc::unlink(path);
            }
        }
    }
    // SAFETY: signal(2) and raise(3) are async-signal-safe; the default disposition
    // ends the process by `signal`, as without this handler.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        libc::raise(signal);
    }
}

/// The signals whose default action ends the process and that a handler may catch,
/// less those left alone: SIGSEGV and SIGBUS (the standard library's stack-overflow
/// report), SIGILL and SIGFPE (faults of the code itself), SIGTRAP (a debugger's), and
/// any this process ignores (SIGPIPE: failed writes are errors; SIGXFSZ: see `main`; a
/// SIGHUP ignored by `nohup`). The real-time signals from `SIGRTMIN` up end the process
/// by default too and are added by [`clean_up_on_signals`].
pub const CLEANED_UP_SIGNALS: [libc::c_int; 15] = [
    libc::SIGHUP,
    libc::SIGINT,
    libc::SIGQUIT,
    libc::SIGTERM,
    libc::SIGUSR1,
    libc::SIGUSR2,
    libc::SIGALRM,
    libc::SIGVTALRM,
    libc::SIGPROF,
    libc::SIGXCPU,
    libc::SIGIO,
    libc::SIGPWR,
    libc::SIGSTKFLT,
    libc::SIGSYS,
    libc::SIGABRT,
];

/// Installs a handler for every signal that ends the process by default
/// ([`CLEANED_UP_SIGNALS`] and the real-time signals) that removes the temporary files
/// of a commit in progress and then ends the process by the same signal (as it would
/// have ended without the handler). A signal this process ignores stays ignored. Call
/// once, early in `main`.
pub fn clean_up_on_signals() {
    let handler = remove_temporaries_and_die as extern "C" fn(libc::c_int);
    let realtime = libc::SIGRTMIN()..=libc::SIGRTMAX();
    for signal in CLEANED_UP_SIGNALS.into_iter().chain(realtime) {
        // SAFETY: a zeroed sigaction is a valid value to be filled; sigaction(2) with a
        // null new action only reads the current disposition into it.
        let ignored = unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(signal, std::ptr::null(), &mut old) == 0
                && old.sa_sigaction == libc::SIG_IGN
        };
        if ignored {
            continue;
        }
        // SAFETY: the handler only reads atomics, calls unlink, signal and raise (all
        // async-signal-safe) and touches no lock or allocation.
        unsafe {
            libc::signal(signal, handler as libc::sighandler_t);
        }
    }
}

/// The identity of a target, for the same-file check: the canonical folder and the name.
fn identity(target: &Target) -> PathBuf {
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
