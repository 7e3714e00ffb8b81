//! File signature (spec §1.2): magic, format version, file flags.

use crate::error::{Error, Field, Result, Structure};

/// The first 8 bytes of every stream: `\x89 S A L V Q \r \n`. The high byte catches 7-bit
/// transfers, the CR LF pair catches line-ending conversion (as PNG's signature does).
pub const MAGIC: [u8; 8] = [0x89, b'S', b'A', b'L', b'V', b'Q', 0x0d, 0x0a];

/// Format major version this crate implements.
pub const FORMAT_MAJOR: u8 = 0;
/// Format minor version this crate implements.
pub const FORMAT_MINOR: u8 = 15;

/// Bytes in the signature: magic (8), major (1), minor (1), flags (2).
pub const SIGNATURE_LEN: usize = 12;

/// File flags with no bit defined: all reserved in 0.1 (§1.2).
pub const FILE_FLAGS_DEFINED: u16 = 0;

/// The decoded signature.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Signature {
    /// Format major version (§1.2.1).
    pub major: u8,
    /// Format minor version (§1.2.1).
    pub minor: u8,
    /// `file_flags`: every bit is reserved and zero in this version (§1.2).
    pub flags: u16,
}

impl Signature {
    /// The signature this crate writes.
    pub fn current() -> Self {
        Signature {
            major: FORMAT_MAJOR,
            minor: FORMAT_MINOR,
            flags: 0,
        }
    }

    /// The 12 signature bytes of Table 1-1: magic, major, minor, little-endian flags.
    pub fn to_bytes(self) -> [u8; SIGNATURE_LEN] {
        let mut b = [0u8; SIGNATURE_LEN];
        b[..8].copy_from_slice(&MAGIC);
        b[8] = self.major;
        b[9] = self.minor;
        b[10..12].copy_from_slice(&self.flags.to_le_bytes());
        b
    }

    /// Parses and checks the signature (§1.2 steps 1-4); returns it and the bytes after it.
    pub fn parse(data: &[u8]) -> Result<(Signature, &[u8])> {
        let [m0, m1, m2, m3, m4, m5, m6, m7, major, minor, f0, f1, rest @ ..] = data else {
            // Step 1: a stream shorter than the signature still gets its magic checked, so
            // a non-SALVQ file is reported as such rather than as truncated.
            let n = data.len().min(8);
            if data[..n] != MAGIC[..n] {
                let mut found = [0u8; 8];
                found[..n].copy_from_slice(&data[..n]);
                return Err(Error::SignatureMismatch { found });
            }
            return Err(Error::Truncated {
                structure: Structure::Signature,
                needed: SIGNATURE_LEN as u64,
                available: data.len() as u64,
            });
        };
        let magic = [*m0, *m1, *m2, *m3, *m4, *m5, *m6, *m7];
        if magic != MAGIC {
            return Err(Error::SignatureMismatch { found: magic });
        }
        // Step 2: a different major version is a different format.
        if *major != FORMAT_MAJOR {
            return Err(Error::UnsupportedMajorVersion {
                found: *major,
                supported: FORMAT_MAJOR,
            });
        }
        // Step 3: major 0 is a draft series; each minor is its own format (§1.2.1).
        if *major == 0 && *minor != FORMAT_MINOR {
            return Err(Error::UnsupportedMinorVersion {
                major: *major,
                found: *minor,
                supported: FORMAT_MINOR,
            });
        }
        // Step 4: reserved flag bits must be zero.
        let flags = u16::from_le_bytes([*f0, *f1]);
        if flags & !FILE_FLAGS_DEFINED != 0 {
            return Err(Error::ReservedBitsSet {
                field: Field::FileFlags,
                value: flags.into(),
            });
        }
        Ok((
            Signature {
                major: *major,
                minor: *minor,
                flags,
            },
            rest,
        ))
    }
}
