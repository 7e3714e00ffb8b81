//! The errors of the scene-file and rendering tools: a standard 3DGS PLY that breaks the
//! layout (Annex C.3), a model file that is not safetensors (Annex A.1), a scene without
//! neural Gaussians (C.1), a render setting out of range (C.2), a file operation that failed
//! (§9.2), or the decoder's own error (§9, Table 9-1) from a stream or a model it validated.

use std::fmt;
use std::path::PathBuf;

use salvq_bitstream::error::Field;

/// What a file operation was doing when it failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IoOp {
    /// Reading a file.
    Read,
    /// Writing the output.
    Write,
    /// Creating the temporary file an output is written to.
    CreateTemp,
    /// Renaming the temporary file over the output.
    Rename,
}

/// An error of the scene-file and rendering tools.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The decoder's error: a stream that breaks a rule, or a model that fails validation
    /// (spec §9, Table 9-1).
    Stream(salvq::Error),
    /// The model file is not a valid safetensors file (Annex A.1).
    InterchangeFormat {
        /// What the safetensors reader reported.
        detail: String,
    },
    /// A standard 3DGS PLY file's header breaks a rule of the layout (Annex C.3).
    PlyHeaderInvalid {
        /// The header line, from 1; 0 when the rule concerns the header as a whole.
        line: u32,
        /// The rule broken.
        rule: &'static str,
    },
    /// A PLY vertex property that a 3DGS Gaussian needs is absent (Annex C.3).
    PlyPropertyMissing {
        /// The property.
        property: &'static str,
    },
    /// The `f_rest_*` properties are not `f_rest_0 … f_rest_{n−1}` with n = 0, 9, 24 or 45
    /// (SH degree 0 … 3; Annex C.3).
    PlyShCoefficients {
        /// The number of `f_rest_*` properties.
        count: u32,
    },
    /// The PLY body is shorter than its element counts times their record sizes (Annex C.3).
    PlyTruncated {
        /// The PLY element.
        element: String,
        /// Its record count.
        count: u64,
        /// Bytes per record.
        stride: u64,
        /// Bytes that are left.
        available: u64,
    },
    /// A PLY vertex value that a Gaussian uses is NaN, or infinite other than the opacity
    /// logit (Annex C.3).
    PlyValueNotFinite {
        /// The vertex's index.
        vertex: u64,
        /// The property.
        property: String,
    },
    /// The model's shape has no Scaffold-GS neural Gaussians (Annex C.1): the scaling must
    /// have 6 dimensions, the view inputs 3 or 4.
    NeuralGaussiansUnsupported {
        /// The dimension.
        field: Field,
        /// Its value.
        value: u64,
        /// The rule broken.
        rule: &'static str,
    },
    /// A render setting (image size, view index, field of view, elevation) is outside its
    /// range (Annex C.2).
    RenderSettingInvalid {
        /// The setting.
        setting: &'static str,
        /// Its value.
        value: f64,
        /// The rule broken.
        rule: &'static str,
    },
    /// A camera file (the Inria 3DGS `cameras.json`, a COLMAP `cameras.txt` or `images.txt`)
    /// breaks its format, or describes a camera the renderer cannot draw (Annex C.2).
    CameraFileInvalid {
        /// The file.
        path: PathBuf,
        /// The line, from 1; 0 when the problem concerns the file as a whole.
        line: u64,
        /// The field, as the file's format names it (`rotation`, `MODEL`, `QW` …).
        field: &'static str,
        /// What is wrong, with the value found.
        problem: String,
    },
    /// The output file exists and the command was not allowed to replace it (§9.2).
    OutputExists {
        /// The output.
        path: PathBuf,
    },
    /// The output is one of the command's inputs (the same file, by any name): never
    /// written over (§9.2).
    OutputIsInput {
        /// The output as named.
        path: PathBuf,
        /// The input it is.
        input: PathBuf,
    },
    /// The output's extension names a format this output is not written in (§9.2).
    OutputExtension {
        /// The output.
        path: PathBuf,
        /// What the output can be (`a scene stream (explicit profile) decodes to a 3DGS PLY`).
        what: &'static str,
        /// The extensions that name it (`.ply`).
        extensions: &'static str,
    },
    /// A file operation failed (§9.2: no partial output is left behind).
    Io {
        /// What was being done.
        op: IoOp,
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// The result type of the scene-file and rendering tools.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An I/O error on `path` during `op`.
    pub fn io(op: IoOp, path: &std::path::Path, source: std::io::Error) -> Error {
        Error::Io {
            op,
            path: path.to_path_buf(),
            source,
        }
    }

    /// The decoder's error inside, if that is what this is.
    pub fn as_stream(&self) -> Option<&salvq::Error> {
        match self {
            Error::Stream(e) => Some(e),
            _ => None,
        }
    }

    /// The error's class, as `salvq` stderr spells it (the decoder's class for its errors).
    pub fn class(&self) -> &'static str {
        match self {
            Error::Stream(e) => e.class(),
            Error::InterchangeFormat { .. } => "InterchangeFormat",
            Error::PlyHeaderInvalid { .. } => "PlyHeaderInvalid",
            Error::PlyPropertyMissing { .. } => "PlyPropertyMissing",
            Error::PlyShCoefficients { .. } => "PlyShCoefficients",
            Error::PlyTruncated { .. } => "PlyTruncated",
            Error::PlyValueNotFinite { .. } => "PlyValueNotFinite",
            Error::NeuralGaussiansUnsupported { .. } => "NeuralGaussiansUnsupported",
            Error::RenderSettingInvalid { .. } => "RenderSettingInvalid",
            Error::CameraFileInvalid { .. } => "CameraFileInvalid",
            Error::OutputExists { .. } => "OutputExists",
            Error::OutputIsInput { .. } => "OutputIsInput",
            Error::OutputExtension { .. } => "OutputExtension",
            Error::Io { .. } => "Io",
        }
    }

    /// The spec section whose rule this error reports.
    pub fn spec_section(&self) -> &'static str {
        match self {
            Error::Stream(e) => e.spec_section(),
            Error::InterchangeFormat { .. } => "§A.1",
            Error::NeuralGaussiansUnsupported { .. } => "§C.1",
            Error::RenderSettingInvalid { .. } | Error::CameraFileInvalid { .. } => "§C.2",
            Error::PlyHeaderInvalid { .. }
            | Error::PlyPropertyMissing { .. }
            | Error::PlyShCoefficients { .. }
            | Error::PlyTruncated { .. }
            | Error::PlyValueNotFinite { .. } => "§C.3",
            Error::OutputExists { .. }
            | Error::OutputIsInput { .. }
            | Error::OutputExtension { .. }
            | Error::Io { .. } => "§9.2",
        }
    }
}

