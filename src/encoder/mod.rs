//! The encoder: validates a model, puts its anchors in canonical order, writes the chunks
//! in the order of spec Table 1-3. Encoding choices never change what a decoder must do.

pub mod convert;

use crate::container::chunk::{write_chunk, ChunkTag};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::Signature;
use crate::error::Result;
use crate::model::validate::validate_model;
use crate::model::{decoded_bytes, SceneModel};

/// Options that change what the encoder writes without changing the decoded model.
#[derive(Debug, Clone, Default)]
pub struct EncodeOptions {
    /// Text for an `encd` ancillary chunk (§1.7); `None` writes no such chunk.
    pub encoder_note: Option<String>,
}

/// Encodes a model with default options.
pub fn encode(model: &SceneModel) -> Result<Vec<u8>> {
    encode_with_options(model, &EncodeOptions::default())
}

/// Encodes a model. Fails, writing nothing, if the model breaks any rule of spec §2.
pub fn encode_with_options(model: &SceneModel, options: &EncodeOptions) -> Result<Vec<u8>> {
    validate_model(model)?;
    let canonical;
    let m = if model.is_canonical() {
        model
    } else {
        canonical = model.to_canonical_order();
        &canonical
    };
    let head = Preflight {
        dims: m.dims.clone(),
        coord_bits: m.coord_bits(),
        origin: m.origin,
        voxel_size: m.voxel_size,
        decoded_bytes: decoded_bytes(&m.dims),
    };
    let mut out = Vec::with_capacity(head.decoded_bytes as usize + 256);
    out.extend_from_slice(&Signature::current().to_bytes());
    write_chunk(&mut out, ChunkTag::HEAD, &head.to_payload());
    if let Some(note) = &options.encoder_note {
        write_chunk(&mut out, ChunkTag::ENCD, note.as_bytes());
    }
    write_chunk(&mut out, ChunkTag::GRID, &payload::write_grid(&m.grid));
    write_chunk(&mut out, ChunkTag::MLPS, &payload::write_mlps(m));
    write_chunk(&mut out, ChunkTag::QUAN, &payload::write_quan(m));
    let a = &m.anchors;
    write_chunk(&mut out, ChunkTag::APOS, &payload::write_apos(a));
    write_chunk(&mut out, ChunkTag::AMSK, &payload::write_amsk(a));
    write_chunk(&mut out, ChunkTag::AFEA, &payload::write_f32_chunk(&a.feat));
    write_chunk(
        &mut out,
        ChunkTag::ASCL,
        &payload::write_f32_chunk(&a.scaling),
    );
    write_chunk(
        &mut out,
        ChunkTag::AOFF,
        &payload::write_f32_chunk(&a.offsets),
    );
    write_chunk(&mut out, ChunkTag::SEND, &[]);
    Ok(out)
}
