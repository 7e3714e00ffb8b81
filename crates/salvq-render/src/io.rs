//! File helpers: whole-file reads, and atomic writes (temp file in the same folder, then
//! rename), so a failed command never leaves a partial output behind (spec §9.2).

use std::io::{BufWriter, Write};
use std::path::Path;

use crate::error::{Error, IoOp, Result};

/// Reads a whole file.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(IoOp::Read, path, e))
}

/// Writes `path` atomically: `fill` writes into a temporary file beside it, which is renamed
/// over `path` only when `fill` and the flush succeed; on any error the temporary is removed.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".salvq-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| Error::io(IoOp::CreateTemp, path, e))?;
    {
        let mut w = BufWriter::with_capacity(1 << 20, tmp.as_file());
        fill(&mut w).map_err(|e| Error::io(IoOp::Write, path, e))?;
        w.flush().map_err(|e| Error::io(IoOp::Write, path, e))?;
    }
    tmp.persist(path)
        .map_err(|e| Error::io(IoOp::Rename, path, e.error))?;
    Ok(())
}

/// Writes bytes to `path` atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}
