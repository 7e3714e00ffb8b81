//! File helpers: whole-file reads, and atomic writes (temp file in the same folder, then
//! rename), so a failed command never leaves a partial output behind (spec §9.2); outputs
//! get the permissions any new file gets, and `-`, devices and FIFOs are written directly.

use std::io::{BufWriter, Write};
use std::path::Path;

use crate::error::{Error, IoOp, Result};

/// Reads a whole file.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(IoOp::Read, path, e))
}

/// Checks, before any work, that `path` can be an output: not a folder, in a folder that
/// exists (`-`, standard output, always can).
pub fn check_output(path: &Path) -> Result<()> {
    if path == Path::new("-") {
        return Ok(());
    }
    if path.is_dir() {
        let e = std::io::Error::new(std::io::ErrorKind::IsADirectory, "it is a folder");
        return Err(Error::io(IoOp::Write, path, e));
    }
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => {
            let e = std::io::Error::new(std::io::ErrorKind::NotFound, "its folder does not exist");
            Err(Error::io(IoOp::Write, path, e))
        }
        _ => Ok(()),
    }
}

/// Whether an output may take the place of a file that exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Replace {
    /// An existing regular file is replaced (what the library functions do).
    Allowed,
    /// An existing regular file is an error ([`Error::OutputExists`]), also when it appears
    /// while the output is being written: the finished file is moved into place only where
    /// no file is (a device or a FIFO is still written).
    Never,
}

/// Writes `path` atomically: `fill` writes into a temporary file beside it, which is renamed
/// over `path` only when `fill` and the flush succeed; on any error the temporary is removed.
/// The new file gets the permissions of the file it replaces, or those the umask gives a new
/// file. A symbolic link is followed (the file it names is replaced, the link stays); a
/// target that is not a regular file (`/dev/null`, a FIFO) is written directly, and `-` is
/// standard output.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_atomic_as(path, Replace::Allowed, fill)
}

/// [`write_atomic`], replacing an existing file only where `replace` allows it.
pub fn write_atomic_as(
    path: &Path,
    replace: Replace,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    if path == Path::new("-") {
        let stdout = std::io::stdout();
        let mut w = BufWriter::with_capacity(1 << 20, stdout.lock());
        fill(&mut w).map_err(|e| Error::io(IoOp::Write, path, e))?;
        return w.flush().map_err(|e| Error::io(IoOp::Write, path, e));
    }
    check_output(path)?;
    let target = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            std::fs::canonicalize(path).map_err(|e| Error::io(IoOp::Write, path, e))?
        }
        _ => path.to_path_buf(),
    };
    let existing = std::fs::metadata(&target).ok();
    if let Some(m) = &existing {
        if m.is_file() && replace == Replace::Never {
            return Err(Error::OutputExists {
                path: path.to_path_buf(),
            });
        }
        if !m.is_file() {
            // A device or a FIFO: nothing to replace atomically.
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .map_err(|e| Error::io(IoOp::Write, path, e))?;
            let mut w = BufWriter::with_capacity(1 << 20, file);
            fill(&mut w).map_err(|e| Error::io(IoOp::Write, path, e))?;
            return w.flush().map_err(|e| Error::io(IoOp::Write, path, e));
        }
    }
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".salvq-").suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Opened with this mode, the temporary gets the umask like any new file (0644
        // under the usual 022), not tempfile's private 0600.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder
        .tempfile_in(dir)
        .map_err(|e| Error::io(IoOp::CreateTemp, path, e))?;
    if let Some(m) = existing {
        tmp.as_file()
            .set_permissions(m.permissions())
            .map_err(|e| Error::io(IoOp::Write, path, e))?;
    }
    {
        let mut w = BufWriter::with_capacity(1 << 20, tmp.as_file());
        fill(&mut w).map_err(|e| Error::io(IoOp::Write, path, e))?;
        w.flush().map_err(|e| Error::io(IoOp::Write, path, e))?;
    }
    let persisted = match replace {
        Replace::Allowed => tmp.persist(&target),
        // A file made while this one was written is not replaced either.
        Replace::Never => tmp.persist_noclobber(&target),
    };
    persisted.map_err(|e| match e.error.kind() {
        std::io::ErrorKind::AlreadyExists if replace == Replace::Never => Error::OutputExists {
            path: path.to_path_buf(),
        },
        _ => Error::io(IoOp::Rename, path, e.error),
    })?;
    Ok(())
}

/// Writes bytes to `path` atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}
