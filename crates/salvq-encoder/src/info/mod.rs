//! `salvq info`: what a stream holds, chunk by chunk, without decoding the payloads, and
//! the split into model bytes and anchor bytes (spec §1.3, §1.4).

pub mod explicit;
mod model_parts;

use model_parts::model_parts;
pub use model_parts::ModelPart;

use serde::Serialize;

use crate::error::Result;
use crate::EncodeReport;
use salvq_bitstream::container::chunk::{ChunkReader, ChunkTag, CHUNK_OVERHEAD};
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::container::signature::{Signature, SIGNATURE_LEN};
use salvq_bitstream::limits::Limits;
use salvq_bitstream::model::Dims;

/// What a chunk's bytes pay for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ByteClass {
    /// Shared model: preflight, hash grid, MLPs, quantizers.
    Model,
    /// Per-anchor data: positions, masks, features, scalings, offsets.
    Anchor,
    /// Framing, end marker and ancillary chunks.
    Other,
}

/// Which class a chunk type belongs to.
pub fn byte_class(tag: ChunkTag) -> ByteClass {
    match tag {
        ChunkTag::HEAD | ChunkTag::MLPS | ChunkTag::QUAN | ChunkTag::GRID => ByteClass::Model,
        ChunkTag::APOS | ChunkTag::AMSK | ChunkTag::AFEA | ChunkTag::ASCL | ChunkTag::AOFF => {
            ByteClass::Anchor
        }
        _ => ByteClass::Other,
    }
}

/// One chunk as `info` lists it.
#[derive(Debug, Clone, Serialize)]
pub struct ChunkInfo {
    /// The chunk type.
    pub tag: String,
    /// Whether a decoder must understand it.
    pub critical: bool,
    /// What its bytes count as.
    pub class: ByteClass,
    /// Offset of the chunk's length field.
    pub offset: u64,
    /// Bytes of its payload.
    pub payload_bytes: u64,
    /// Payload plus 12 bytes of framing.
    pub total_bytes: u64,
    /// Its CRC-32C, in hex.
    pub crc32c: String,
}

/// The preflight as `info` shows it: the dimensions (§2.1) and the other `HEAD` fields.
#[derive(Debug, Clone, Serialize)]
pub struct HeadInfo {
    #[serde(flatten)]
    /// The dimensions (§2.1).
    pub dims: Dims,
    /// Bits per voxel coordinate.
    pub coord_bits: u8,
    /// World position of voxel (0, 0, 0)'s corner.
    pub origin: [f32; 3],
    /// Edge of a voxel in world units.
    pub voxel_size: f32,
    /// The decoded model's size in bytes (§1.4).
    pub decoded_bytes: u64,
    /// The rates the stream codes.
    pub coded_rates: Vec<u8>,
}

impl From<&Preflight> for HeadInfo {
    fn from(p: &Preflight) -> Self {
        HeadInfo {
            dims: p.dims.clone(),
            coord_bits: p.coord_bits,
            origin: p.origin,
            voxel_size: p.voxel_size,
            decoded_bytes: p.decoded_bytes,
            coded_rates: p.coded_rates(),
        }
    }
}

/// Bytes per class and per anchor.
#[derive(Debug, Clone, Serialize)]
pub struct Totals {
    /// Bytes of the stream.
    pub file_bytes: u64,
    /// Of those, the shared model's chunks.
    pub model_bytes: u64,
    /// The anchors' chunks.
    pub anchor_bytes: u64,
    /// Everything else (signature, ancillary chunks).
    pub other_bytes: u64,
    /// The whole stream per anchor, in bits.
    pub bits_per_anchor: f64,
}

/// The symbol bytes of one coded rate (`salvq info --json`: `layers`).
#[derive(Debug, Clone, Serialize)]
pub struct LayerInfo {
    /// The rate.
    pub rate: u8,
    /// `AFEA`, `ASCL`, `AOFF` of this layer, chunk overhead included.
    pub feat_bytes: u64,
    /// `ASCL` of this layer, chunk overhead included.
    pub scaling_bytes: u64,
    /// `AOFF` of this layer, chunk overhead included.
    pub offsets_bytes: u64,
    /// This layer's symbol bits per anchor.
    pub symbol_bits_per_anchor: f64,
    /// Bits per anchor of the single-rate stream of this rate (`salvq extract`): everything
    /// but the other layers.
    pub stream_bits_per_anchor: f64,
}

