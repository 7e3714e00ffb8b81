//! The one public error type (spec §9: every failure names the rule it breaks).
//!
//! Every variant carries the values that broke the rule; `Display` is written by hand
//! and ends with the spec section, e.g.
//! `chunk AFEA: CRC-32C mismatch (stored 0x1234abcd, computed 0x0badf00d) [§1.3]`.

use std::fmt;

use crate::container::tag::ChunkTag;
use crate::limits::LimitKind;
use crate::model::Dtype;

/// Which fixed-size structure the stream ended inside (spec §1.2, §1.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Structure {
    /// The 12-byte file signature and version (§1.2).
    Signature,
    /// The 8-byte length + tag that opens a chunk (§1.3).
    ChunkHeader,
    /// The 4-byte CRC-32C that closes a chunk (§1.3).
    ChunkCrc,
    /// The fields inside a chunk payload (§1.4 onwards).
    Payload(ChunkTag),
}

impl fmt::Display for Structure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Structure::Signature => f.write_str("file signature"),
            Structure::ChunkHeader => f.write_str("chunk header"),
            Structure::ChunkCrc => f.write_str("chunk CRC"),
            Structure::Payload(tag) => write!(f, "{tag} payload"),
        }
    }
}

/// How an entropy-coded (ANS) payload broke the coder's rules (spec §6.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnsFault {
    /// The body's length is not a multiple of 4 bytes, or it is shorter than the 8-byte state.
    Framing,
    /// The initial state's top word is zero: the encoder never writes that.
    ZeroTopWord,
    /// Decoding needed more words than the payload holds.
    OutOfWords,
    /// Words are left over after the last symbol.
    WordsLeftOver,
    /// The state after the last symbol is not the encoder's initial state.
    StateNotFinal,
}

impl AnsFault {
    fn describe(self) -> &'static str {
        match self {
            AnsFault::Framing => "the payload is not a whole number of coder words holding a state",
            AnsFault::ZeroTopWord => "the coder state's top word is zero",
            AnsFault::OutOfWords => "decoding ran past the end of the coded words",
            AnsFault::WordsLeftOver => "coded words are left over after the last symbol",
            AnsFault::StateNotFinal => "the coder's final state is not the initial state",
        }
    }
}

