//! `salvq info` for an explicit-profile stream (spec §3): per layer, the bytes of each chunk
//! and the bits per Gaussian of the positions and of each attribute group, measured as the
//! ideal cost of the layer's own events under its own tables (which the ANS coder meets
//! within a few bytes per tile).

use serde::Serialize;

use crate::error::Result;
use salvq::DecodedGaussians;
use salvq_bitstream::container::chunk::{ChunkReader, ChunkTag};
use salvq_bitstream::container::signature::{Signature, SIGNATURE_LEN};
use salvq_bitstream::entropy::{wide_scale, GaussianTables, SCALE_COUNT, SCALE_INDEX_COUNT};
use salvq_bitstream::explicit::attributes::{rest_count_of, walk, BitEvent, Events, TileSymbols};
use salvq_bitstream::explicit::refinement::{refine_walk, Refinement};
use salvq_bitstream::explicit::GroupKind;
use salvq_bitstream::limits::Limits;

/// One layer as `info` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitLayerInfo {
    /// The layer's rate.
    pub rate: u8,
    /// Bits per voxel coordinate.
    pub coord_bits: u8,
    /// Edge of a voxel in world units.
    pub voxel_size: f32,
    /// Position refinement bits per axis, per size class.
    pub refine: [u8; 4],
    /// Tiles in the layer.
    pub tiles: usize,
    /// Framed bytes of the layer's chunks (its section, §3.7).
    pub layer_bytes: u64,
    /// Bytes of the stream that decodes this rate (what `salvq extract` writes): the layer
    /// alone, or in a progressive stream the prefix up to it (§3.8), shared chunks and `SEND`
    /// included.
    pub single_rate_bytes: u64,
    /// Byte offset where the layer's section ends in the stream: in a progressive stream,
    /// a prefix of this many bytes decodes to this rate (§3.8.4).
    pub stream_end: u64,
    /// Bits per Gaussian: the octree (`APOS` payload) and the refinement bits.
    pub octree_bits: f64,
    /// Bits per Gaussian of the position refinement.
    pub refine_bits: f64,
    /// Bits per Gaussian of each group, by name (the rotation index in `rotation`).
    pub group_bits: Vec<(String, f64)>,
    /// Per group: the share of its coded values at a wide scale (k ≥ 64, §6.3.6), at the
    /// widest (k = 127), and sent with an escape (a symbol or high part past R_k, §6.4).
    /// Values whose spread passes the widest scale's σ cost more than their entropy, and each
    /// escape is 2L + 2 binary events more to decode.
    pub saturation: Vec<GroupSaturation>,
}

/// How far a group's values overrun the scale grid (`info`'s `saturation`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GroupSaturation {
    /// The group's name.
    pub group: String,
    /// Share of its coded values coded at a wide scale (k ≥ 64, §6.3.6).
    pub wide_scale: f64,
    /// Share of its coded values coded at the widest scale (k = 127).
    pub widest_scale: f64,
    /// Share of its coded values sent with an escape.
    pub escaped: f64,
}

/// `info` of an explicit-profile stream.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitInfo {
    /// The format version, `major.minor`.
    pub format_version: String,
    /// Gaussians in every layer.
    pub gaussians: u32,
    /// SH degree.
    pub sh_degree: u8,
    /// Rates the quantizers have gains for.
    pub rate_count: u8,
    /// The rates the stream codes.
    pub coded_rates: Vec<u8>,
    /// Bytes of the stream.
    pub file_bytes: u64,
    /// Framed bytes of `GHED`, `GQUA` and the ancillary chunks before the first layer.
    pub shared_bytes: u64,
    /// Per group: its name and whether it has a KLT basis (lattice code 4).
    pub lattices: Vec<(String, bool)>,
    /// Whether the rates nest (§3.8).
    pub progressive: bool,
    /// Its layers, finest first.
    pub layers: Vec<ExplicitLayerInfo>,
}

