//! Valid explicit-profile vectors built by editing a coded stream (spec §3, §8, §11.4): a
//! `GQUA` field moved, or layer 0 decoded to what its chunks code, changed where an encoder
//! would not go, and coded again by the format's own writers. Their oracle is the reference
//! decode, each checked here to tell apart the readings of the rule it pins.

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{wide_scale, GaussianTables};
use salvq_bitstream::explicit::attributes::{rest_count_of, walk, BitEvent, Events, TileSymbols};
use salvq_bitstream::tiles::{join_bodies, TileTable};
use salvq_encoder::explicit::{ExplicitOptions, RatePlan};
use salvq_encoder::writers::surgery;
use salvq_encoder::writers::SymbolWriter;
use salvq_encoder::Result;
use salvq_gen::gaussians::GaussianParams;

use super::explicit_vectors::{base_plan, encode_synthetic, vector, ExplicitVector};

/// Every edited valid vector, in a fixed order (after [`explicit_valid_vectors`]'s).
///
/// [`explicit_valid_vectors`]: super::explicit_vectors::explicit_valid_vectors
pub fn edited_valid_vectors() -> Result<Vec<ExplicitVector>> {
    Ok(vec![
        rotation_near_sphere()?,
        coordinate_limit()?,
        rest_uncoded_predicted()?,
        rest_uncoded_context()?,
        octree_halving()?,
    ])
}

/// The rotation group's three values of `g-rotation-near-sphere`: a·a + b·b + c·c is 1 to
/// within a few binary32 units, where §3.6 step 3 evaluated in binary32 changes by 3.45e-4
/// when a multiply and an add are fused.
const NEAR_SPHERE: [f32; 3] = [0.577_296_9, 0.577_369_15, 0.577_384_7];

/// A valid stream whose decoded rotations sit where a decoder that evaluates §3.6 step 3 in
/// binary32 with a fused multiply-add fails §11.3's tolerance: `g-sh0`'s kind of stream with
/// the rotation group's mean moved onto the unit sphere and its step made tiny (`GQUA`
/// edited; every field stays valid). Its oracle is the reference decode, checked here to
/// differ from the fused binary32 form beyond the tolerance for most Gaussians.
fn rotation_near_sphere() -> Result<ExplicitVector> {
    let e = encode_synthetic(
        &GaussianParams::new(60, 0, 31),
        vec![base_plan(false)],
        ExplicitOptions {
            klt: Some(vec![false; 4]),
            progressive: false,
            ..Default::default()
        },
    )?;
    // GQUA (§3.3), SH degree 0, one rate, identity lattices: coding_method, then per group
    // lattice, step, one gain, d means: scale (d = 3) at 1, opacity (d = 1) at 22, rotation
    // (d = 3) at 35: its step at 36, its means at 44.
    let stream = surgery::edit_payload(&e.stream, ChunkTag::GQUA, |p| {
        assert_eq!(p[35], 0, "the rotation group's lattice is the identity");
        p[36..40].copy_from_slice(&1e-9f32.to_le_bytes());
        for (j, v) in NEAR_SPHERE.iter().enumerate() {
            p[44 + 4 * j..48 + 4 * j].copy_from_slice(&v.to_le_bytes());
        }
    })
    .expect("the stream has a GQUA");
    let decoded = salvq::Decoder::builder()
        .limits(Default::default())
        .rate(None)
        .build()
        .decode(&stream)
        .and_then(salvq::Scene::try_into_gaussians)?;
    let g = decoded.gaussians;
    let beyond = g
        .rotations
        .iter()
        .filter(|q| {
            // m, near 0, is the component of least magnitude; a, b, c are the others in order.
            let k = (0..4)
                .min_by(|&i, &j| q[i].abs().total_cmp(&q[j].abs()))
                .unwrap_or(0);
            let mut abc = (0..4).filter(|&i| i != k).map(|i| q[i]);
            let (a, b, c) = (abc.next(), abc.next(), abc.next());
            let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                return false;
            };
            let t = 1.0 - c.mul_add(c, a.mul_add(a, b * b));
            let fused32 = if t > 0.0 { t.sqrt() } else { 0.0 };
            let tolerance = 2f32.powi(-14) * (1.0 + q[k].abs());
            (fused32 - q[k]).abs() > tolerance
        })
        .count();
    assert!(
        2 * beyond > g.rotations.len(),
        "only {beyond} of {} rotations tell a fused binary32 evaluation apart",
        g.rotations.len()
    );
    Ok(ExplicitVector {
        name: "g-rotation-near-sphere",
        description: "60 synthetic Gaussians, SH degree 0, whose rotation values sit on the \
                      unit sphere to within a few binary32 units (GQUA's rotation mean moved \
                      there, its step 1e-9): §3.6 step 3 in binary64, which a fused \
                      multiply-add cannot change",
        sections: &[],
        rates: vec![0],
        oracle: vec![g],
        stream,
    })
}

