//! What a command reads and writes, as gzip and zstd do it: `-` is standard input or
//! output; an output is named from its input when none is given; an output that exists is
//! replaced only with `--force`; an input is never written over, by any name; messages go
//! to standard error, so standard output holds data alone and commands compose in pipes
//! (spec §9.2).

use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};

use salvq_encoder::Error;
use salvq_render::error::IoOp;
use salvq_render::io::Replace;

/// The path that stands for standard input or output.
pub(crate) const STDIO: &str = "-";

/// Whether `path` is `-`.
pub(crate) fn is_stdio(path: &Path) -> bool {
    path == Path::new(STDIO)
}

/// The options every command shares: how its messages and outputs behave.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ctx {
    /// Replace an output that exists.
    pub(crate) force: bool,
    /// No messages on standard error but errors.
    pub(crate) quiet: bool,
}

impl Ctx {
    /// A message for a person: one line on standard error, unless `--quiet`.
    pub(crate) fn say(&self, line: &str) {
        if !self.quiet {
            eprintln!("{line}");
        }
    }

    /// The output a command writes, checked before any work: `given`, or else `input`'s
    /// name with `extension` (`scene.ply` → `scene.salvq`), in the input's folder. Refused:
    /// a folder, a folder that does not exist, one of `inputs` (always), a file that exists
    /// (without `--force`), binary data for a terminal (without `--force`).
    pub(crate) fn output(
        &self,
        given: Option<&Path>,
        input: &Path,
        extension: &str,
        inputs: &[&Path],
    ) -> Result<Output, Error> {
        let path = match given {
            Some(p) => p.to_path_buf(),
            None => default_name(input, extension).unwrap_or_else(|why| usage(why)),
        };
        self.check(path, inputs)
    }

    /// Checks an output named by the user (see [`Ctx::output`]).
    pub(crate) fn check(&self, path: PathBuf, inputs: &[&Path]) -> Result<Output, Error> {
        if is_stdio(&path) {
            if std::io::stdout().is_terminal() && !self.force {
                usage(
                    "-o -: standard output is a terminal, and the output is binary data; \
                     redirect it (`-o - > file`, `| next-command`), name a file, or pass --force",
                );
            }
            return Ok(Output {
                path,
                replace: Replace::Allowed,
            });
        }
        salvq_render::io::check_output(&path)?;
        for input in inputs.iter().filter(|i| !is_stdio(i)) {
            if same_file(input, &path) {
                return Err(salvq_render::Error::OutputIsInput {
                    path: path.clone(),
                    input: input.to_path_buf(),
                }
                .into());
            }
        }
        let metadata = std::fs::metadata(&path);
        let exists = metadata.as_ref().is_ok_and(|m| m.is_file());
        if exists && !self.force {
            return Err(salvq_render::Error::OutputExists { path }.into());
        }
        // A regular file is written beside itself and renamed: a folder that takes no new
        // file (read-only, say) fails now, not after the work.
        if metadata.map_or(true, |m| m.is_file()) {
            let dir = match path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            tempfile::Builder::new()
                .prefix(".salvq-")
                .suffix(".tmp")
                .tempfile_in(dir)
                .map_err(|e| Error::io(IoOp::CreateTemp, &path, e))?;
        }
        let replace = if self.force {
            Replace::Allowed
        } else {
            Replace::Never
        };
        Ok(Output { path, replace })
    }
}

/// An output, checked ([`Ctx::output`]), and whether it may replace a file.
#[derive(Debug, Clone)]
pub(crate) struct Output {
    /// The path, or `-`.
    pub(crate) path: PathBuf,
    /// [`Replace::Never`] unless `--force`: a file that appears while the command works is
    /// not replaced either.
    pub(crate) replace: Replace,
}

impl Output {
    /// Whether the output is standard output.
    pub(crate) fn is_stdout(&self) -> bool {
        is_stdio(&self.path)
    }