/// A tool error equals a decoder error when it passes that error on.
impl PartialEq<salvq::Error> for Error {
    fn eq(&self, other: &salvq::Error) -> bool {
        self.as_stream() == Some(other)
    }
}

impl From<salvq::Error> for Error {
    fn from(e: salvq::Error) -> Self {
        Error::Stream(e)
    }
}

impl From<salvq::camera::SettingInvalid> for Error {
    fn from(e: salvq::camera::SettingInvalid) -> Self {
        Error::RenderSettingInvalid {
            setting: e.setting,
            value: e.value,
            rule: e.rule,
        }
    }
}

impl From<salvq::neural::NeuralError> for Error {
    fn from(e: salvq::neural::NeuralError) -> Self {
        match e {
            salvq::neural::NeuralError::Unsupported { field, value, rule } => {
                Error::NeuralGaussiansUnsupported { field, value, rule }
            }
            salvq::neural::NeuralError::Shape(e) => Error::Stream(e),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            // The decoder's message ends with its section already.
            Error::Stream(e) => return write!(f, "{e}"),
            Error::InterchangeFormat { detail } => {
                write!(f, "model file: not a valid safetensors file ({detail})")?
            }
            Error::PlyHeaderInvalid { line: 0, rule } => write!(f, "PLY header: {rule}")?,
            Error::PlyHeaderInvalid { line, rule } => {
                write!(f, "PLY header, line {line}: {rule}")?
            }
            Error::PlyPropertyMissing { property } => write!(
                f,
                "PLY vertex element: property '{property}' is missing (a 3DGS Gaussian needs it)"
            )?,
            Error::PlyShCoefficients { count } => write!(
                f,
                "PLY vertex element: {count} f_rest properties; SH needs f_rest_0 … f_rest_(n-1) with n = 0, 9, 24 or 45"
            )?,
            Error::PlyTruncated {
                element,
                count,
                stride,
                available,
            } => write!(
                f,
                "PLY element '{element}': {count} records of {stride} bytes need {} bytes, {available} available",
                u128::from(*count) * u128::from(*stride)
            )?,
            Error::PlyValueNotFinite { vertex, property } => write!(
                f,
                "PLY vertex {vertex}: property '{property}' is not finite"
            )?,
            Error::NeuralGaussiansUnsupported { field, value, rule } => write!(
                f,
                "{} = {value}: no Scaffold-GS neural Gaussians: {rule}",
                field.spec_name()
            )?,
            Error::RenderSettingInvalid {
                setting,
                value,
                rule,
            } => write!(f, "render setting {setting} = {value}: {rule}")?,
            Error::CameraFileInvalid {
                path,
                line: 0,
                field,
                problem,
            } => write!(f, "camera file {}: {field}: {problem}", path.display())?,
            Error::CameraFileInvalid {
                path,
                line,
                field,
                problem,
            } => write!(
                f,
                "camera file {}, line {line}, field {field}: {problem}",
                path.display()
            )?,
            Error::OutputExists { path } => write!(
                f,
                "{} exists; not replaced (-f / --force replaces it)",
                path.display()
            )?,
            Error::OutputIsInput { path, input } if path == input => write!(
                f,
                "{} is this command's input; an input is never written over",
                path.display()
            )?,
            Error::OutputIsInput { path, input } => write!(
                f,
                "{} is the same file as the input {}; an input is never written over",
                path.display(),
                input.display()
            )?,
            Error::OutputExtension {
                path,
                what,
                extensions,
            } => write!(
                f,
                "{}: {what} ({extensions}); the output's extension picks the format",
                path.display()
            )?,
            Error::Io { op, path, source } => {
                let verb = match op {
                    IoOp::Read => "cannot read",
                    IoOp::Write => "cannot write",
                    IoOp::CreateTemp => "cannot create a temporary file beside",
                    IoOp::Rename => "cannot move the finished file to",
                };
                write!(f, "{verb} {}: {source}", path.display())?
            }
        }
        write!(f, " [{}]", self.spec_section())
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Stream(e) => Some(e),
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}