/// Layer 0 of an explicit-profile stream (its lowest coded rate, layered streams only)
/// decoded to what its chunks code — grid and prior, tiles, voxels and every Gaussian's
/// coordinates, rotation index and position bits — to be changed and coded again by the
/// format's own writers. Valid vectors change what an encoder would not choose; must-fail
/// vectors break one rule of a body with everything decoded before it intact.
pub(crate) struct LayerEdit {
    stream: Vec<u8>,
    pub(crate) groups: Vec<salvq_bitstream::explicit::Group>,
    pub(crate) layer: salvq_bitstream::explicit::Layer,
    pub(crate) tiles: TileTable,
    pub(crate) voxels: Vec<[u32; 3]>,
    pub(crate) symbols: TileSymbols,
    /// Coded values per Gaussian (D, §3.3).
    pub(crate) values: usize,
}

/// A fault written into one symbol of a `GATT` body: at tile-local Gaussian `gaussian`,
/// coded value `value`, an escape (§6.4) whose prefix has `zeros` zero bits (30: a valid
/// escape, the longest; 31: EscapeOverflow).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct EscapeAt {
    pub(crate) gaussian: usize,
    pub(crate) value: usize,
    pub(crate) zeros: u32,
}

impl LayerEdit {
    /// Decodes layer 0 of `stream`, and checks that coding it again gives the same bytes.
    pub(crate) fn new(stream: Vec<u8>) -> LayerEdit {
        let d = salvq::Decoder::builder()
            .limits(Default::default())
            .rate(None)
            .build()
            .decode(&stream)
            .and_then(salvq::Scene::try_into_gaussians)
            .expect("the stream decodes");
        assert!(!d.header.progressive, "a layered stream");
        let values = d.groups.iter().map(|g| g.dim).sum();
        let edit = LayerEdit {
            stream,
            groups: d.groups,
            layer: d.layer,
            tiles: d.tiles,
            voxels: d.voxels,
            symbols: d.symbols,
            values,
        };
        assert!(
            edit.encode() == edit.stream,
            "coding layer 0 again is exact"
        );
        edit
    }

    /// Coordinate `v` of Gaussian `i` (stream order).
    pub(crate) fn coord(&self, i: usize, v: usize) -> i32 {
        self.symbols.coords[i * self.values + v]
    }

    pub(crate) fn set_coord(&mut self, i: usize, v: usize, u: i32) {
        self.symbols.coords[i * self.values + v] = u;
    }

    /// Tile `t`'s cell level and its voxels relative to its cell (§8).
    pub(crate) fn local_voxels(&self, t: usize) -> (u8, Vec<[u32; 3]>) {
        let (level, cell) = self.tiles.cells[t];
        let local = self.voxels[self.tiles.range(t)]
            .iter()
            .map(|v| [0, 1, 2].map(|a| v[a] - (cell[a] << level)))
            .collect();
        (level, local)
    }

    /// Tile `t`'s `APOS` body (§8) from its voxels.
    pub(crate) fn apos_body(&self, t: usize) -> Vec<u8> {
        let (level, local) = self.local_voxels(t);
        salvq_encoder::writers::encode_geometry(&local, level, GaussianTables::standard())
            .expect("the tile's voxels code")
    }

    /// Tile `t`'s `GATT` body (§3.5) from its symbols, with `escape` written in, then, with
    /// `extra_event`, one more binary event that no decoder reads (so the state a decoder
    /// ends in is not 2^32, §6.2.6 step 5). Also whether the walk ended without error (a
    /// coordinate past 2^24 stops it right after its symbol is written).
    pub(crate) fn gatt_body(
        &self,
        t: usize,
        escape: Option<EscapeAt>,
        extra_event: bool,
    ) -> (Vec<u8>, salvq::Result<()>) {
        let r = self.tiles.range(t);
        let tables = GaussianTables::standard();
        let mut answers = Answers {
            out: SymbolWriter::new(ChunkTag::GATT, tables),
            tables,
            coords: &self.symbols.coords[r.start * self.values..r.end * self.values],
            rotation: &self.symbols.rotation_index[r.clone()],
            refinement: &self.symbols.refinement[r.clone()],
            values: self.values,
            rest_count: 0,
            escape,
        };
        let walked = walk(&self.layer, &self.groups, &self.voxels[r], &mut answers).map(|_| ());
        if extra_event {
            answers.out.bit(false, 1 << 15);
        }
        (answers.out.finish(), walked)
    }

