//! `GHED`, the explicit profile's preflight (spec §3.2): every number a decoder needs to size
//! its work before it decodes anything.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::error::{Error, Field, Result};
use crate::explicit::rest_per_channel;
use crate::limits::{LimitKind, Limits};

/// `GHED` payload bytes (Table 3-1).
pub const GHED_BYTES: usize = 4 + 1 + 1 + 1 + 8 + 12 + 8;

/// The decoded `GHED` (Table 3-1).
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianHeader {
    /// N: Gaussians in every layer.
    pub count: u32,
    /// SH degree, 0 … 3.
    pub sh_degree: u8,
    /// M: rates the quantizers have gains for.
    pub rate_count: u8,
    /// Bit r set: the stream carries the layer of rate r.
    pub rate_mask: u64,
    /// World position of voxel (0, 0, 0)'s corner in every layer.
    pub origin: [f32; 3],
    /// `head_flags` bit 0 (§3.8): the rates nest, the coarsest coded first and each finer
    /// one a refinement of the one before.
    pub progressive: bool,
}

/// `head_flags` bit 0: a progressive stream (§3.8).
pub const HEAD_FLAG_PROGRESSIVE: u8 = 1;

/// Binary32 values per decoded Gaussian: position 3, opacity 1, log-scales 3, rotation 4,
/// SH DC 3, SH rest 3·B (§3.6, Table 3-4).
pub fn values_per_gaussian(sh_degree: u8) -> u64 {
    14 + 3 * rest_per_channel(sh_degree) as u64
}

impl GaussianHeader {
    /// §3.2 step 5: bytes of the decoded Gaussians.
    pub fn decoded_bytes(&self) -> u64 {
        u64::from(self.count) * 4 * values_per_gaussian(self.sh_degree)
    }

    /// §9.1: bytes a decode holds besides the decoded Gaussians: each Gaussian's voxel
    /// (three `u32`) and, where the symbols are kept, its D coded values (`i32`), rotation
    /// index and size class (a byte each) and position refinement (three `u32`).
    pub fn working_bytes(&self, symbols: bool) -> u64 {
        let coded = values_per_gaussian(self.sh_degree) - 4;
        let per = 12 + if symbols { 4 * coded + 2 + 12 } else { 0 };
        u64::from(self.count) * per
    }

    /// The layers the stream carries, lowest rate first.
    pub fn coded_rates(&self) -> Vec<u8> {
        (0..self.rate_count)
            .filter(|r| self.rate_mask >> r & 1 == 1)
            .collect()
    }

    /// The coded rates in stream order (§3.7, §3.8): lowest first, or in a progressive
    /// stream the highest (coarsest) first.
    pub fn stream_rates(&self) -> Vec<u8> {
        let mut rates = self.coded_rates();
        if self.progressive {
            rates.reverse();
        }
        rates
    }

    /// The `GHED` payload (§3.2), as the encoder writes it.
    pub fn to_payload(&self) -> Vec<u8> {
        let mut w = PayloadWriter::default();
        w.u32(self.count);
        w.u8(self.sh_degree);
        w.u8(self.rate_count);
        w.u8(if self.progressive {
            HEAD_FLAG_PROGRESSIVE
        } else {
            0
        });
        w.u64(self.rate_mask);
        for v in self.origin {
            w.f32(v);
        }
        w.u64(self.decoded_bytes());
        w.buf
    }

    /// §3.2 steps 1-6.
    pub fn parse(payload: &[u8], limits: &Limits) -> Result<GaussianHeader> {
        let tag = ChunkTag::GHED;
        // Steps 1-2: the fields, then the exact length.
        let mut r = PayloadReader::new(tag, payload);
        let count = r.u32()?;
        let sh_degree = r.u8()?;
        let rate_count = r.u8()?;
        let flags = r.u8()?;
        let rate_mask = r.u64()?;
        let origin = [r.f32()?, r.f32()?, r.f32()?];
        let stated = r.u64()?;
        r.finish()?;
        // Step 3: reserved bits.
        if flags & !HEAD_FLAG_PROGRESSIVE != 0 {
            return Err(Error::ReservedBitsSet {
                field: Field::HeadFlags,
                value: u32::from(flags),
            });
        }
        // Step 4: ranges, in table order.
        let range = |field, value: u64, min: u64, max: u64| {
            if value < min || value > max {
                Err(Error::FieldOutOfRange {
                    field,
                    value,
                    min,
                    max,
                })
            } else {
                Ok(())
            }
        };
        range(Field::GaussianCount, count.into(), 1, u32::MAX.into())?;
        range(Field::ShDegree, sh_degree.into(), 0, 3)?;
        range(Field::RateCount, rate_count.into(), 1, 64)?;
        let allowed = if rate_count >= 64 {
            u64::MAX
        } else {
            (1u64 << rate_count) - 1
        };
        if rate_mask == 0 || rate_mask & !allowed != 0 {
            return Err(Error::FieldOutOfRange {
                field: Field::RateMask,
                value: rate_mask,
                min: 1,
                max: allowed,
            });
        }
        for (a, v) in origin.iter().enumerate() {
            if !v.is_finite() {
                return Err(Error::NonFiniteValue {
                    tensor: "GHED.origin",
                    index: vec![a as u64],
                });
            }
        }
        let head = GaussianHeader {
            count,
            sh_degree,
            rate_count,
            rate_mask,
            origin,
            progressive: flags & HEAD_FLAG_PROGRESSIVE != 0,
        };
        // Step 5: the decoded size.
        let computed = head.decoded_bytes();
        if stated != computed {
            return Err(Error::DecodedSizeMismatch { stated, computed });
        }
        // Step 6: limits, before anything is allocated.
        limits.check(LimitKind::Anchors, u64::from(count))?;
        limits.check(LimitKind::AllocationBytes, computed)?;
        Ok(head)
    }

    /// §3.7, §3.8: the selected rate (default: the lowest coded, the finest), its layer's
    /// index in stream order, and the layer count.
    pub fn select_layer(&self, rate: Option<u8>) -> Result<(u8, usize, usize)> {
        let coded = self.coded_rates();
        let rate = match rate {
            None => coded[0],
            Some(r) if r >= self.rate_count => {
                return Err(Error::FieldOutOfRange {
                    field: Field::CodedRate,
                    value: r.into(),
                    min: 0,
                    max: u64::from(self.rate_count) - 1,
                })
            }
            Some(r) if self.rate_mask >> r & 1 == 0 => {
                return Err(Error::RateNotCoded {
                    rate: r,
                    rate_mask: self.rate_mask,
                })
            }
            Some(r) => r,
        };
        let order = self.stream_rates();
        let index = order.iter().position(|&c| c == rate).unwrap_or(0);
        Ok((rate, index, coded.len()))
    }
}
