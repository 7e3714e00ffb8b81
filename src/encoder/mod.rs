//! The encoder: validates a model, puts its anchors in canonical order, converts the context
//! MLP to fixed point, quantizes and entropy-codes the anchor attributes, and writes the
//! chunks in the order of spec Table 1-3. Encoding choices never change what a decoder must do.

pub mod attributes;
pub mod convert;
pub mod float_prior;

use serde::{Deserialize, Serialize};

use crate::container::chunk::{write_chunk, ChunkTag};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::Signature;
use crate::entropy::GaussianTables;
use crate::error::{Error, Field, Result};
use crate::hyperprior::prior::Prior;
use crate::hyperprior::GridLayout;
use crate::model::validate::validate_model;
use crate::model::{decoded_bytes, names, SceneModel};

pub use attributes::GroupStats;

/// Options that change what the encoder writes.
#[derive(Debug, Clone, Default)]
pub struct EncodeOptions {
    /// Text for an `encd` ancillary chunk (§1.7); `None` writes no such chunk.
    pub encoder_note: Option<String>,
    /// The rate (index into the gains) whose symbols the stream carries.
    pub rate: u8,
    /// Write the `ests` ancillary chunk with the encoder's statistics (§1.7).
    pub statistics: bool,
}

/// What the encoder measured (written to `ests` when asked; `salvq info` shows it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EncodeReport {
    pub anchors: u64,
    pub rate: u8,
    pub groups: Vec<GroupStats>,
    pub mask_bits: u64,
    pub mask_bytes: u64,
    /// Touched / total hash-grid entries (§5.2).
    pub grid_entries_stored: u64,
    pub grid_entries_total: u64,
}

/// Encodes a model with default options.
pub fn encode(model: &SceneModel) -> Result<Vec<u8>> {
    encode_with_options(model, &EncodeOptions::default())
}

/// Encodes a model. Fails, writing nothing, if the model breaks any rule of spec §2.
pub fn encode_with_options(model: &SceneModel, options: &EncodeOptions) -> Result<Vec<u8>> {
    encode_with_report(model, options).map(|(s, _)| s)
}

/// Encodes a model and reports what each part cost.
pub fn encode_with_report(
    model: &SceneModel,
    options: &EncodeOptions,
) -> Result<(Vec<u8>, EncodeReport)> {
    encode_full(model, options).map(|e| (e.stream, e.report))
}

/// Everything the encoder produces: the stream, its report, and the model a conformant
/// decoder must output for it (bit for bit), which tests use as their oracle.
pub struct Encoded {
    pub stream: Vec<u8>,
    pub report: EncodeReport,
    pub expected: SceneModel,
}