    /// The stream with layer 0's `GLAY` and `TILS` from `self` and its `APOS` and `GATT`
    /// from the tile bodies given.
    pub(crate) fn stream_with(&self, apos: &[Vec<u8>], gatt: &[Vec<u8>]) -> Vec<u8> {
        let coded = |bodies: &[Vec<u8>]| {
            let mut p = vec![1u8];
            p.extend(join_bodies(bodies));
            p
        };
        let mut cs = surgery::chunks(&self.stream).expect("the stream frames");
        for (tag, payload) in [
            (ChunkTag::GLAY, self.layer.to_payload()),
            (ChunkTag::TILS, self.tiles.to_payload()),
            (ChunkTag::APOS, coded(apos)),
            (ChunkTag::GATT, coded(gatt)),
        ] {
            if let Some(c) = cs.iter_mut().find(|(t, _)| *t == tag) {
                c.1 = payload;
            }
        }
        surgery::assemble(&self.stream, &cs)
    }

    /// Every tile's bodies of `APOS` and `GATT` (as they are, or as a change to `self` makes
    /// them).
    pub(crate) fn bodies(&self) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
        let tiles = 0..self.tiles.len();
        let apos = tiles.clone().map(|t| self.apos_body(t)).collect();
        let gatt = tiles
            .map(|t| {
                let (body, walked) = self.gatt_body(t, None, false);
                walked.expect("every coordinate is within 2^24");
                body
            })
            .collect();
        (apos, gatt)
    }

    /// The stream with layer 0 coded from `self`.
    pub(crate) fn encode(&self) -> Vec<u8> {
        let (apos, gatt) = self.bodies();
        self.stream_with(&apos, &gatt)
    }
}

/// Answers a tile's `GATT` events (§3.5) from its symbols and writes them, as the
/// reference encoder does; an [`EscapeAt`] replaces one symbol.
struct Answers<'a> {
    out: SymbolWriter<'a>,
    tables: &'a GaussianTables,
    coords: &'a [i32],
    rotation: &'a [u8],
    refinement: &'a [[u32; 3]],
    values: usize,
    rest_count: usize,
    escape: Option<EscapeAt>,
}

impl Events for Answers<'_> {
    fn bit(&mut self, freq_one: u32, i: usize, what: BitEvent) -> salvq::Result<bool> {
        let bit = match what {
            BitEvent::RotationHigh => self.rotation[i] >> 1 == 1,
            BitEvent::RotationLow => self.rotation[i] & 1 == 1,
            BitEvent::Refine { axis, bit } => self.refinement[i][axis] >> bit & 1 == 1,
            BitEvent::RestCount { bit } => self.rest_count >> bit & 1 == 1,
        };
        self.out.bit(bit, freq_one);
        Ok(bit)
    }

    fn symbol(&mut self, k: u8, i: usize, v: usize, pred: i64) -> salvq::Result<i64> {
        let Some(e) = self.escape.filter(|e| (e.gaussian, e.value) == (i, v)) else {
            let r = i64::from(self.coords[i * self.values + v]) - pred;
            self.out.symbol(r, k)?;
            return Ok(r);
        };
        // §6.3.6: a wide scale escapes its high part in its table scale, low bits 0.
        let (table, low_bits) = wide_scale(k).unwrap_or((k, 0));
        let scale = self.tables.scale(table);
        if e.zeros <= 30 {
            let r = (i64::from(scale.radius()) + (1 << e.zeros)) << low_bits;
            self.out.symbol(r, k)?;
            return Ok(r);
        }
        // ESCAPE is the alphabet's last symbol, [2^16 − f, 2^16): a binary event's 1 with
        // freq_one f; then the prefix's zero bits, each an escape bit (probability ½).
        let f = scale.frequencies()[scale.escape_index()];
        self.out.bit(true, f);
        for _ in 0..e.zeros {
            self.out.bit(false, 1 << 15);
        }
        Ok(0)
    }

    fn rest_predictions(&mut self, i: usize, first: usize, pred: impl Fn(usize) -> i64) {
        let row = &self.coords[i * self.values + first..(i + 1) * self.values];
        self.rest_count = rest_count_of(row, pred);
    }
}

