//! The decoder (spec §1.5 decoding process): signature, then chunks in order, each payload
//! decoded against the preflight; the anchor attributes are decoded together once `SEND`
//! has been read (§6.6.2). It never panics on any input, sizes every allocation from a
//! preflight that passed [`Limits`], and reports the first broken rule.

use crate::attributes::{read_attributes, read_masks};
use crate::container::chunk::{ChunkReader, ChunkTag};
use crate::container::payload;
use crate::container::preflight::Preflight;
use crate::container::signature::{Signature, SIGNATURE_LEN};
use crate::entropy::GaussianTables;
use crate::error::{Error, Result, Structure};
use crate::hyperprior::prior::Prior;
use crate::hyperprior::{GridLayout, IntMlp};
use crate::limits::Limits;
use crate::model::{Anchors, GroupQuantizer, HashGrid, Mlp, SceneModel};
use crate::quantizer::GroupLattices;

/// Decodes a whole stream with the default [`Limits`], at its lowest coded rate.
pub fn decode(data: &[u8]) -> Result<SceneModel> {
    decode_with_limits(data, &Limits::default())
}

/// What to decode and under which limits.
#[derive(Debug, Clone, Default)]
pub struct DecodeOptions {
    pub limits: Limits,
    /// The rate whose symbol layer to decode (§7.4); `None`: the lowest coded rate.
    pub rate: Option<u8>,
}

/// The critical chunk expected at position `i` of a stream with `layers` symbol layers
/// (§1.5 Table 1-3 with §7.4: the layer chunks repeat once per layer).
pub(crate) fn expected_critical(i: usize, layers: usize) -> ChunkTag {
    const SHARED: usize = 6;
    const LAYER: [ChunkTag; 3] = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];
    match i.checked_sub(SHARED) {
        None => ChunkTag::CRITICAL_ORDER[i],
        Some(j) if j < 3 * layers => LAYER[j % 3],
        Some(_) => ChunkTag::SEND,
    }
}

/// Parts of the model decoded so far, filled chunk by chunk.
#[derive(Default)]
struct Partial<'a> {
    head: Option<Preflight>,
    mlps: Option<(IntMlp, [Mlp; 3])>,
    quan: Option<[GroupQuantizer; 3]>,
    voxel: Option<Vec<[u32; 3]>>,
    touched: Option<[Vec<bool>; 4]>,
    grid: Option<HashGrid>,
    mask: Option<Vec<u8>>,
    attributes: [&'a [u8]; 3],
    /// The rate being decoded.
    rate: u8,
}

fn missing(tag: ChunkTag) -> Error {
    Error::ChunkOrder {
        found: ChunkTag::SEND,
        expected: tag,
    }
}

/// Decodes a whole stream under `limits`, at its lowest coded rate.
pub fn decode_with_limits(data: &[u8], limits: &Limits) -> Result<SceneModel> {
    decode_with_options(
        data,
        &DecodeOptions {
            limits: *limits,
            rate: None,
        },
    )
}