/// Everything `salvq info` reports.
#[derive(Debug, Clone, Serialize)]
pub struct StreamInfo {
    /// The format version, `major.minor`.
    pub format_version: String,
    /// The signature's file flags (§1.2).
    pub file_flags: u16,
    /// The preflight, when `HEAD` decodes.
    pub head: Option<HeadInfo>,
    /// Every chunk, in stream order.
    pub chunks: Vec<ChunkInfo>,
    /// Bytes per class.
    pub totals: Totals,
    /// Model bytes per part (framing and method bytes not included).
    pub model_parts: Vec<ModelPart>,
    /// The encoder's measurements, one per `ests` chunk (one per layer, §7.4), in stream order.
    pub encoder: Vec<EncodeReport>,
    /// The tile table (§10.1), summarised.
    pub tiles: Option<TilesInfo>,
    /// Symbol bytes per coded rate, rates ascending.
    pub layers: Vec<LayerInfo>,
}

/// How a stream is cut into tiles (§10).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TilesInfo {
    /// Tiles.
    pub count: u64,
    /// Anchors in the smallest tile.
    pub min_anchors: u32,
    /// Anchors in the largest tile.
    pub max_anchors: u32,
}

/// The per-group table of an encoder report.
pub fn groups_text(r: &EncodeReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<8} {:>10} {:>8} {:>12} {:>14} {:>14} {:>9} {:>9}",
        "group",
        "symbols",
        "escapes",
        "coded bytes",
        "ideal int (B)",
        "ideal float (B)",
        "coded/int",
        "int/float"
    );
    for g in &r.groups {
        let int_bytes = g.ideal_bits_integer / 8.0;
        let float_bytes = g.ideal_bits_float / 8.0;
        let _ = writeln!(
            s,
            "{:<8} {:>10} {:>8} {:>12} {:>14.0} {:>14.0} {:>9.4} {:>9.4}",
            g.group,
            g.symbols,
            g.escapes,
            g.coded_bytes,
            int_bytes,
            float_bytes,
            g.coded_bytes as f64 / int_bytes.max(1e-9),
            int_bytes / float_bytes.max(1e-9)
        );
    }
    let _ = writeln!(
        s,
        "masks: {} bits in {} bytes; hash grid: {} of {} entries stored (touched)",
        r.mask_bits, r.mask_bytes, r.grid_entries_stored, r.grid_entries_total
    );
    s
}