/// Encodes a model, returning the stream, the report and the expected decoded model.
pub fn encode_full(model: &SceneModel, options: &EncodeOptions) -> Result<Encoded> {
    validate_model(model)?;
    // §6.6: version 0.2 codes every group with the identity basis.
    for (q, tensor) in [
        (&model.quant_feat, names::QUANT_FEAT[2]),
        (&model.quant_scaling, names::QUANT_SCALING[2]),
    ] {
        if q.basis.is_some() {
            return Err(Error::QuantizerUnsupported { tensor });
        }
    }
    if options.rate >= model.dims.rates {
        return Err(Error::FieldOutOfRange {
            field: Field::CodedRate,
            value: options.rate.into(),
            min: 0,
            max: u64::from(model.dims.rates) - 1,
        });
    }
    let canonical;
    let m = if model.is_canonical() {
        model
    } else {
        canonical = model.to_canonical_order();
        &canonical
    };
    let d = &m.dims;
    let coord_bits = m.coord_bits();
    let head = Preflight {
        dims: d.clone(),
        coord_bits,
        origin: m.origin,
        voxel_size: m.voxel_size,
        decoded_bytes: decoded_bytes(d),
        coded_rate: options.rate,
    };
    // §5: the integer prior, converted from the model's float context MLP.
    let layout = GridLayout::new(d, coord_bits);
    let x = convert::grid_inputs(m, &layout);
    let int_mlp = convert::convert_context_mlp(&m.mlp_grid, layout.features(), &x)?;
    drop(x);
    let rate = usize::from(options.rate);
    let quant = [&m.quant_feat, &m.quant_scaling, &m.quant_offsets];
    let prior = Prior::new(d, coord_bits, int_mlp.clone(), quant, rate);
    let float = float_prior::FloatPrior::new(m, coord_bits, rate);
    let touched = layout.touched(&m.anchors.voxel, d.entries_3d(), d.entries_2d());
    let tables = GaussianTables::standard();
    let coded = attributes::code_attributes(m, &prior, &float, tables)?;

    let report = EncodeReport {
        anchors: d.anchors.into(),
        rate: options.rate,
        groups: coded.stats.to_vec(),
        mask_bits: coded.mask_bits,
        mask_bytes: coded.amsk.len() as u64,
        grid_entries_stored: touched
            .iter()
            .map(|t| t.iter().filter(|&&u| u).count() as u64)
            .sum(),
        grid_entries_total: d.entries_3d() + 3 * d.entries_2d(),
    };
    let mut out = Vec::with_capacity(coded.chunks.iter().map(Vec::len).sum::<usize>() + (1 << 20));
    out.extend_from_slice(&Signature::current().to_bytes());
    write_chunk(&mut out, ChunkTag::HEAD, &head.to_payload());
    if let Some(note) = &options.encoder_note {
        write_chunk(&mut out, ChunkTag::ENCD, note.as_bytes());
    }
    write_chunk(&mut out, ChunkTag::MLPS, &payload::write_mlps(&int_mlp, m));
    write_chunk(&mut out, ChunkTag::QUAN, &payload::write_quan(m));
    write_chunk(&mut out, ChunkTag::APOS, &payload::write_apos(&m.anchors));
    write_chunk(
        &mut out,
        ChunkTag::GRID,
        &payload::write_grid(&m.grid, &touched, usize::from(d.grid_channels)),
    );
    write_chunk(&mut out, ChunkTag::AMSK, &coded.amsk);
    let [afea, ascl, aoff] = &coded.chunks;
    write_chunk(&mut out, ChunkTag::AFEA, afea);
    write_chunk(&mut out, ChunkTag::ASCL, ascl);
    write_chunk(&mut out, ChunkTag::AOFF, aoff);
    if options.statistics {
        let json = serde_json::to_vec(&report).unwrap_or_default();
        write_chunk(&mut out, ChunkTag::ESTS, &json);
    }
    write_chunk(&mut out, ChunkTag::SEND, &[]);
    // The decoded model: reconstructed attributes, the integer MLP's values, +1 at untouched
    // grid entries (§5.2, §6.6.2).
    let c = usize::from(d.grid_channels);
    let keep = |t: &[i8], used: &[bool]| -> Vec<i8> {
        t.iter()
            .enumerate()
            .map(|(i, &v)| if used[i / c] { v } else { 1 })
            .collect()
    };
    let [feat, scaling, offsets] = coded.recon;
    let expected = SceneModel {
        anchors: crate::model::Anchors {
            voxel: m.anchors.voxel.clone(),
            mask: m.anchors.mask.clone(),
            feat,
            scaling,
            offsets,
        },
        grid: crate::model::HashGrid {
            grid_3d: keep(&m.grid.grid_3d, &touched[0]),
            grid_xy: keep(&m.grid.grid_xy, &touched[1]),
            grid_xz: keep(&m.grid.grid_xz, &touched[2]),
            grid_yz: keep(&m.grid.grid_yz, &touched[3]),
        },
        mlp_grid: int_mlp.to_float(),
        ..m.clone()
    };
    Ok(Encoded {
        stream: out,
        report,
        expected,
    })
}
