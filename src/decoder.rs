//! The decoder (spec §1.5 decoding process): signature, then chunks in order, each payload
//! decoded against the preflight. It never panics on any input, sizes every allocation from
//! a preflight that passed [`Limits`], and reports the first broken rule.

use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::error::{Error, Result, Structure};
use crate::limits::Limits;
use crate::model::{names, Anchors, SceneModel};

/// Decodes a whole stream with the default [`Limits`].
pub fn decode(data: &[u8]) -> Result<SceneModel> {
    decode_with_limits(data, &Limits::default())
}

/// Parts of the model decoded so far, filled chunk by chunk.
#[derive(Default)]
struct Partial {
    head: Option<Preflight>,
    grid: Option<crate::model::HashGrid>,
    mlps: Option<[crate::model::Mlp; 4]>,
    quan: Option<[crate::model::GroupQuantizer; 3]>,
    voxel: Option<Vec<[u32; 3]>>,
    mask: Option<Vec<u8>>,
    feat: Option<Vec<f32>>,
    scaling: Option<Vec<f32>>,
    offsets: Option<Vec<f32>>,
}

/// Decodes a whole stream under `limits`.
pub fn decode_with_limits(data: &[u8], limits: &Limits) -> Result<SceneModel> {
    // §1.2: signature and version.
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut next_critical = 0usize;
    let mut p = Partial::default();
    loop {
        let Some(chunk) = reader.next_chunk()? else {
            // §1.5 rule 4: the stream ends only with SEND.
            return Err(Error::Truncated {
                structure: Structure::ChunkHeader,
                needed: 8,
                available: 0,
            });
        };
        let tag = chunk.tag;
        let expected = ChunkTag::CRITICAL_ORDER
            .get(next_critical)
            .copied()
            .unwrap_or(ChunkTag::SEND);
        if !tag.is_critical() {
            // §1.5 rule 2: ancillary chunks may stand anywhere after HEAD; unknown ones
            // are skipped (0.1 defines `encd`, which a decoder may also skip).
            if p.head.is_none() {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::HEAD,
                });
            }
            continue;
        }
        if !ChunkTag::CRITICAL_ORDER.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        next_critical += 1;
        let payload_bytes = chunk.payload;
        if tag == ChunkTag::HEAD {
            p.head = Some(Preflight::parse(payload_bytes, limits)?);
            continue;
        }
        let Some(head) = p.head.as_ref() else {
            return Err(Error::ChunkOrder {
                found: tag,
                expected: ChunkTag::HEAD,
            });
        };
        let d = &head.dims;
        let n = u64::from(d.anchors);
        let k = u64::from(d.offsets);
        match tag {
            ChunkTag::GRID => p.grid = Some(payload::read_grid(payload_bytes, d)?),
            ChunkTag::MLPS => p.mlps = Some(payload::read_mlps(payload_bytes, d)?),
            ChunkTag::QUAN => p.quan = Some(payload::read_quan(payload_bytes, d)?),
            ChunkTag::APOS => p.voxel = Some(payload::read_apos(payload_bytes, head)?),
            ChunkTag::AMSK => p.mask = Some(payload::read_amsk(payload_bytes, d)?),
            ChunkTag::AFEA => {
                p.feat = Some(payload::read_f32_chunk(
                    tag,
                    names::FEAT,
                    payload_bytes,
                    &[n, d.feat_dim.into()],
                )?)
            }
            ChunkTag::ASCL => {
                p.scaling = Some(payload::read_f32_chunk(
                    tag,
                    names::SCALING,
                    payload_bytes,
                    &[n, d.scaling_dim.into()],
                )?)
            }
            ChunkTag::AOFF => {
                p.offsets = Some(payload::read_f32_chunk(
                    tag,
                    names::OFFSETS,
                    payload_bytes,
                    &[n, k, 3],
                )?)
            }
            _ => {
                // SEND: empty, last, nothing after it (§1.5 rules 4-5).
                if !payload_bytes.is_empty() {
                    return Err(Error::ChunkSizeMismatch {
                        tag,
                        expected: 0,
                        found: payload_bytes.len() as u64,
                    });
                }
                let trailing = reader.remaining().len();
                if trailing != 0 {
                    return Err(Error::TrailingData {
                        bytes: trailing as u64,
                    });
                }
                return assemble(p);
            }
        }
    }
}

/// Builds the model once every critical chunk has been read (the order rules guarantee it).
fn assemble(p: Partial) -> Result<SceneModel> {
    let missing = |tag| Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    };
    let head = p.head.ok_or(missing(ChunkTag::HEAD))?;
    let [mlp_grid, mlp_opacity, mlp_cov, mlp_color] = p.mlps.ok_or(missing(ChunkTag::MLPS))?;
    let [quant_feat, quant_scaling, quant_offsets] = p.quan.ok_or(missing(ChunkTag::QUAN))?;
    Ok(SceneModel {
        origin: head.origin,
        voxel_size: head.voxel_size,
        dims: head.dims,
        anchors: Anchors {
            voxel: p.voxel.ok_or(missing(ChunkTag::APOS))?,
            mask: p.mask.ok_or(missing(ChunkTag::AMSK))?,
            feat: p.feat.ok_or(missing(ChunkTag::AFEA))?,
            scaling: p.scaling.ok_or(missing(ChunkTag::ASCL))?,
            offsets: p.offsets.ok_or(missing(ChunkTag::AOFF))?,
        },
        grid: p.grid.ok_or(missing(ChunkTag::GRID))?,
        mlp_grid,
        mlp_opacity,
        mlp_cov,
        mlp_color,
        quant_feat,
        quant_scaling,
        quant_offsets,
    })
}