struct Cost<'a> {
    coords: &'a [i32],
    values: usize,
    group_of: &'a [usize],
    tables: &'a GaussianTables,
    bits: Vec<f64>,
    /// Per group: coded values, those at a wide scale, at the widest, those escaped.
    counts: Vec<[u64; 4]>,
    refine: f64,
    rotation_group: usize,
    /// The `sh_rest` count of the Gaussian at hand (§3.5), and the group's index.
    rest_count: usize,
    rest_group: usize,
    /// Every symbol, in order, when they are collected ([`coded_symbols`]).
    symbols: Option<Vec<i64>>,
}

impl<'a> Cost<'a> {
    fn new(d: &DecodedGaussians, group_of: &'a [usize], tables: &'a GaussianTables) -> Self {
        let position = |kind| d.groups.iter().position(|g| g.kind == kind).unwrap_or(0);
        Cost {
            coords: &[],
            values: group_of.len(),
            group_of,
            tables,
            bits: vec![0.0; d.groups.len()],
            counts: vec![[0; 4]; d.groups.len()],
            refine: 0.0,
            rotation_group: position(GroupKind::Rotation),
            rest_count: 0,
            rest_group: position(GroupKind::Rest),
            symbols: None,
        }
    }
}

/// The group of each coded value of `d`'s layer.
fn group_of(d: &DecodedGaussians) -> Vec<usize> {
    d.groups
        .iter()
        .enumerate()
        .flat_map(|(gi, g)| std::iter::repeat_n(gi, g.dim))
        .collect()
}

/// The symbols `d`'s `GATT` codes, tile by tile in stream order (§3.5): what a decoder reads
/// from the ANS coder besides binary events (a benchmark's bare-coder floor).
pub fn coded_symbols(d: &DecodedGaussians) -> salvq::Result<Vec<i64>> {
    let group_of = group_of(d);
    let values = group_of.len();
    let mut cost = Cost::new(d, &group_of, GaussianTables::standard());
    cost.symbols = Some(Vec::new());
    for t in 0..d.tiles.len() {
        let range = d.tiles.range(t);
        cost.coords = &d.symbols.coords[range.start * values..range.end * values];
        walk(&d.layer, &d.groups, &d.voxels[range], &mut cost)?;
    }
    Ok(cost.symbols.unwrap_or_default())
}

impl Events for Cost<'_> {
    fn bit(&mut self, freq_one: u32, _: usize, what: BitEvent) -> salvq::Result<bool> {
        // A refinement bit costs one bit; the rotation index's bits are costed from the
        // decoded indices afterwards (the traversal does not need them to be right here).
        match what {
            BitEvent::Refine { .. } => self.refine += 1.0,
            // The sh_rest count's bits steer the traversal: answered from the decoded
            // coordinates (as the encoder wrote them) and costed at their probabilities.
            BitEvent::RestCount { bit } => {
                let one = self.rest_count >> bit & 1 == 1;
                let p = f64::from(freq_one) / 65536.0;
                self.bits[self.rest_group] -= (if one { p } else { 1.0 - p }).log2();
                return Ok(one);
            }
            BitEvent::RotationHigh | BitEvent::RotationLow => {}
        }
        Ok(false)
    }
    fn rest_predictions(&mut self, i: usize, first: usize, pred: impl Fn(usize) -> i64) {
        let row = &self.coords[i * self.values + first..(i + 1) * self.values];
        self.rest_count = rest_count_of(row, pred);
    }
    fn symbol(&mut self, k: u8, i: usize, v: usize, pred: i64) -> salvq::Result<i64> {
        let r = i64::from(self.coords[i * self.values + v]) - pred;
        if let Some(symbols) = &mut self.symbols {
            symbols.push(r);
        }
        let g = self.group_of[v];
        self.bits[g] += self.tables.ideal_bits(k, r);
        // §6.3.6: a wide scale codes ⌊r / 2^b⌋ at its table scale.
        let (table, high) = wide_scale(k).map_or((k, r), |(t, low_bits)| (t, r >> low_bits));
        let escaped = high.unsigned_abs() > u64::from(self.tables.radius(table));
        self.counts[g][0] += 1;
        self.counts[g][1] += u64::from(usize::from(k) >= SCALE_COUNT);
        self.counts[g][2] += u64::from(usize::from(k) == SCALE_INDEX_COUNT - 1);
        self.counts[g][3] += u64::from(escaped);
        Ok(r)
    }
}