/// Every error of the decoder (spec §9, Table 9-1): a stream that breaks a rule, or a model
/// that fails validation (§2). Tools built on the decoder wrap it in their own errors.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    // ---- container (§1) ----
    /// The first 8 bytes are not the SALVQ magic.
    SignatureMismatch {
        /// The first 8 bytes (fewer, zero-padded, for a shorter stream).
        found: [u8; 8],
    },
    /// The stream ended inside a fixed-size structure, or before the `SEND` chunk.
    Truncated {
        /// The structure the stream ended in.
        structure: Structure,
        /// Bytes the structure needs.
        needed: u64,
        /// Bytes that are left.
        available: u64,
    },
    /// The stream's major version is not one this decoder implements.
    UnsupportedMajorVersion {
        /// The stream's major version.
        found: u8,
        /// The version this decoder implements.
        supported: u8,
    },
    /// A draft (major 0) stream whose minor version differs from the implemented one.
    UnsupportedMinorVersion {
        /// The stream's major version.
        major: u8,
        /// The stream's minor version.
        found: u8,
        /// The minor version this decoder implements.
        supported: u8,
    },
    /// A bit that the spec reserves is set.
    ReservedBitsSet {
        /// The field holding the bits.
        field: Field,
        /// Its value.
        value: u32,
    },
    /// A chunk's declared length runs past the end of the stream.
    ChunkLengthPastEnd {
        /// The chunk.
        tag: ChunkTag,
        /// The declared payload length.
        length: u64,
        /// Bytes that are left.
        available: u64,
    },
    /// The CRC-32C stored after a chunk does not match its tag and payload.
    ChunkCrcMismatch {
        /// The chunk.
        tag: ChunkTag,
        /// The CRC stored after the chunk.
        stored: u32,
        /// The value computed from the stream.
        computed: u32,
    },
    /// A chunk tag byte is outside the allowed characters.
    ChunkTagInvalid {
        /// The tag's bytes.
        tag: [u8; 4],
    },
    /// A critical chunk this decoder does not know.
    UnknownCriticalChunk {
        /// The chunk.
        tag: ChunkTag,
    },
    /// A critical chunk appeared where the chunk order rules require another.
    ChunkOrder {
        /// The chunk found.
        found: ChunkTag,
        /// The chunk the order rules require there.
        expected: ChunkTag,
    },
    /// Bytes follow the `SEND` chunk.
    TrailingData {
        /// How many bytes follow.
        bytes: u64,
    },
    /// A payload's length differs from the length the header implies.
    ChunkSizeMismatch {
        /// The chunk.
        tag: ChunkTag,
        /// The payload length the header implies.
        expected: u64,
        /// The payload's length.
        found: u64,
    },
    /// A payload's coding-method byte names no method of this version.
    UnknownCodingMethod {
        /// The chunk.
        tag: ChunkTag,
        /// The method byte.
        method: u8,
    },
    /// A header field or model dimension is outside its allowed range.
    FieldOutOfRange {
        /// The field.
        field: Field,
        /// Its value.
        value: u64,
        /// The smallest allowed value.
        min: u64,
        /// The largest allowed value.
        max: u64,
    },
    /// The preflight's stated decoded size differs from the size its dimensions imply.
    DecodedSizeMismatch {
        /// The value the stream states.
        stated: u64,
        /// The value computed from the stream.
        computed: u64,
    },
    /// A decoder limit would be exceeded (checked before allocating).
    LimitExceeded {
        /// Which limit.
        limit: LimitKind,
        /// What the stream asks for.
        requested: u64,
        /// What the limit allows.
        allowed: u64,
    },
    /// Padding bits at the end of a bit-packed payload are not zero.
    PaddingBitsSet {
        /// The chunk.
        tag: ChunkTag,
    },
    /// An anchor voxel coordinate does not fit in `coord_bits` bits.
    CoordinateOutOfRange {
        /// The anchor, in canonical order.
        anchor: u64,
        /// The axis, 0 … 2 (x, y, z).
        axis: u8,
        /// Its value.
        value: i64,
        /// The coordinate width in bits.
        coord_bits: u8,
    },

    // ---- entropy coding (§6) ----
    /// The ANS-coded words of a chunk are malformed.
    AnsStreamInvalid {
        /// The chunk.
        tag: ChunkTag,
        /// How the coded words broke the coder's rules.
        fault: AnsFault,
    },
    /// An escaped symbol's Exp-Golomb prefix is longer than the spec allows.
    EscapeOverflow {
        /// The chunk.
        tag: ChunkTag,
        /// The symbol's index within the chunk's tile body.
        symbol: u64,
        /// The prefix length read.
        prefix_bits: u32,
    },
    /// A computed scale index lies outside the frequency tables.
    ScaleIndexOutOfRange {
        /// The chunk.
        tag: ChunkTag,
        /// The symbol's index within the chunk's tile body.
        symbol: u64,
        /// The computed index.
        scale_index: i64,
        /// The largest table index.
        max: u64,
    },

    /// A group's lattice does not fit its dimension (§7.1: E8 products need a multiple of
    /// 8, D_n at least 2).
    LatticeDimension {
        /// The group's lattice field.
        field: Field,
        /// The lattice's name.
        lattice: &'static str,
        /// The group's dimension.
        dim: u64,
        /// The rule broken.
        rule: &'static str,
    },
    /// The rate asked for has no symbol layer in the stream (§7.4).
    RateNotCoded {
        /// The rate asked for.
        rate: u8,
        /// The stream's mask of coded rates (bit r: rate r).
        rate_mask: u64,
    },
    /// A tile's first voxel does not come after the previous tile's last in Morton order
    /// (§10.1).
    TileOrder {
        /// The tile.
        tile: u32,
    },
    /// A tile's stated bounding box is not its anchors' (§10.1).
    TileBoxMismatch {
        /// The tile.
        tile: u32,
        /// The box `TILS` states (min x, y, z, max x, y, z).
        stated: [u32; 6],
        /// The box of its anchors.
        actual: [u32; 6],
    },
    /// The anchor octree breaks a rule of §8: more cells at a depth than anchors, or voxel
    /// counts that do not add up to the anchor count.
    OctreeInvalid {
        /// The rule broken.
        rule: &'static str,
        /// The octree depth.
        depth: u8,
        /// The count at that depth.
        count: u64,
        /// The anchors in the tile.
        anchors: u32,
    },

    // ---- tensor values (§2, decoder and encoder alike) ----
    /// A float value is NaN or infinite.
    NonFiniteValue {
        /// The tensor.
        tensor: &'static str,
        /// The element's index, outermost dimension first.
        index: Vec<u64>,
    },
    /// A value that must be positive (step, gain, voxel size) is not.
    ValueNotPositive {
        /// The tensor.
        tensor: &'static str,
        /// The element's index, outermost dimension first.
        index: Vec<u64>,
        /// Its value.
        value: f32,
    },
    /// An integer tensor holds a value outside its allowed set.
    ValueInvalid {
        /// The tensor.
        tensor: &'static str,
        /// The element's index, outermost dimension first.
        index: Vec<u64>,
        /// Its value.
        value: i64,
        /// The values allowed.
        allowed: &'static str,
    },

    // ---- model interchange and validation (Annex A, §2) ----
    /// A required tensor is absent.
    TensorMissing {
        /// The tensor.
        tensor: &'static str,
    },
    /// The model holds a tensor the schema does not define.
    TensorUnexpected {
        /// The tensor's name.
        name: String,
    },
    /// A tensor has the wrong dtype.
    TensorDtype {
        /// The tensor.
        tensor: &'static str,
        /// The dtype the schema requires.
        expected: Dtype,
        /// The dtype found.
        found: String,
    },
    /// A tensor has the wrong number of dimensions.
    TensorRank {
        /// The tensor.
        tensor: &'static str,
        /// The rank the schema requires.
        expected: u8,
        /// The rank found.
        found: u8,
    },
    /// A tensor has the wrong shape.
    TensorShape {
        /// The tensor.
        tensor: &'static str,
        /// The shape the schema requires.
        expected: Vec<u64>,
        /// The shape found.
        found: Vec<u64>,
    },
    /// A lattice basis has a zero singular value.
    BasisSingular {
        /// The tensor.
        tensor: &'static str,
        /// The index of the zero singular value.
        index: u64,
    },
    /// A lattice basis' condition number max|s| / min|s| exceeds the limit.
    BasisIllConditioned {
        /// The tensor.
        tensor: &'static str,
        /// The basis' condition number.
        condition: f64,
        /// The largest condition number allowed.
        max: f64,
    },
    /// A lattice basis factor U or V is not orthogonal within tolerance.
    BasisNotOrthogonal {
        /// The tensor.
        tensor: &'static str,
        /// The entry of UᵀU (or VᵀV) furthest from the identity.
        index: [u64; 2],
        /// The largest deviation from orthogonality.
        deviation: f64,
        /// The tolerance.
        tolerance: f64,
    },
    // ---- files ----
}

