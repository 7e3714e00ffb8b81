//! The hand-written messages of [`Error`]: the rule broken, the values, then the section.

use std::fmt;

use super::Error;

/// Writes a multi-dimensional index as `[i, j, k]`.
struct Index<'a>(&'a [u64]);

impl fmt::Display for Index<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[")?;
        for (i, v) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{v}")?;
        }
        f.write_str("]")
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Every variant has a message in one of the three; one added without a message
        // still prints its fields.
        if !(write_framing(self, f)? || write_payload(self, f)? || write_model(self, f)?) {
            write!(f, "{self:?}")?;
        }
        write!(f, " [{}]", self.spec_section())
    }
}

/// Writes the message of an error of the signature or the chunk framing (§1.2 – §1.5);
/// false (nothing written) for the others.
fn write_framing(e: &Error, f: &mut fmt::Formatter<'_>) -> Result<bool, fmt::Error> {
    use Error::*;
    match e {
        SignatureMismatch { found } => write!(
            f,
            "file signature: not a SALVQ stream (first bytes {:02x?})",
            found
        )?,
        Truncated {
            structure,
            needed,
            available,
        } => write!(
            f,
            "{structure}: stream truncated ({needed} bytes needed, {available} available)"
        )?,
        UnsupportedMajorVersion { found, supported } => write!(
            f,
            "file signature: format major version {found} is not supported (this decoder implements major {supported})"
        )?,
        UnsupportedMinorVersion {
            major,
            found,
            supported,
        } => write!(
            f,
            "file signature: draft format {major}.{found} is not supported (a major-0 decoder reads only its own minor, {major}.{supported})"
        )?,
        ReservedBitsSet { field, value } => write!(
            f,
            "{}: reserved bits are set (value 0x{value:x})",
            field.spec_name()
        )?,
        ChunkLengthPastEnd {
            tag,
            length,
            available,
        } => write!(
            f,
            "chunk {tag}: length {length} runs past the end of the stream ({available} bytes left)"
        )?,
        ChunkCrcMismatch {
            tag,
            stored,
            computed,
        } => write!(
            f,
            "chunk {tag}: CRC-32C mismatch (stored 0x{stored:08x}, computed 0x{computed:08x})"
        )?,
        ChunkTagInvalid { tag } => write!(
            f,
            "chunk tag {:02x?}: bytes must be ASCII letters (first) or letters and digits",
            tag
        )?,
        UnknownCriticalChunk { tag } => write!(f, "chunk {tag}: unknown critical chunk")?,
        ChunkOrder { found, expected } => write!(
            f,
            "chunk {found}: out of order (the next critical chunk must be {expected})"
        )?,
        TrailingData { bytes } => {
            write!(f, "stream: {bytes} bytes follow the SEND chunk")?
        }
        ChunkSizeMismatch {
            tag,
            expected,
            found,
        } => write!(
            f,
            "chunk {tag}: payload is {found} bytes, the header implies {expected}"
        )?,
        UnknownCodingMethod { tag, method } => {
            write!(f, "chunk {tag}: unknown coding method {method}")?
        }
        _ => return Ok(false),
    }
    Ok(true)
}