/// Inspects an explicit-profile stream: every coded layer is decoded and its events costed.
pub fn inspect_explicit(data: &[u8], limits: &Limits) -> Result<ExplicitInfo> {
    let (sig, rest) = Signature::parse(data)?;
    let sections = section_bytes(rest, limits)?;
    let first = decode_rate(data, limits, None)?;
    let h = first.header.clone();
    let tables = GaussianTables::standard();
    let n = f64::from(h.count.max(1));
    let mut layers = Vec::new();
    // In stream order, each layer's decode and the one before it (what a refinement refines).
    let mut before: Option<salvq::DecodedGaussians> = None;
    for (li, rate) in h.stream_rates().into_iter().enumerate() {
        let d = if rate == first.rate {
            first.clone()
        } else {
            decode_rate(data, limits, Some(rate))?
        };
        let group_of = group_of(&d);
        let mut cost = Cost::new(&d, &group_of, tables);
        let refinement = before
            .as_ref()
            .filter(|_| h.progressive)
            .zip(d.refinements.last());
        cost_tiles(&d, refinement, &mut cost)?;
        let layer_bytes = sections.get(li + 1).copied().unwrap_or(0);
        // A progressive rate is read as the stream's prefix up to its layer.
        let read: u64 = match h.progressive {
            true => sections[1..=li + 1].iter().sum(),
            false => layer_bytes,
        };
        let apos = match refinement {
            Some(_) => 0,
            None => octree_bytes(data, li, limits)?,
        };
        let stream_end = SIGNATURE_LEN as u64 + sections[..=li + 1].iter().sum::<u64>();
        layers.push(ExplicitLayerInfo {
            rate,
            coord_bits: d.layer.coord_bits,
            voxel_size: d.layer.voxel_size,
            refine: d.precision.refine,
            tiles: d.tiles.len(),
            layer_bytes,
            single_rate_bytes: SIGNATURE_LEN as u64 + sections[0] + read + 12,
            stream_end,
            octree_bits: apos as f64 * 8.0 / n,
            refine_bits: cost.refine / n,
            group_bits: d
                .groups
                .iter()
                .zip(&cost.bits)
                .map(|(g, b)| (g.kind.name().to_string(), b / n))
                .collect(),
            saturation: saturation(&d, &cost.counts),
        });
        before = Some(d);
    }
    // Finest first, whatever the stream's order.
    layers.sort_by_key(|l| l.rate);
    Ok(ExplicitInfo {
        progressive: h.progressive,
        format_version: format!("{}.{}", sig.major, sig.minor),
        gaussians: h.count,
        sh_degree: h.sh_degree,
        rate_count: h.rate_count,
        coded_rates: h.coded_rates(),
        file_bytes: data.len() as u64,
        shared_bytes: sections[0],
        lattices: first
            .groups
            .iter()
            .map(|g| (g.kind.name().to_string(), g.basis.is_some()))
            .collect(),
        layers,
    })
}

/// Framed bytes of each section of the chunks after the signature (`rest`): the shared
/// chunks until the first `GLAY` (or `GREF`), then one per layer (§3.7); `SEND` is in none.
fn section_bytes(rest: &[u8], limits: &Limits) -> Result<Vec<u64>> {
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut sections: Vec<u64> = vec![0];
    while let Some(c) = reader.next_chunk()? {
        if matches!(c.tag, ChunkTag::GLAY | ChunkTag::GREF) {
            sections.push(0);
        }
        if c.tag != ChunkTag::SEND {
            *sections.last_mut().unwrap_or(&mut 0) += c.payload.len() as u64 + 12;
        }
    }
    Ok(sections)
}

/// The stream decoded at `rate` (`None`: the decoder's default rate) as explicit Gaussians.
fn decode_rate(data: &[u8], limits: &Limits, rate: Option<u8>) -> Result<DecodedGaussians> {
    Ok(salvq::Decoder::builder()
        .limits(*limits)
        .rate(rate)
        .build()
        .decode(data)
        .and_then(salvq::Scene::try_into_gaussians)?)
}

