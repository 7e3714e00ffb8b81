//! The `HEAD` chunk (spec §1.4): everything a decoder needs to size its work before it
//! decodes anything: dimensions, geometry, and the decoded model's total size.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::error::{Error, Field, Result};
use crate::limits::{LimitKind, Limits};
use crate::model::validate::{check_dims, check_field, check_geometry};
use crate::model::{decoded_bytes, Dims};

/// `head_flags` bit 0: the feature group carries a general lattice basis.
pub const HEAD_FLAG_FEAT_BASIS: u8 = 1 << 0;
/// `head_flags` bit 1: the scaling group carries a general lattice basis (FS-SALVQ).
pub const HEAD_FLAG_SCALING_BASIS: u8 = 1 << 1;
const HEAD_FLAGS_DEFINED: u8 = HEAD_FLAG_FEAT_BASIS | HEAD_FLAG_SCALING_BASIS;

/// The decoded `HEAD` payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Preflight {
    pub dims: Dims,
    /// Bits per voxel coordinate: every coordinate is < 2^coord_bits.
    pub coord_bits: u8,
    pub origin: [f32; 3],
    pub voxel_size: f32,
    /// Sum of the sizes of every decoded tensor (spec Table 2-1).
    pub decoded_bytes: u64,
    /// The rate whose symbols the stream carries (0 .. rate_count - 1).
    pub coded_rate: u8,
}

impl Preflight {
    /// Serializes the payload in the order of spec Table 1-4.
    pub fn to_payload(&self) -> Vec<u8> {
        let d = &self.dims;
        let mut w = PayloadWriter::default();
        w.u32(d.anchors);
        w.u16(d.feat_dim);
        w.u16(d.offsets);
        w.u16(d.scaling_dim);
        w.u8(d.rates);
        w.u8(self.coord_bits);
        let mut flags = 0;
        if d.feat_basis {
            flags |= HEAD_FLAG_FEAT_BASIS;
        }
        if d.scaling_basis {
            flags |= HEAD_FLAG_SCALING_BASIS;
        }
        w.u8(flags);
        w.u8(d.grid_channels);
        w.u8(d.res_3d.len() as u8);
        w.u8(d.res_2d.len() as u8);
        w.u8(d.log2_size_3d);
        w.u8(d.log2_size_2d);
        w.u16(d.context_hidden);
        w.u16(d.scaffold_hidden);
        w.u8(d.view_dims);
        w.u8(self.coded_rate);
        for o in self.origin {
            w.f32(o);
        }
        w.f32(self.voxel_size);
        for &r in &d.res_3d {
            w.u16(r);
        }
        for &r in &d.res_2d {
            w.u16(r);
        }
        w.u64(self.decoded_bytes);
        w.buf
    }

    /// Parses and checks `HEAD` (§1.4 steps 1-6), including the decoder limits.
    pub fn parse(payload: &[u8], limits: &Limits) -> Result<Preflight> {
        let mut r = PayloadReader::new(ChunkTag::HEAD, payload);
        let anchors = r.u32()?;
        let feat_dim = r.u16()?;
        let offsets = r.u16()?;
        let scaling_dim = r.u16()?;
        let rates = r.u8()?;
        let coord_bits = r.u8()?;
        let flags = r.u8()?;
        let grid_channels = r.u8()?;
        let levels_3d = r.u8()?;
        let levels_2d = r.u8()?;
        let log2_size_3d = r.u8()?;
        let log2_size_2d = r.u8()?;
        let context_hidden = r.u16()?;
        let scaffold_hidden = r.u16()?;
        let view_dims = r.u8()?;
        let coded_rate = r.u8()?;
        let origin = [r.f32()?, r.f32()?, r.f32()?];
        let voxel_size = r.f32()?;
        // Step 2: reserved flag bits.
        if flags & !HEAD_FLAGS_DEFINED != 0 {
            return Err(Error::ReservedBitsSet {
                field: Field::HeadFlags,
                value: flags.into(),
            });
        }
        // Step 3: the level counts bound the resolution lists read next (at most 2 x 255
        // u16 values, read into vectors no longer than the payload allows).
        let mut res_3d = Vec::with_capacity(usize::from(levels_3d));
        for _ in 0..levels_3d {
            res_3d.push(r.u16()?);
        }
        let mut res_2d = Vec::with_capacity(usize::from(levels_2d));
        for _ in 0..levels_2d {
            res_2d.push(r.u16()?);
        }
        let stated = r.u64()?;
        r.finish()?;
        let dims = Dims {
            anchors,
            feat_dim,
            offsets,
            scaling_dim,
            rates,
            grid_channels,
            res_3d,
            res_2d,
            log2_size_3d,
            log2_size_2d,
            context_hidden,
            scaffold_hidden,
            view_dims,
            feat_basis: flags & HEAD_FLAG_FEAT_BASIS != 0,
            scaling_basis: flags & HEAD_FLAG_SCALING_BASIS != 0,
        };
        // Step 4: every field in its range (Table 1-4).
        check_dims(&dims)?;
        check_field(Field::CoordBits, coord_bits.into())?;
        if coded_rate >= rates {
            return Err(Error::FieldOutOfRange {
                field: Field::CodedRate,
                value: coded_rate.into(),
                min: 0,
                max: u64::from(rates) - 1,
            });
        }
        check_geometry(&origin, voxel_size)?;
        // Step 5: the stated size must be the size the dimensions imply.
        let computed = decoded_bytes(&dims);
        if stated != computed {
            return Err(Error::DecodedSizeMismatch { stated, computed });
        }
        // Step 6: limits, before anything is allocated from these numbers.
        limits.check(LimitKind::Anchors, anchors.into())?;
        limits.check(LimitKind::AllocationBytes, computed)?;
        Ok(Preflight {
            dims,
            coord_bits,
            origin,
            voxel_size,
            decoded_bytes: computed,
            coded_rate,
        })
    }
}