/// Writes the message of an error in a payload's fields, limits, entropy-coded data, tiles
/// or octree; false (nothing written) for the others.
fn write_payload(e: &Error, f: &mut fmt::Formatter<'_>) -> Result<bool, fmt::Error> {
    use Error::*;
    match e {
        FieldOutOfRange {
            field,
            value,
            min,
            max,
        } => write!(
            f,
            "{}: value {value} is outside [{min}, {max}]",
            field.spec_name()
        )?,
        DecodedSizeMismatch { stated, computed } => write!(
            f,
            "HEAD: decoded_bytes is {stated}, the dimensions imply {computed}"
        )?,
        LimitExceeded {
            limit,
            requested,
            allowed,
        } => write!(
            f,
            "limits: {limit} of {requested} exceeds the decoder limit {allowed}"
        )?,
        PaddingBitsSet { tag } => write!(f, "chunk {tag}: padding bits are not zero")?,
        CoordinateOutOfRange {
            anchor,
            axis,
            value,
            coord_bits,
        } => write!(
            f,
            "anchor.voxel[{anchor}, {axis}]: coordinate {value} does not fit in coord_bits = {coord_bits}"
        )?,
        AnsStreamInvalid { tag, fault } => {
            write!(f, "chunk {tag}: entropy-coded data invalid: {}", fault.describe())?
        }
        EscapeOverflow {
            tag,
            symbol,
            prefix_bits,
        } => write!(
            f,
            "chunk {tag}: symbol {symbol}: escape prefix of {prefix_bits} bits exceeds the maximum"
        )?,
        ScaleIndexOutOfRange {
            tag,
            symbol,
            scale_index,
            max,
        } => write!(
            f,
            "chunk {tag}: symbol {symbol}: scale index {scale_index} is outside [0, {max}]"
        )?,
        LatticeDimension {
            field,
            lattice,
            dim,
            rule,
        } => write!(
            f,
            "{}: lattice '{lattice}' on a group of dimension {dim}: {rule}",
            field.spec_name()
        )?,
        TileOrder { tile } => write!(
            f,
            "TILS/APOS: tile {tile}'s first voxel does not follow the previous tile's last in Morton order"
        )?,
        TileBoxMismatch {
            tile,
            stated,
            actual,
        } => write!(
            f,
            "TILS: tile {tile}: box {stated:?} is not its anchors' box {actual:?}"
        )?,
        OctreeInvalid {
            rule,
            depth,
            count,
            anchors,
        } => write!(
            f,
            "APOS octree: {rule} (depth {depth}: {count}, anchor_count {anchors})"
        )?,
        RateNotCoded { rate, rate_mask } => write_rate_not_coded(f, *rate, *rate_mask)?,
        _ => return Ok(false),
    }
    Ok(true)
}

/// Writes the message of an error of the scene model's validation (§2); false (nothing
/// written) for the others.
fn write_model(e: &Error, f: &mut fmt::Formatter<'_>) -> Result<bool, fmt::Error> {
    use Error::*;
    match e {
        NonFiniteValue { tensor, index } => {
            write!(f, "{tensor}{}: value is not finite", Index(index))?
        }
        ValueNotPositive {
            tensor,
            index,
            value,
        } => write!(f, "{tensor}{}: value {value} must be > 0", Index(index))?,
        ValueInvalid {
            tensor,
            index,
            value,
            allowed,
        } => write!(
            f,
            "{tensor}{}: value {value} is not allowed (allowed: {allowed})",
            Index(index)
        )?,
        TensorMissing { tensor } => write!(f, "{tensor}: required tensor is missing")?,
        TensorUnexpected { name } => {
            write!(f, "{name}: tensor is not part of the model schema")?
        }
        TensorDtype {
            tensor,
            expected,
            found,
        } => write!(f, "{tensor}: dtype is {found}, expected {expected}")?,
        TensorRank {
            tensor,
            expected,
            found,
        } => write!(f, "{tensor}: has {found} dimensions, expected {expected}")?,
        TensorShape {
            tensor,
            expected,
            found,
        } => write!(
            f,
            "{tensor}: shape is {}, expected {}",
            Index(found),
            Index(expected)
        )?,
        BasisSingular { tensor, index } => write!(
            f,
            "{tensor}[{index}]: singular value is zero (the lattice basis is singular)"
        )?,
        BasisIllConditioned {
            tensor,
            condition,
            max,
        } => write!(
            f,
            "{tensor}: lattice basis condition number {condition:.3e} exceeds {max:.0e}"
        )?,
        BasisNotOrthogonal {
            tensor,
            index,
            deviation,
            tolerance,
        } => write!(
            f,
            "{tensor}: not orthogonal, (M^T M - I)[{}, {}] = {deviation:.3e} exceeds {tolerance:.0e}",
            index[0], index[1]
        )?,
        _ => return Ok(false),
    }
    Ok(true)
}

/// "rate 3 has no symbol layer in this stream; it holds rates 0, 1 (rate_mask 0x3)".
fn write_rate_not_coded(f: &mut fmt::Formatter<'_>, rate: u8, rate_mask: u64) -> fmt::Result {
    write!(
        f,
        "rate {rate} has no symbol layer in this stream; it holds "
    )?;
    match rate_mask.count_ones() {
        0 => write!(f, "none")?,
        1 => write!(f, "rate ")?,
        _ => write!(f, "rates ")?,
    }
    let coded = (0..64u8).filter(|r| rate_mask >> r & 1 == 1);
    for (i, r) in coded.enumerate() {
        write!(f, "{}{r}", if i == 0 { "" } else { ", " })?;
    }
    write!(f, " (rate_mask {rate_mask:#x})")
}
