//! `manifest.json` (spec §11.4): one entry per vector — what it exercises, its stream's
//! SHA-256, and for a valid vector each decode's expected hashes, expected-output file and
//! float tolerances; for a must-fail vector the error class a decoder must report.

use serde::{Deserialize, Serialize};

/// The file name of the manifest inside a vectors folder.
pub const MANIFEST_FILE: &str = "manifest.json";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// The format version the vectors are written in (`major.minor`).
    pub format_version: String,
    /// Where the hashes, tolerances and decoder contract are defined.
    pub defined_in: String,
    pub vectors: Vec<VectorEntry>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VectorKind {
    /// A conformant stream: decodes to the expected canonical form at each listed rate.
    Valid,
    /// A non-conformant stream: a decoder must stop with `error_class`.
    MustFail,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VectorEntry {
    pub name: String,
    pub kind: VectorKind,
    /// The stream, relative to the manifest.
    pub file: String,
    pub bytes: u64,
    pub sha256: String,
    pub description: String,
    /// Spec sections the vector exercises (for valid vectors, beyond the sections every
    /// valid vector exercises, `base_sections` of the README's coverage table).
    pub sections: Vec<String>,
    /// Valid vectors: one decode per rate, then the region decodes (§11.7); must-fail
    /// vectors: region decodes that must succeed (the fault is in a tile they leave out).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub decodes: Vec<ExpectedDecode>,
    /// Must-fail vectors: the rate the decoder is asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<u8>,
    /// Must-fail vectors: the error class (Table 9-1 spelling).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_class: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedDecode {
    pub rate: u8,
    /// The reference decoder's canonical form (§11.1), relative to the manifest.
    pub expected: String,
    /// §11.2 integer-domain hash: must match exactly.
    pub integer_sha256: String,
    /// §11.2 float hash: matches for a decoder with the reference's binary32 order.
    pub float_sha256: String,
    /// §11.3: how far a float value may be from the expected one.
    pub tolerance: Tolerance,
    /// Tensors of the canonical form left out of the expected file (large lossless tensors):
    /// the integer hash alone checks them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub omitted: Vec<String>,
    /// A region decode (§10.3.1, §11.7): the box asked for; absent for a whole decode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<RegionDecode>,
}

/// A region decode's box and, to help a decoder's author, what it selects (§11.7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionDecode {
    /// Min x, y, z, max x, y, z (binary64; JSON numbers that read back exactly).
    #[serde(rename = "box")]
    pub region: [f64; 6],
    /// The selected tiles (informative: follows from `TILS` and the box).
    pub tiles: Vec<u32>,
    /// Anchors (Gaussians) in the output (informative).
    pub count: u64,
    /// The rule this decode pins.
    pub pins: String,
}

/// §11.3: a decoded float `a` matches the expected `b` when `|a − b| ≤ relative·|b| + absolute`
/// (or both are NaN, or the same infinity).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Tolerance {
    pub relative: f64,
    pub absolute: f64,
}

impl Tolerance {
    /// §11.3: 2^−14 relative and 2^−14 absolute.
    pub const STANDARD: Tolerance = Tolerance {
        relative: 1.0 / 16384.0,
        absolute: 1.0 / 16384.0,
    };

    /// Whether `a` matches the expected `b`.
    pub fn matches(&self, a: f32, b: f32) -> bool {
        if a.is_nan() || b.is_nan() {
            return a.is_nan() && b.is_nan();
        }
        if a.is_infinite() || b.is_infinite() {
            return a == b;
        }
        (f64::from(a) - f64::from(b)).abs() <= self.relative * f64::from(b).abs() + self.absolute
    }
}
