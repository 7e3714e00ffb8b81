//! The encoder's errors: an input it does not read (Annex A.8.1), a lattice search or a fit
//! that failed (§7.3, Annex A.5), and the errors it passes on from the decoder crate (a model
//! that fails validation, §2) and from the scene files it reads (PLY, safetensors).

use std::fmt;

/// An error of the encoder (and of the tools built on it).
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The decoder crate's error: a model that breaks a rule of §2, or a stream (§9).
    Stream(salvq::Error),
    /// Reading or writing a scene file, or rendering (Annex A.1, Annex C, §9.2).
    Files(salvq_render::Error),
    /// An encoder input is a file of a kind the encoder does not read (Annex A.8.1).
    UnsupportedInput {
        /// What the input is.
        found: std::borrow::Cow<'static, str>,
        /// How to convert it.
        hint: &'static str,
    },
    /// An encoder option does not apply to this input (Annex A.4).
    OptionUnsupported {
        /// The option.
        option: &'static str,
        /// Why it does not apply.
        reason: &'static str,
        /// What to do instead.
        hint: &'static str,
    },
    /// The lattice search could not quantize a group (§7.3).
    LatticeSearchFailed {
        /// The tensor.
        tensor: &'static str,
        /// The anchor, when one is to blame.
        anchor: Option<u64>,
        /// Why.
        reason: String,
    },
    /// A render-PSNR target is above what the scene renders at with every value at the
    /// finest step the encoder tries (Annex A.8.2): no allocation meets it.
    TargetUnreachable {
        /// The rate.
        rate: u8,
        /// Its target, dB.
        target_db: f64,
        /// The scene's render PSNR at the finest steps, dB.
        ceiling_db: f64,
    },
    /// The fit of a basis or of scale rows to the model's anchors (Annex A.5) failed.
    FitFailed {
        /// The tensor.
        tensor: &'static str,
        /// Why.
        reason: String,
    },
}

/// The encoder's result type.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// The error's class, as `salvq` stderr spells it.
    pub fn class(&self) -> &'static str {
        match self {
            Error::Stream(e) => e.class(),
            Error::Files(e) => e.class(),
            Error::UnsupportedInput { .. } => "UnsupportedInput",
            Error::OptionUnsupported { .. } => "OptionUnsupported",
            Error::LatticeSearchFailed { .. } => "LatticeSearchFailed",
            Error::FitFailed { .. } => "FitFailed",
            Error::TargetUnreachable { .. } => "TargetUnreachable",
        }
    }

    /// The spec section whose rule this error reports.
    pub fn spec_section(&self) -> &'static str {
        match self {
            Error::Stream(e) => e.spec_section(),
            Error::Files(e) => e.spec_section(),
            Error::UnsupportedInput { .. } => "Annex A.8.1",
            Error::OptionUnsupported { .. } => "Annex A.4",
            Error::LatticeSearchFailed { .. } => "§7.3",
            Error::FitFailed { .. } => "Annex A.5",
            Error::TargetUnreachable { .. } => "Annex A.8.2",
        }
    }

    /// An I/O error on `path` during `op` (§9.2).
    pub fn io(
        op: salvq_render::error::IoOp,
        path: &std::path::Path,
        source: std::io::Error,
    ) -> Error {
        Error::Files(salvq_render::Error::io(op, path, source))
    }

    /// The decoder's error inside, if that is what this is.
    pub fn as_stream(&self) -> Option<&salvq::Error> {
        match self {
            Error::Stream(e) | Error::Files(salvq_render::Error::Stream(e)) => Some(e),
            _ => None,
        }
    }
}

/// An encoder error equals a decoder error when it passes that error on.
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

impl From<salvq_render::Error> for Error {
    fn from(e: salvq_render::Error) -> Self {
        match e {
            // One wrapping of the decoder's error, whichever way it came.
            salvq_render::Error::Stream(e) => Error::Stream(e),
            e => Error::Files(e),
        }
    }
}

impl From<salvq::camera::SettingInvalid> for Error {
    fn from(e: salvq::camera::SettingInvalid) -> Self {
        salvq_render::Error::from(e).into()
    }
}

impl From<salvq::neural::NeuralError> for Error {
    fn from(e: salvq::neural::NeuralError) -> Self {
        salvq_render::Error::from(e).into()
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Stream(e) => return write!(f, "{e}"),
            Error::Files(e) => return write!(f, "{e}"),
            Error::UnsupportedInput { found, hint } => write!(
                f,
                "the input is {found}, which this command does not read: {hint}"
            )?,
            Error::OptionUnsupported {
                option,
                reason,
                hint,
            } => write!(f, "{option}: {reason}; {hint}")?,
            Error::LatticeSearchFailed {
                tensor,
                anchor,
                reason,
            } => match anchor {
                Some(a) => write!(f, "{tensor}: anchor {a}: {reason}")?,
                None => write!(f, "{tensor}: {reason}")?,
            },
            Error::FitFailed { tensor, reason } => write!(f, "{tensor}: fit failed: {reason}")?,
            Error::TargetUnreachable {
                rate,
                target_db,
                ceiling_db,
            } => write!(
                f,
                "rate {rate}: the target {target_db} dB is above {ceiling_db:.1} dB, what this \
                 scene renders at with every value at the finest step the encoder tries (8 ring \
                 views at 512x384); give targets up to {:.0} dB",
                ceiling_db.floor()
            )?,
        }
        write!(f, " [{}]", self.spec_section())
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Stream(e) => Some(e),
            Error::Files(e) => Some(e),
            _ => None,
        }
    }
}