/// The section of §3 that defines an explicit-profile chunk.
fn explicit_section(tag: ChunkTag) -> Option<&'static str> {
    match &tag.0 {
        b"GHED" => Some("§3.2"),
        b"GQUA" => Some("§3.3"),
        b"GLAY" => Some("§3.4"),
        b"GATT" => Some("§3.5"),
        b"GREF" | b"GRSY" => Some("§3.8"),
        _ => None,
    }
}

/// The chunk tag a tensor name like `GQUA.step` starts with.
fn tensor_tag(tensor: &str) -> ChunkTag {
    let b = tensor.as_bytes();
    ChunkTag([b[0], b[1], b[2], b[3]])
}

impl Error {
    /// Whether the error says the bytes ended early: a chunk's header or payload runs past
    /// the end, or the stream ends before `SEND`.
    pub fn is_truncation(&self) -> bool {
        matches!(
            self,
            Error::Truncated {
                structure: Structure::ChunkHeader,
                ..
            } | Error::ChunkLengthPastEnd { .. }
        )
    }

    /// The spec section whose rule this error reports.
    pub fn spec_section(&self) -> &'static str {
        use Error::*;
        match self {
            SignatureMismatch { .. } | UnsupportedMajorVersion { .. } => "§1.2",
            UnsupportedMinorVersion { .. } => "§1.2",
            ReservedBitsSet {
                field: Field::FileFlags,
                ..
            } => "§1.2",
            ReservedBitsSet { .. } => "§1.4",
            // The explicit profile's chunks and fields (§3).
            Truncated {
                structure: Structure::Payload(tag),
                ..
            }
            | ChunkSizeMismatch { tag, .. }
                if explicit_section(*tag).is_some() =>
            {
                explicit_section(*tag).unwrap_or("§3")
            }
            FieldOutOfRange {
                field: Field::GaussianCount | Field::ShDegree,
                ..
            } => "§3.2",
            FieldOutOfRange {
                field:
                    Field::PredLevel
                    | Field::ScaleTable
                    | Field::RotationFreq
                    | Field::PredictFlag
                    | Field::Refine,
                ..
            } => "§3.4",
            FieldOutOfRange {
                field: Field::Factor,
                ..
            } => "§3.8",
            NonFiniteValue { tensor, .. }
            | ValueNotPositive { tensor, .. }
            | ValueInvalid { tensor, .. }
            | BasisSingular { tensor, .. }
                if tensor.len() > 4 && explicit_section(tensor_tag(tensor)).is_some() =>
            {
                explicit_section(tensor_tag(tensor)).unwrap_or("§3")
            }
            Truncated {
                structure: Structure::Signature,
                ..
            } => "§1.2",
            Truncated {
                structure: Structure::Payload(_),
                ..
            } => "§1.4",
            Truncated { .. } => "§1.3",
            ChunkLengthPastEnd { .. } | ChunkCrcMismatch { .. } | ChunkTagInvalid { .. } => "§1.3",
            UnknownCriticalChunk { .. } | ChunkOrder { .. } | TrailingData { .. } => "§1.5",
            FieldOutOfRange { .. } | DecodedSizeMismatch { .. } => "§1.4",
            ChunkSizeMismatch { tag, .. } if *tag == ChunkTag::HEAD => "§1.4",
            ChunkSizeMismatch { tag, .. } if *tag == ChunkTag::SEND => "§1.5",
            ChunkSizeMismatch { .. } | UnknownCodingMethod { .. } | PaddingBitsSet { .. } => "§1.6",
            LimitExceeded { .. } => "§9.1",
            CoordinateOutOfRange { .. } => "§2.2",
            AnsStreamInvalid { .. } => "§6.2",
            EscapeOverflow { .. } => "§6.4",
            ScaleIndexOutOfRange { .. } => "§6.3",
            LatticeDimension { .. } => "§7.1",
            RateNotCoded { .. } => "§7.4",
            OctreeInvalid { .. } => "§8",
            TileBoxMismatch { .. } | TileOrder { .. } => "§10.1",
            NonFiniteValue { .. } | ValueNotPositive { .. } | ValueInvalid { .. } => "§2.3",
            BasisSingular { .. } | BasisIllConditioned { .. } | BasisNotOrthogonal { .. } => "§2.6",
            TensorMissing { .. }
            | TensorUnexpected { .. }
            | TensorDtype { .. }
            | TensorRank { .. }
            | TensorShape { .. } => "§A.1",
        }
    }

    /// The variant's name, as conformance manifests and `salvq` stderr spell the error class.
    pub fn class(&self) -> &'static str {
        use Error::*;
        match self {
            SignatureMismatch { .. } => "SignatureMismatch",
            Truncated { .. } => "Truncated",
            UnsupportedMajorVersion { .. } => "UnsupportedMajorVersion",
            UnsupportedMinorVersion { .. } => "UnsupportedMinorVersion",
            ReservedBitsSet { .. } => "ReservedBitsSet",
            ChunkLengthPastEnd { .. } => "ChunkLengthPastEnd",
            ChunkCrcMismatch { .. } => "ChunkCrcMismatch",
            ChunkTagInvalid { .. } => "ChunkTagInvalid",
            UnknownCriticalChunk { .. } => "UnknownCriticalChunk",
            ChunkOrder { .. } => "ChunkOrder",
            TrailingData { .. } => "TrailingData",
            ChunkSizeMismatch { .. } => "ChunkSizeMismatch",
            UnknownCodingMethod { .. } => "UnknownCodingMethod",
            FieldOutOfRange { .. } => "FieldOutOfRange",
            DecodedSizeMismatch { .. } => "DecodedSizeMismatch",
            LimitExceeded { .. } => "LimitExceeded",
            PaddingBitsSet { .. } => "PaddingBitsSet",
            CoordinateOutOfRange { .. } => "CoordinateOutOfRange",
            AnsStreamInvalid { .. } => "AnsStreamInvalid",
            EscapeOverflow { .. } => "EscapeOverflow",
            ScaleIndexOutOfRange { .. } => "ScaleIndexOutOfRange",
            LatticeDimension { .. } => "LatticeDimension",
            RateNotCoded { .. } => "RateNotCoded",
            OctreeInvalid { .. } => "OctreeInvalid",
            TileBoxMismatch { .. } => "TileBoxMismatch",
            TileOrder { .. } => "TileOrder",
            NonFiniteValue { .. } => "NonFiniteValue",
            ValueNotPositive { .. } => "ValueNotPositive",
            ValueInvalid { .. } => "ValueInvalid",
            TensorMissing { .. } => "TensorMissing",
            TensorUnexpected { .. } => "TensorUnexpected",
            TensorDtype { .. } => "TensorDtype",
            TensorRank { .. } => "TensorRank",
            TensorShape { .. } => "TensorShape",
            BasisSingular { .. } => "BasisSingular",
            BasisIllConditioned { .. } => "BasisIllConditioned",
            BasisNotOrthogonal { .. } => "BasisNotOrthogonal",
        }
    }
}

mod display;
mod field;

pub use field::Field;

impl std::error::Error for Error {}

/// The crate's result type.
pub type Result<T> = std::result::Result<T, Error>;
