//! The `HEAD` chunk (spec §1.4): everything a decoder needs to size its work before it
//! decodes anything: dimensions, geometry, and the decoded model's total size.

use crate::container::bytes::{PayloadReader, PayloadWriter};
use crate::container::chunk::ChunkTag;
use crate::error::{Error, Field, Result};
use crate::limits::{LimitKind, Limits};
use crate::model::validate::{check_dim_fields, check_field, check_geometry, check_lattices};
use crate::model::{decoded_bytes, Dims, LatticeKind};

/// `head_flags`: no bit is defined in this version (all reserved, zero).
const HEAD_FLAGS_DEFINED: u8 = 0;

/// The decoded `HEAD` payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Preflight {
    /// The scene's dimensions (§2.1), from the `HEAD` fields of Table 1-4.
    pub dims: Dims,
    /// Bits per voxel coordinate: every coordinate is < 2^coord_bits.
    pub coord_bits: u8,
    /// World position of voxel (0, 0, 0) (Table 2-1 `geometry.origin`).
    pub origin: [f32; 3],
    /// Voxel edge length in world units, finite and > 0 (Table 2-1 `geometry.voxel_size`).
    pub voxel_size: f32,
    /// Sum of the sizes of every decoded tensor (spec Table 2-1).
    pub decoded_bytes: u64,
    /// Bit i set: the stream carries a symbol layer for rate i (§7.4); at least one bit,
    /// none at or above `rate_count`.
    pub rate_mask: u64,
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
        w.u8(0);
        w.u8(d.feat_lattice.code());
        w.u8(d.scaling_lattice.code());
        w.u16(d.feat_regions);
        w.u16(d.scaling_regions);
        w.u8(d.grid_channels);
        w.u8(d.res_3d.len() as u8);
        w.u8(d.res_2d.len() as u8);
        w.u8(d.log2_size_3d);
        w.u8(d.log2_size_2d);
        w.u16(d.context_hidden);
        w.u16(d.scaffold_hidden);
        w.u8(d.view_dims);
        w.u64(self.rate_mask);
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
        let feat_lattice = r.u8()?;
        let scaling_lattice = r.u8()?;
        let feat_regions = r.u16()?;
        let scaling_regions = r.u16()?;
        let grid_channels = r.u8()?;
        let levels_3d = r.u8()?;
        let levels_2d = r.u8()?;
        let log2_size_3d = r.u8()?;
        let log2_size_2d = r.u8()?;
        let context_hidden = r.u16()?;
        let scaffold_hidden = r.u16()?;
        let view_dims = r.u8()?;
        let rate_mask = r.u64()?;
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
            // Set below, once the fields before them are checked.
            feat_lattice: LatticeKind::Identity,
            scaling_lattice: LatticeKind::Identity,
            feat_regions,
            scaling_regions,
        };
        // Step 4: every field in its range (Table 1-4), in the spec's order: dimensions,
        // coord_bits, the lattice codes, their fit and regions, rate_mask, geometry.
        check_dim_fields(&dims)?;
        check_field(Field::CoordBits, coord_bits.into())?;
        let mut dims = dims;
        dims.feat_lattice = lattice_kind(Field::FeatLattice, feat_lattice)?;
        dims.scaling_lattice = lattice_kind(Field::ScalingLattice, scaling_lattice)?;
        check_lattices(&dims)?;
        let all_rates = u64::MAX >> (64 - u32::from(rates.clamp(1, 64)));
        if rate_mask == 0 || rate_mask & !all_rates != 0 {
            return Err(Error::FieldOutOfRange {
                field: Field::RateMask,
                value: rate_mask,
                min: 1,
                max: all_rates,
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
            rate_mask,
        })
    }

    /// The coded rates, ascending (§7.4: the order of the symbol layers).
    pub fn coded_rates(&self) -> Vec<u8> {
        (0..64u8)
            .filter(|&i| self.rate_mask >> i & 1 == 1)
            .collect()
    }

    /// §7.4: the rate to decode (`rate`, or the lowest coded one), its layer's index among the
    /// layers, and the number of layers. Errors: a rate ≥ M is **FieldOutOfRange** (field
    /// `rate`); a rate without a layer is **RateNotCoded**.
    pub fn select_layer(&self, rate: Option<u8>) -> Result<(u8, usize, usize)> {
        let coded = self.coded_rates();
        let rate = rate.unwrap_or(coded.first().copied().unwrap_or(0));
        if rate >= self.dims.rates {
            return Err(Error::FieldOutOfRange {
                field: Field::CodedRate,
                value: rate.into(),
                min: 0,
                max: u64::from(self.dims.rates) - 1,
            });
        }
        let index = coded
            .iter()
            .position(|&r| r == rate)
            .ok_or(Error::RateNotCoded {
                rate,
                rate_mask: self.rate_mask,
            })?;
        Ok((rate, index, coded.len()))
    }
}

/// Table 1-4: a lattice code (Table 7-1).
fn lattice_kind(field: Field, code: u8) -> Result<LatticeKind> {
    LatticeKind::from_code(code).ok_or(Error::FieldOutOfRange {
        field,
        value: code.into(),
        min: 0,
        max: 3,
    })
}