/// A valid vector of a stream made by [`LayerEdit`]: its oracle is the reference decode.
fn edited(
    name: &'static str,
    description: &'static str,
    sections: &'static [&'static str],
    stream: Vec<u8>,
) -> Result<ExplicitVector> {
    let d = salvq::Decoder::builder()
        .limits(Default::default())
        .rate(None)
        .build()
        .decode(&stream)
        .and_then(salvq::Scene::try_into_gaussians)?;
    Ok(ExplicitVector {
        name,
        description,
        sections,
        rates: vec![d.rate],
        oracle: vec![d.gaussians],
        stream,
    })
}

/// A scene of `n` Gaussians of SH degree 1 in one tile, identity lattices, coded as a
/// layered stream of one rate, ready to edit; with every group predicted and every
/// Gaussian after the first referring to the one before (`pred_level` = `coord_bits`).
fn predicted_scene(n: usize, seed: u64) -> Result<LayerEdit> {
    let e = encode_synthetic(
        &GaussianParams::new(n, 1, seed),
        vec![base_plan(true)],
        ExplicitOptions {
            klt: Some(vec![false; 5]),
            tile_gaussians: 16_384,
            progressive: false,
            ..Default::default()
        },
    )?;
    let mut edit = LayerEdit::new(e.stream);
    assert_eq!(edit.tiles.len(), 1);
    edit.layer.predict = vec![true; edit.groups.len()];
    edit.layer.pred_level = edit.layer.coord_bits;
    Ok(edit)
}

/// The first coded value of the `sh_rest` group (after scale 3, opacity 1, rotation 3 and
/// SH DC 3: §3.3).
const REST: usize = 10;

/// §3.5's prediction of Gaussian `i`'s `sh_rest` value `j` from Gaussian `i − 1` (its
/// reference in [`predicted_scene`]): the reference's coordinate rescaled to `i`'s shift.
fn rest_prediction(e: &LayerEdit, i: usize, j: usize) -> i32 {
    let shift = |g: usize| e.layer.group_shift(4, usize::from(e.symbols.size_class[g]));
    let u = i64::from(e.coord(i - 1, REST + j));
    salvq_bitstream::explicit::attributes::rescale(u, shift(i - 1), shift(i)) as i32
}

/// The `sh_rest` count §3.5 codes for Gaussian `i` of an edited [`predicted_scene`].
fn rest_count(e: &LayerEdit, i: usize) -> usize {
    let d = e.values - REST;
    let row: Vec<i32> = (0..d).map(|j| e.coord(i, REST + j)).collect();
    rest_count_of(&row, |j| i64::from(rest_prediction(e, i, j)))
}

/// Coordinates ±2^24, the largest magnitude §3.5 allows (`|u| > 2^24` is the error; valid
/// vector of the boundary, must-fail `x-g-coordinate-past-limit` one past it).
fn coordinate_limit() -> Result<ExplicitVector> {
    let mut e = predicted_scene(40, 37)?;
    e.set_coord(0, 3, 1 << 24);
    e.set_coord(1, 7, -(1 << 24));
    e.set_coord(2, 7, 1 << 24);
    edited(
        "g-coordinate-limit",
        "40 synthetic Gaussians, SH degree 1: Gaussian 0's opacity coordinate 2^24, Gaussian \
         1's first SH DC coordinate −2^24 and Gaussian 2's 2^24 (coded as a symbol of 2^25 \
         from its prediction): §3.5's limit |u| ≤ 2^24 includes 2^24",
        &[],
        e.encode(),
    )
}

/// Uncoded `sh_rest` values (after a Gaussian's count) are the prediction, not 0 (§3.5).
fn rest_uncoded_predicted() -> Result<ExplicitVector> {
    let mut e = predicted_scene(48, 43)?;
    let d = e.values - REST;
    for i in (1..e.voxels.len()).step_by(2) {
        let sign = if i % 4 == 1 { 1 } else { -1 };
        for j in 2..d {
            e.set_coord(i - 1, REST + j, sign * 3 * (j as i32 - 1));
            let p = rest_prediction(&e, i, j);
            e.set_coord(i, REST + j, p);
        }
        let p = rest_prediction(&e, i, 2);
        assert!(
            rest_count(&e, i) <= 2 && p != 0,
            "Gaussian {i}'s values from 2 on are uncoded"
        );
    }
    edited(
        "g-rest-uncoded-predicted",
        "48 synthetic Gaussians, SH degree 1, every group predicted, each Gaussian's \
         reference the one before: every odd Gaussian's sh_rest values from the third on \
         equal their nonzero predictions, so its sh_rest count is at most 2 and those values \
         decode as the prediction, not 0 (§3.5)",
        &[],
        e.encode(),
    )
}

