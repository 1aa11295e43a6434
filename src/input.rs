//! Reading an input file with a bound: only a regular file no larger than a limit the
//! caller gives is read, and the check comes before the read. A device (`/dev/zero`), a
//! FIFO, a socket or a folder has no size to check (or one that never ends) and is
//! refused naming the path; so is a file above the limit, from its size before reading
//! and again from the bytes read (a file that grows while it is read). Every file input
//! of dispmap (height, albedo and normal maps here; scene files, meshes and their
//! buffers, the viewer's camera paths and scripts in the command line) goes through
//! [`open`] or [`read`].

use crate::error::{Error, Result};
use std::io::Read as _;
use std::path::Path;

fn refused(path: &Path, kind: std::io::ErrorKind, message: String) -> Error {
    Error::Io {
        path: path.to_owned(),
        source: std::io::Error::new(kind, message),
    }
}

/// Checks that `path` is a regular file of at most `max_bytes` without opening it, and
/// returns its size. `what` names the kind of file in errors ("an image file").
pub fn check(path: &Path, max_bytes: u64, what: &str) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    check_metadata(path, &meta, max_bytes, what)
}

fn check_metadata(
    path: &Path,
    meta: &std::fs::Metadata,
    max_bytes: u64,
    what: &str,
) -> Result<u64> {
    if meta.is_dir() {
        return Err(refused(
            path,
            std::io::ErrorKind::IsADirectory,
            format!("is a folder, not {what}"),
        ));
    }
    if !meta.is_file() {
        return Err(refused(
            path,
            std::io::ErrorKind::InvalidInput,
            "is not a regular file (a device or pipe is not read: its size cannot be checked)"
                .into(),
        ));
    }
    if meta.len() > max_bytes {
        return Err(refused(
            path,
            std::io::ErrorKind::InvalidData,
            format!(
                "the file has {} bytes, more than the {max_bytes} read at most for {what}",
                meta.len()
            ),
        ));
    }
    Ok(meta.len())
}

/// Opens `path` for reading if it is a regular file of at most `max_bytes` (see the
/// module docs) and returns it with its size. The kind is checked before opening
/// (opening a FIFO waits for a writer) and again on the opened file, which must be the
/// one checked.
pub fn open(path: &Path, max_bytes: u64, what: &str) -> Result<(std::fs::File, u64)> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    check(path, max_bytes, what)?;
    let file = std::fs::File::open(path).map_err(io)?;
    // The path may have been replaced between the check and the open: the opened file
    // is what is read, so it is checked itself.
    let meta = file.metadata().map_err(io)?;
    let len = check_metadata(path, &meta, max_bytes, what)?;
    Ok((file, len))
}

/// Reads the whole of `path` if it is a regular file of at most `max_bytes` (see
/// [`open`]); a file that grows past the limit while it is read is refused too.
pub fn read(path: &Path, max_bytes: u64, what: &str) -> Result<Vec<u8>> {
    let (file, len) = open(path, max_bytes, what)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|source| Error::Io {
            path: path.to_owned(),
            source,
        })?;
    if bytes.len() as u64 > max_bytes {
        return Err(refused(
            path,
            std::io::ErrorKind::InvalidData,
            format!("the file grew past the {max_bytes} bytes read at most for {what}"),
        ));
    }
    Ok(bytes)
}

/// [`read`] as UTF-8 text; an error names the path when the bytes are not UTF-8.
pub fn read_to_string(path: &Path, max_bytes: u64, what: &str) -> Result<String> {
    String::from_utf8(read(path, max_bytes, what)?).map_err(|e| {
        refused(
            path,
            std::io::ErrorKind::InvalidData,
            format!(
                "is not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_limit_are_read() {
        let dir = std::env::temp_dir().join(format!("dispmap-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("f.txt");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(read(&file, 5, "a text file").unwrap(), b"12345");
        assert_eq!(read_to_string(&file, 5, "a text file").unwrap(), "12345");
        let err = read(&file, 4, "a text file").unwrap_err().to_string();
        assert!(
            err.contains("f.txt") && err.contains("5 bytes, more than the 4"),
            "{err}"
        );
        let err = read(&dir, 4, "a text file").unwrap_err().to_string();
        assert!(err.contains("is a folder, not a text file"), "{err}");
        for device in ["/dev/zero", "/dev/null"] {
            let err = read(Path::new(device), 1 << 20, "a text file")
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(device) && err.contains("not a regular file"),
                "{err}"
            );
        }
        let fifo = dir.join("fifo");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if made {
            let err = read(&fifo, 1 << 20, "a text file").unwrap_err().to_string();
            assert!(err.contains("not a regular file"), "{err}");
        }
        std::fs::write(&file, [0xFF, 0xFE]).unwrap();
        let err = read_to_string(&file, 5, "a text file")
            .unwrap_err()
            .to_string();
        assert!(err.contains("not UTF-8"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
