//! The temporary files a commit writes beside its targets: their names, and their
//! removal when a signal ends the process mid-commit.

use super::checks::parent_of;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicPtr, Ordering};

/// The longest file name the file system of `folder` takes (`pathconf(_PC_NAME_MAX)`);
/// 255 (Linux's `NAME_MAX`) where it cannot be asked (a missing folder).
pub(super) fn name_max(folder: &Path) -> usize {
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
pub(super) fn temporary_name(target: &Path, k: usize) -> PathBuf {
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
pub(super) static TEMPORARIES: [AtomicPtr<libc::c_char>; MAX_TEMPORARIES] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; MAX_TEMPORARIES];
pub(super) const MAX_TEMPORARIES: usize = 256;

/// Registers `tmp` for removal by the signal handler; the slot, or `None` when all are
/// taken (the file is then only removed on error, not on a signal).
pub(super) fn register_temporary(tmp: &Path) -> Option<usize> {
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
pub(super) fn unregister_temporary(slot: Option<usize>) {
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