/// A reference's uncoded `sh_rest` value gives the symbol r' = 0, context class 1 (§3.5),
/// not the symbol of the Gaussian before the reference nor its coordinate.
fn rest_uncoded_context() -> Result<ExplicitVector> {
    let mut e = predicted_scene(48, 47)?;
    let d = e.values - REST;
    // The sh_rest value whose context is tested, and a table that gives each context class
    // of every sh_rest value its own scale index (offsets 0), so a wrong class reads the
    // symbol with another table.
    let j = 4;
    for row in &mut e.layer.scale_table[REST..] {
        *row = [2, 12, 22, 32, 42, 50, 56, 63];
    }
    e.layer.scale_offset[3] = [0; 4];
    // Triples (A, B, C): A codes value j with the symbol 40, B leaves it uncoded (its values
    // from j on are their predictions), C codes it with the symbol 1 under B's r' = 0.
    for a in (1..e.voxels.len() - 2).step_by(3) {
        let (b, c) = (a + 1, a + 2);
        let pa = rest_prediction(&e, a, j);
        e.set_coord(a, REST + j, pa + 40);
        for jj in j..d {
            let p = rest_prediction(&e, b, jj);
            e.set_coord(b, REST + jj, p);
        }
        let pc = rest_prediction(&e, c, j);
        e.set_coord(c, REST + j, pc + 1);
        assert!(rest_count(&e, a) > j && rest_count(&e, b) <= j && rest_count(&e, c) > j);
    }
    edited(
        "g-rest-uncoded-context",
        "48 synthetic Gaussians, SH degree 1, every group predicted, each Gaussian's \
         reference the one before, a scale table giving each context class of the sh_rest \
         values its own scale index: in triples A, B, C, A codes sh_rest value 4 with the \
         symbol 40, B leaves it uncoded, C codes it in context class 1, from B's symbol 0 \
         (§3.5)",
        &[],
        e.encode(),
    )
}

/// The probabilities §8.3 gives the events of one context whose bits are `bits`, with its
/// counts halved once their sum passes `limit` (256) or reaches it (`at_limit`), rounding up
/// or (`round_down`) down.
fn context_freqs(bits: &[bool], at_limit: bool, round_down: bool) -> Vec<u32> {
    let (mut c0, mut c1) = (1u32, 1u32);
    let mut out = Vec::with_capacity(bits.len());
    for &b in bits {
        out.push(((c1 << 16) / (c0 + c1)).clamp(1, (1 << 16) - 1));
        *(if b { &mut c1 } else { &mut c0 }) += 1;
        if c0 + c1 > 256 || (at_limit && c0 + c1 == 256) {
            let half = |c: u32| if round_down { c >> 1 } else { (c + 1) >> 1 };
            (c0, c1) = (half(c0), half(c1));
        }
    }
    out
}

/// §8.3's halving: a tile of 400 distinct voxels, so contexts pass 256 events; among them
/// the voxel-count context 0 (§8.4), which reads one 0 per voxel: its counts reach (255, 1),
/// then pass 256 as (256, 1) and become (128, 1), and its later events are coded with that.
fn octree_halving() -> Result<ExplicitVector> {
    let e = encode_synthetic(
        &GaussianParams::new(400, 0, 41),
        vec![RatePlan {
            voxel: 0.002,
            ..base_plan(false)
        }],
        ExplicitOptions {
            klt: Some(vec![false; 4]),
            tile_gaussians: 16_384,
            progressive: false,
            ..Default::default()
        },
    )?;
    let edit = LayerEdit::new(e.stream.clone());
    assert_eq!(edit.tiles.len(), 1);
    // Count context 0 reads one event per voxel: 1 where the voxel holds more Gaussians.
    let mut bits: Vec<bool> = Vec::new();
    for (i, v) in edit.voxels.iter().enumerate() {
        match bits.last_mut() {
            Some(b) if edit.voxels[i - 1] == *v => *b = true,
            _ => bits.push(false),
        }
    }
    let right = context_freqs(&bits, false, false);
    assert!(
        right != context_freqs(&bits, false, true),
        "rounding down changes it"
    );
    assert!(
        right != context_freqs(&bits, true, false),
        "halving at 256 changes it"
    );
    Ok(vector(
        "g-octree-halving",
        "400 synthetic Gaussians, SH degree 0, in one tile of 400 distinct voxels: contexts \
         of §8.3 pass 256 and are halved, among them the voxel-count context 0 (§8.4), which \
         reaches (255, 1), passes 256 as (256, 1) and becomes (128, 1); halving at 256, or \
         rounding down, gives later events other probabilities",
        &["§8.3", "§8.4"],
        e,
    ))
}