/// Costs every tile of layer `d` into `cost`: its `GATT` walk and rotation indices (§3.5), or,
/// for a refinement, its walk over the tile's symbols of the layer `before` it (§3.8.2).
fn cost_tiles<'a>(
    d: &'a DecodedGaussians,
    refinement: Option<(&DecodedGaussians, &Refinement)>,
    cost: &mut Cost<'a>,
) -> Result<()> {
    let values: usize = d.groups.iter().map(|g| g.dim).sum();
    for t in 0..d.tiles.len() {
        let range = d.tiles.range(t);
        cost.coords = &d.symbols.coords[range.start * values..range.end * values];
        let voxels = &d.voxels[range.clone()];
        if let Some((b, r)) = refinement {
            // §3.8.2: the tile's symbols before the refinement, refined in place.
            let mut tile = TileSymbols {
                coords: b.symbols.coords[range.start * values..range.end * values].to_vec(),
                rotation_index: b.symbols.rotation_index[range.clone()].to_vec(),
                size_class: b.symbols.size_class[range.clone()].to_vec(),
                refinement: b.symbols.refinement[range.clone()].to_vec(),
            };
            refine_walk(r, &d.groups, voxels, cost, &mut tile.as_mut())?;
            continue;
        }
        walk(&d.layer, &d.groups, voxels, cost)?;
        // The rotation index: two binary events per Gaussian at the layer's frequencies.
        for &r in &d.symbols.rotation_index[range] {
            let f = d.layer.rotation_freq;
            let high = r >> 1;
            let p_high = f64::from(f[0]) / 65536.0;
            let p_low = f64::from(f[1 + usize::from(high)]) / 65536.0;
            let b = |p: f64, one: bool| -(if one { p } else { 1.0 - p }).log2();
            cost.bits[cost.rotation_group] += b(p_high, high == 1) + b(p_low, r & 1 == 1);
        }
    }
    Ok(())
}

/// Per group of `d`, the shares of its coded values at a wide scale, at the widest and escaped,
/// from the per-group `counts` of [`Cost`].
fn saturation(d: &DecodedGaussians, counts: &[[u64; 4]]) -> Vec<GroupSaturation> {
    d.groups
        .iter()
        .zip(counts)
        .map(|(g, &[values, wide, widest, escaped])| {
            let share = |c: u64| c as f64 / values.max(1) as f64;
            GroupSaturation {
                group: g.kind.name().to_string(),
                wide_scale: share(wide),
                widest_scale: share(widest),
                escaped: share(escaped),
            }
        })
        .collect()
}

/// Payload bytes of layer `li`'s `APOS`.
fn octree_bytes(data: &[u8], li: usize, limits: &Limits) -> Result<u64> {
    let (_, rest) = Signature::parse(data)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, limits);
    let mut seen = 0usize;
    while let Some(c) = reader.next_chunk()? {
        if c.tag == ChunkTag::APOS {
            if seen == li {
                return Ok(c.payload.len() as u64);
            }
            seen += 1;
        }
    }
    Ok(0)
}