/// Lists a stream's chunks (checking framing and CRCs) and its preflight.
pub fn inspect(data: &[u8], limits: &Limits) -> Result<StreamInfo> {
    let (sig, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut chunks = Vec::new();
    let mut head = None;
    let mut preflight = None;
    let mut encoder = Vec::new();
    let mut tiles = None;
    let (mut context_weight_bytes, mut scaffold_value_bytes) = (2, 4);
    let (mut model, mut anchor, mut other) = (0u64, 0u64, SIGNATURE_LEN as u64);
    while let Some(c) = reader.next_chunk()? {
        if c.tag == ChunkTag::HEAD && head.is_none() {
            let p = Preflight::parse(c.payload, limits)?;
            head = Some(HeadInfo::from(&p));
            preflight = Some(p);
        }
        if c.tag == ChunkTag::ESTS {
            encoder.extend(serde_json::from_slice::<EncodeReport>(c.payload).ok());
        }
        if let (ChunkTag::MLPS, Some(p)) = (c.tag, &preflight) {
            (context_weight_bytes, scaffold_value_bytes) = mlps_precisions(c.payload, p);
        }
        if let (ChunkTag::TILS, Some(p)) = (c.tag, &preflight) {
            tiles = Some(tiles_info(c.payload, p)?);
        }
        let total = c.payload.len() as u64 + CHUNK_OVERHEAD;
        let class = byte_class(c.tag);
        match class {
            ByteClass::Model => model += total,
            ByteClass::Anchor => anchor += total,
            ByteClass::Other => other += total,
        }
        chunks.push(ChunkInfo {
            tag: c.tag.to_string(),
            critical: c.tag.is_critical(),
            class,
            offset: c.offset,
            payload_bytes: c.payload.len() as u64,
            total_bytes: total,
            crc32c: format!("{:08x}", c.crc),
        });
    }
    let file_bytes = data.len() as u64;
    let anchors = head.as_ref().map_or(0, |h| h.dims.anchors);
    let bytes_of = |tag: ChunkTag| {
        chunks
            .iter()
            .find(|c| c.tag == tag.to_string())
            .map_or(0, |c| c.payload_bytes)
    };
    let model_parts = preflight
        .as_ref()
        .map(|p| model_parts(p, bytes_of, scaffold_value_bytes, context_weight_bytes))
        .unwrap_or_default();
    let rates = head.as_ref().map_or(Vec::new(), |h| h.coded_rates.clone());
    let layers = layer_infos(&chunks, &rates, anchors, file_bytes);
    Ok(StreamInfo {
        model_parts,
        format_version: format!("{}.{}", sig.major, sig.minor),
        file_flags: sig.flags,
        head,
        chunks,
        encoder,
        tiles,
        layers,
        totals: Totals {
            file_bytes,
            model_bytes: model,
            anchor_bytes: anchor,
            other_bytes: other,
            bits_per_anchor: bits_per_anchor(file_bytes, anchors),
        },
    })
}

/// The bytes per context weight and per scaffold MLP value that an `MLPS` payload declares
/// (§1.6.2: `context_precision` follows the method byte; `scaffold_precision` the context MLP).
fn mlps_precisions(payload: &[u8], p: &Preflight) -> (u64, u64) {
    let context = match payload.get(1) {
        Some(1) => salvq_bitstream::container::payload::ContextPrecision::I8,
        _ => salvq_bitstream::container::payload::ContextPrecision::I16,
    };
    let at = 1 + salvq_bitstream::container::payload::context_bytes(&p.dims, context);
    let scaffold_value_bytes = match payload.get(at as usize) {
        Some(1) => 2,
        _ => 4,
    };
    (context.bytes(), scaffold_value_bytes)
}

/// The tile table of a `TILS` payload (§10.1), summarised.
fn tiles_info(payload: &[u8], p: &Preflight) -> Result<TilesInfo> {
    let t = salvq_bitstream::tiles::TileTable::parse(payload, p.dims.anchors, p.coord_bits)?;
    let counts = (0..t.len()).map(|i| t.count(i));
    Ok(TilesInfo {
        count: t.len() as u64,
        min_anchors: counts.clone().min().unwrap_or(0),
        max_anchors: counts.max().unwrap_or(0),
    })
}

/// `bytes` in bits per anchor (0 for a stream without anchors).
fn bits_per_anchor(bytes: u64, anchors: u32) -> f64 {
    if anchors == 0 {
        0.0
    } else {
        bytes as f64 * 8.0 / f64::from(anchors)
    }
}

/// The symbol bytes of each coded rate: §7.4's layer chunks repeat AFEA ASCL AOFF once per
/// coded rate, rates ascending.
fn layer_infos(
    chunks: &[ChunkInfo],
    rates: &[u8],
    anchors: u32,
    file_bytes: u64,
) -> Vec<LayerInfo> {
    let layer_chunks: Vec<&ChunkInfo> = chunks
        .iter()
        .filter(|c| ["AFEA", "ASCL", "AOFF"].contains(&c.tag.as_str()))
        .collect();
    let all_layers: u64 = layer_chunks.iter().map(|c| c.total_bytes).sum();
    rates
        .iter()
        .zip(layer_chunks.chunks(3))
        .filter_map(|(&rate, c)| match c {
            [fe, sc, of] => {
                let own = fe.total_bytes + sc.total_bytes + of.total_bytes;
                Some(LayerInfo {
                    rate,
                    feat_bytes: fe.total_bytes,
                    scaling_bytes: sc.total_bytes,
                    offsets_bytes: of.total_bytes,
                    symbol_bits_per_anchor: bits_per_anchor(own, anchors),
                    stream_bits_per_anchor: bits_per_anchor(file_bytes - all_layers + own, anchors),
                })
            }
            _ => None,
        })
        .collect()
}

impl StreamInfo {
    /// The human-readable report of `salvq info`.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "SALVQ stream, format {}", self.format_version);
        if let Some(h) = &self.head {
            self.write_head(h, &mut s);
        }
        let _ = writeln!(
            s,
            "{:<6} {:>10} {:>12} {:>8}  crc32c",
            "chunk", "offset", "payload", "class"
        );
        for c in &self.chunks {
            let class = match c.class {
                ByteClass::Model => "model",
                ByteClass::Anchor => "anchor",
                ByteClass::Other => "other",
            };
            let _ = writeln!(
                s,
                "{:<6} {:>10} {:>12} {:>8}  {}",
                c.tag, c.offset, c.payload_bytes, class, c.crc32c
            );
        }
        self.write_model_parts(&mut s);
        self.write_layers(&mut s);
        for r in &self.encoder {
            let _ = writeln!(s, "encoder statistics (ests), rate {}:", r.rate);
            s.push_str(&groups_text(r));
        }
        let t = &self.totals;
        let _ = writeln!(
            s,
            "total {} bytes: model {} ({:.1}%), anchors {} ({:.1}%), other {}; {:.2} bits/anchor",
            t.file_bytes,
            t.model_bytes,
            pct(t.model_bytes, t.file_bytes),
            t.anchor_bytes,
            pct(t.anchor_bytes, t.file_bytes),
            t.other_bytes,
            t.bits_per_anchor
        );
        s
    }

    /// The report's preflight lines: the dimensions (§2.1), the tiles and the coded rates.
    fn write_head(&self, h: &HeadInfo, s: &mut String) {
        use std::fmt::Write;
        let d = &h.dims;
        let _ = writeln!(
            s,
            "anchors {}  feat_dim {}  offsets {}  scaling_dim {}  coord_bits {}",
            d.anchors, d.feat_dim, d.offsets, d.scaling_dim, h.coord_bits
        );
        let _ = writeln!(
            s,
            "origin ({}, {}, {})  voxel_size {}",
            h.origin[0], h.origin[1], h.origin[2], h.voxel_size
        );
        let _ = writeln!(
            s,
            "hash grid: {} channels, 3D res {:?} (log2 {}), 2D res {:?} (log2 {})",
            d.grid_channels, d.res_3d, d.log2_size_3d, d.res_2d, d.log2_size_2d
        );
        let _ = writeln!(
            s,
            "MLPs: context hidden {}, scaffold hidden {}, view dims {}",
            d.context_hidden, d.scaffold_hidden, d.view_dims
        );
        if let Some(t) = &self.tiles {
            let _ = writeln!(
                s,
                "tiles: {} ({} … {} anchors each)",
                t.count, t.min_anchors, t.max_anchors
            );
        }
        let _ = writeln!(
            s,
            "quantizers: feature lattice {}, scaling lattice {}, offsets identity",
            d.feat_lattice.name(),
            d.scaling_lattice.name()
        );
        let _ = writeln!(
            s,
            "coded rates {:?} of the model's {} (rate 0 is the finest); decoded size {} bytes",
            h.coded_rates, d.rates, h.decoded_bytes
        );
    }

    /// The report's model bytes: subtotals per group, in order (`--json` lists every tensor).
    fn write_model_parts(&self, s: &mut String) {
        use std::fmt::Write;
        if self.model_parts.is_empty() {
            return;
        }
        let _ = writeln!(s, "model bytes by part (salvq info --json: per tensor):");
        let mut groups: Vec<(&str, &str, u64)> = Vec::new();
        for p in &self.model_parts {
            match groups.last_mut() {
                Some(g) if g.0 == p.group => g.2 += p.bytes,
                _ => groups.push((&p.group, &p.chunk, p.bytes)),
            }
        }
        for (group, chunk, bytes) in groups {
            let _ = writeln!(s, "  {group:<36} {chunk:<5} {bytes:>10}");
        }
    }

    /// The report's symbol bytes per coded rate (§7.4's layers).
    fn write_layers(&self, s: &mut String) {
        use std::fmt::Write;
        if self.layers.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "symbol bytes by rate:  feature  scaling  offsets  symbol bits/anchor  stream bits/anchor (this rate alone)"
        );
        for l in &self.layers {
            let _ = writeln!(
                s,
                "  rate {:>2} {:>15} {:>8} {:>8} {:>19.2} {:>19.2}",
                l.rate,
                l.feat_bytes,
                l.scaling_bytes,
                l.offsets_bytes,
                l.symbol_bits_per_anchor,
                l.stream_bits_per_anchor
            );
        }
    }
}

fn pct(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        100.0 * a as f64 / b as f64
    }
}