/// Decodes one symbol layer of a stream (§7.4): every chunk's framing, CRC and order is
/// checked, the shared chunks and the selected layer are decoded, other layers' payloads
/// are not parsed.
pub fn decode_with_options(data: &[u8], options: &DecodeOptions) -> Result<SceneModel> {
    let limits = &options.limits;
    // §1.2: signature and version.
    let (_sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut next_critical = 0usize;
    let mut p = Partial::default();
    // Layers in the stream and the index of the selected one, known once HEAD is read.
    let (mut layers, mut selected) = (0usize, 0usize);
    let tables = GaussianTables::standard();
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
        if !tag.is_critical() {
            // §1.5 rules 1-2: ancillary chunks after HEAD are skipped.
            if p.head.is_none() {
                return Err(Error::ChunkOrder {
                    found: tag,
                    expected: ChunkTag::HEAD,
                });
            }
            continue;
        }
        // §1.5 rules 0 and 3.
        if !ChunkTag::CRITICAL_ORDER.contains(&tag) {
            return Err(Error::UnknownCriticalChunk { tag });
        }
        let expected = if p.head.is_none() {
            ChunkTag::HEAD
        } else {
            expected_critical(next_critical, layers)
        };
        if tag != expected {
            return Err(Error::ChunkOrder {
                found: tag,
                expected,
            });
        }
        next_critical += 1;
        let bytes = chunk.payload;
        if tag == ChunkTag::HEAD {
            let head = Preflight::parse(bytes, limits)?;
            let rate;
            (rate, selected, layers) = head.select_layer(options.rate)?;
            p.rate = rate;
            p.head = Some(head);
            continue;
        }
        // §7.4: the layer this chunk belongs to, if it is a layer chunk.
        let layer = next_critical.checked_sub(7).map(|j| j / 3);
        let head = p.head.as_ref().ok_or(missing(ChunkTag::HEAD))?;
        let d = &head.dims;
        match tag {
            ChunkTag::MLPS => p.mlps = Some(payload::read_mlps(bytes, d)?),
            ChunkTag::QUAN => p.quan = Some(payload::read_quan(bytes, d)?),
            ChunkTag::APOS => {
                let voxel = payload::read_apos(bytes, head, tables)?;
                // §5.2: the touched grid entries follow from the voxels.
                let layout = GridLayout::new(d, head.coord_bits);
                p.touched = Some(layout.touched(&voxel, d.entries_3d(), d.entries_2d()));
                p.voxel = Some(voxel);
            }
            ChunkTag::GRID => {
                let touched = p.touched.as_ref().ok_or(missing(ChunkTag::APOS))?;
                p.grid = Some(payload::read_grid(bytes, d, touched)?);
            }
            ChunkTag::AMSK => p.mask = Some(read_masks(bytes, d, tables)?),
            ChunkTag::AFEA | ChunkTag::ASCL | ChunkTag::AOFF if layer != Some(selected) => {}
            ChunkTag::AFEA => p.attributes[0] = bytes,
            ChunkTag::ASCL => p.attributes[1] = bytes,
            ChunkTag::AOFF => p.attributes[2] = bytes,
            _ => {
                // SEND: empty, last, nothing after it (§1.5 rules 4-5).
                if !bytes.is_empty() {
                    return Err(Error::ChunkSizeMismatch {
                        tag,
                        expected: 0,
                        found: bytes.len() as u64,
                    });
                }
                let trailing = reader.remaining().len();
                if trailing != 0 {
                    return Err(Error::TrailingData {
                        bytes: trailing as u64,
                    });
                }
                return assemble(p, tables);
            }
        }
    }
}

/// §6.6.2: decodes the attributes and builds the model once every critical chunk has been
/// read (the order rules guarantee each part is present).
fn assemble(p: Partial<'_>, tables: &GaussianTables) -> Result<SceneModel> {
    let head = p.head.ok_or(missing(ChunkTag::HEAD))?;
    let (int_mlp, [mlp_opacity, mlp_cov, mlp_color]) = p.mlps.ok_or(missing(ChunkTag::MLPS))?;
    let [quant_feat, quant_scaling, quant_offsets] = p.quan.ok_or(missing(ChunkTag::QUAN))?;
    let voxel = p.voxel.ok_or(missing(ChunkTag::APOS))?;
    let grid = p.grid.ok_or(missing(ChunkTag::GRID))?;
    let mask = p.mask.ok_or(missing(ChunkTag::AMSK))?;
    let d = &head.dims;
    let prior = Prior::new(
        d,
        head.coord_bits,
        int_mlp,
        [&quant_feat, &quant_scaling, &quant_offsets],
        usize::from(p.rate),
    );
    // §7.2: the reconstruction matrices of the feature and scaling groups.
    // §7.6: one matrix per spatial region.
    let lattices = [
        GroupLattices::new(d.feat_lattice, usize::from(d.feat_dim), &quant_feat),
        GroupLattices::new(
            d.scaling_lattice,
            usize::from(d.scaling_dim),
            &quant_scaling,
        ),
    ];
    let attrs = read_attributes(
        p.attributes,
        d,
        &voxel,
        &mask,
        &grid,
        &prior,
        &lattices,
        tables,
    )?;
    Ok(SceneModel {
        origin: head.origin,
        voxel_size: head.voxel_size,
        anchors: Anchors {
            voxel,
            mask,
            feat: attrs.feat,
            scaling: attrs.scaling,
            offsets: attrs.offsets,
        },
        grid,
        mlp_grid: prior.mlp.to_float(),
        mlp_opacity,
        mlp_cov,
        mlp_color,
        quant_feat,
        quant_scaling,
        quant_offsets,
        dims: head.dims,
    })
}