impl ExplicitInfo {
    /// The human-readable report.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "SALVQ stream, format {}, explicit-Gaussians profile (spec §3)",
            self.format_version
        );
        let _ = writeln!(
            s,
            "{} Gaussians, SH degree {}, {} rates of which {} coded {:?} (rate 0 is the finest); {} bytes, shared {} bytes",
            self.gaussians,
            self.sh_degree,
            self.rate_count,
            self.coded_rates.len(),
            self.coded_rates,
            self.file_bytes,
            self.shared_bytes
        );
        let klt: Vec<&str> = self
            .lattices
            .iter()
            .filter(|l| l.1)
            .map(|l| l.0.as_str())
            .collect();
        if !klt.is_empty() {
            let _ = writeln!(s, "KLT basis (lattice 4): {}", klt.join(", "));
        }
        if self.progressive {
            let _ = writeln!(
                s,
                "progressive (spec §3.8): the coarsest rate first, each finer one refining it; a \
                 rate's bytes are the stream's prefix up to the end of its layer (plus SEND), \
                 its bits/Gaussian those of its own layer"
            );
        }
        self.write_layers(&mut s);
        self.write_saturation(&mut s);
        s
    }

    /// The report's table of layers: per rate its bytes and its bits per Gaussian by part.
    fn write_layers(&self, s: &mut String) {
        use std::fmt::Write;
        let names: Vec<&str> = self
            .layers
            .first()
            .map(|l| l.group_bits.iter().map(|g| g.0.as_str()).collect())
            .unwrap_or_default();
        let bytes_head = if self.progressive {
            "bytes to rate  ends at"
        } else {
            "bytes alone"
        };
        let _ = writeln!(
            s,
            "rate  coord_bits  refine     tiles  {bytes_head}  B/Gaussian  bits/Gaussian: octree refine {}",
            names.join(" ")
        );
        let n = f64::from(self.gaussians.max(1));
        for l in &self.layers {
            let g: Vec<String> = l.group_bits.iter().map(|x| format!("{:.2}", x.1)).collect();
            let bytes = match self.progressive {
                true => format!("{:>13}  {:>7}", l.single_rate_bytes, l.stream_end),
                false => format!("{:>11}", l.single_rate_bytes),
            };
            let _ = writeln!(
                s,
                "{:>4}  {:>10}  {:<9}  {:>5}  {bytes}  {:>10.3}  {:.2} {:.2} {}",
                l.rate,
                l.coord_bits,
                format!("{:?}", l.refine),
                l.tiles,
                l.single_rate_bytes as f64 / n,
                l.octree_bits,
                l.refine_bits,
                g.join(" ")
            );
        }
    }

    /// The report's lines on the groups whose values need wide scales or overrun them
    /// (§6.3.6, §6.4).
    fn write_saturation(&self, s: &mut String) {
        use std::fmt::Write;
        for l in &self.layers {
            let over: Vec<String> = l
                .saturation
                .iter()
                .filter(|g| g.wide_scale > 0.0 || g.escaped > 0.0)
                .map(|g| {
                    format!(
                        "{} {:.1} % / {:.1} % / {:.1} %",
                        g.group,
                        100.0 * g.wide_scale,
                        100.0 * g.widest_scale,
                        100.0 * g.escaped
                    )
                })
                .collect();
            if !over.is_empty() {
                let _ = writeln!(
                    s,
                    "rate {}: values at a wide scale (k ≥ {}) / at the widest (k = {}) / \
                     escaped: {}",
                    l.rate,
                    SCALE_COUNT,
                    SCALE_INDEX_COUNT - 1,
                    over.join(", ")
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value is escaped exactly when its symbol passes the table's radius R_k (§6.4),
    /// a wide scale's high part ⌊r / 2^b⌋ (§6.3.6), and counted as wide from k = 64.
    #[test]
    fn escapes_are_counted_past_the_radius() {
        let tables = GaussianTables::standard();
        let (k, widest) = (40u8, (SCALE_INDEX_COUNT - 1) as u8);
        let r = i64::from(tables.radius(k));
        let r63 = i64::from(tables.radius(63)) as i32;
        // Gaussian 0 codes [R, −R − 1] at k = 40, then at k = 127 (table 63, b = 8) the
        // largest value whose high part is R_63, and the next.
        let coords = [r as i32, -(r as i32) - 1, (r63 << 8) + 255, (r63 + 1) << 8];
        let mut cost = Cost {
            coords: &coords,
            values: 4,
            group_of: &[0, 0, 1, 1],
            tables,
            bits: vec![0.0; 2],
            counts: vec![[0; 4]; 2],
            refine: 0.0,
            rotation_group: 0,
            rest_count: 0,
            rest_group: 0,
            symbols: None,
        };
        cost.symbol(k, 0, 0, 0).unwrap();
        cost.symbol(k, 0, 1, 0).unwrap();
        cost.symbol(widest, 0, 2, 0).unwrap();
        cost.symbol(widest, 0, 3, 0).unwrap();
        assert_eq!(cost.counts, vec![[2, 0, 0, 1], [2, 2, 2, 1]]);
    }
}