    /// The output as messages name it.
    pub(crate) fn shown(&self) -> String {
        if self.is_stdout() {
            "standard output".into()
        } else {
            self.path.display().to_string()
        }
    }

    /// The file's extension, lower case (`""` for none, standard output, a device).
    pub(crate) fn extension(&self) -> String {
        let regular = std::fs::metadata(&self.path).map_or(true, |m| m.is_file());
        if self.is_stdout() || !regular {
            return String::new();
        }
        self.path
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default()
    }

    /// Refuses an output whose extension names another format than the one written (none,
    /// standard output and devices pass): `what` and `extensions` say what it is written as.
    pub(crate) fn require_extension(
        &self,
        allowed: &[&str],
        what: &'static str,
        extensions: &'static str,
    ) -> Result<(), Error> {
        let ext = self.extension();
        if ext.is_empty() || allowed.contains(&ext.as_str()) {
            return Ok(());
        }
        Err(salvq_render::Error::OutputExtension {
            path: self.path.clone(),
            what,
            extensions,
        }
        .into())
    }

    /// Writes the output atomically ([`salvq_render::io::write_atomic_as`]).
    pub(crate) fn write(
        &self,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<(), Error> {
        Ok(salvq_render::io::write_atomic_as(
            &self.path,
            self.replace,
            fill,
        )?)
    }

    /// Writes `bytes`.
    pub(crate) fn write_bytes(&self, bytes: &[u8]) -> Result<(), Error> {
        self.write(|w| w.write_all(bytes))
    }
}

/// A usage error, reported as clap reports its own (`error: …` on standard error, exit
/// status 2), before any work.
pub(crate) fn usage(message: &str) -> ! {
    clap::Error::raw(
        clap::error::ErrorKind::ArgumentConflict,
        format!("{message}\n"),
    )
    .exit()
}

/// `input`'s name with `extension` in place of its own, in its folder; or why there is none.
fn default_name(input: &Path, extension: &str) -> Result<PathBuf, &'static str> {
    if is_stdio(input) {
        return Err(
            "the input is standard input, so no output name follows from it: name \
                    the output with -o FILE, or -o - for standard output",
        );
    }
    let name = input.with_extension(extension);
    if name == input {
        return Err(
            "the default output name would be the input's own: name the output with \
                    -o FILE",
        );
    }
    Ok(name)
}

/// Whether `a` and `b` name the same existing file (through links, other spellings).
fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

/// Reads an input whole: a file, or standard input for `-`.
pub(crate) fn read_input(path: &Path) -> Result<Vec<u8>, Error> {
    if !is_stdio(path) {
        return Ok(salvq_render::io::read_file(path)?);
    }
    let mut bytes = Vec::new();
    std::io::stdin()
        .lock()
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(IoOp::Read, path, e))?;
    Ok(bytes)
}

/// Prints `value` as JSON on standard output (a closed pipe ends the command quietly).
pub(crate) fn print_json(value: &impl serde::Serialize) {
    crate::print_text(&format!(
        "{}\n",
        serde_json::to_string_pretty(value).unwrap_or_default()
    ));
}

/// Refuses `--json` where the data itself goes to standard output (a usage error).
pub(crate) fn json_beside(json: bool, output: &Output) {
    if json && output.is_stdout() {
        usage(
            "--json: the output (-o -) already takes standard output; write the output to a \
             file, or leave out --json",
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_names_swap_the_extension() {
        assert_eq!(
            default_name(Path::new("a/scene.ply"), "salvq").unwrap(),
            Path::new("a/scene.salvq")
        );
        assert_eq!(
            default_name(Path::new("scene.salvq"), "ply").unwrap(),
            Path::new("scene.ply")
        );
        assert_eq!(
            default_name(Path::new("noext"), "ply").unwrap(),
            Path::new("noext.ply")
        );
        assert!(default_name(Path::new("-"), "ply")
            .unwrap_err()
            .contains("-o FILE"));
        assert!(default_name(Path::new("x.salvq"), "salvq").is_err());
    }
}
