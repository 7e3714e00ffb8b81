//! The SALVQ decoder for the web: a stream of either profile decoded into typed
//! arrays of standard 3DGS Gaussians, laid out as the Inria PLY stores them (log-scales,
//! opacity logits, quaternions w x y z, SH channel-major), whole ([`decode`]) or as its
//! bytes arrive ([`Stream`]).
//!
//! An explicit-profile stream (spec §3) decodes to its Gaussians; its tiles come out of
//! [`Stream::take`] as their bytes arrive. An anchors-profile stream decodes to a scene
//! model whose Gaussians depend on the camera (Scaffold-GS, Annex C.1); they are computed
//! for ring camera 0 of Annex C.2, as `salvq export-ply` does, once the stream is complete.
//!
//! Decoding runs on the calling thread (a Web Worker, say). Several workers decode a stream
//! together with [`decode_part`]: each is given the whole stream and decodes its part of the
//! tiles (spec §10.3.2). The package is built with
//! WebAssembly SIMD (`simd128`, the workspace's `.cargo/config.toml`); the compiler keeps every
//! floating-point operation's order and rounding (lane by lane, never a fused multiply-add), so
//! the output is the same bits as the native decoder's (§10.3). With it, the anchors' context
//! MLP (§5.3) runs in the decoder's WebAssembly SIMD kernel (the `simd` feature).

use wasm_bindgen::prelude::*;

use salvq::camera::{Bounds, Ring};
use salvq::neural;
use salvq::StreamDecoder;
use salvq::{DecoderBuilder, Limits, Scene, SceneModel, TilePart};
use salvq_bitstream::container::chunk::{ChunkReader, ChunkTag};
use salvq_bitstream::container::order::{ChunkOrder, Position, Profile};
use salvq_bitstream::container::payload::read_apos;
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::container::signature::{Signature, SIGNATURE_LEN};
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::Gaussians;
use salvq_bitstream::tiles::TileTable;

/// A batch of Gaussians as typed arrays (copied out on each getter call).
#[wasm_bindgen]
pub struct Batch {
    gaussians: Gaussians,
    /// Tiles in the batch (explicit profile; 0 for an anchors-profile stream).
    tiles: usize,
    /// The tiles whose Gaussians the batch holds, in order, and their Gaussian counts
    /// (explicit profile, and an anchors stream's part; empty for a whole anchors stream).
    tile_indices: Vec<u32>,
    tile_counts: Vec<u32>,
    /// Whether the batch holds every Gaussian shown so far at a finer rate, to replace them
    /// (a progressive stream's refinement, spec §3.8), rather than Gaussians to add.
    replaces: bool,
}

#[wasm_bindgen]
impl Batch {
    /// Number of Gaussians.
    #[wasm_bindgen(getter)]
    pub fn count(&self) -> usize {
        self.gaussians.len()
    }

    /// Tiles the batch completes (explicit profile).
    #[wasm_bindgen(getter)]
    pub fn tiles(&self) -> usize {
        self.tiles
    }

    /// The `TILS` index (§10.1) of each tile whose Gaussians the batch holds, in the order
    /// they come (explicit profile, and an anchors stream's `decodePart`; empty for a whole
    /// anchors stream). With
    /// `tileCounts`, what puts the batches of several workers back in stream order.
    #[wasm_bindgen(getter, js_name = tileIndices)]
    pub fn tile_indices(&self) -> Vec<u32> {
        self.tile_indices.clone()
    }

    /// The Gaussian count of each tile of `tileIndices`.
    #[wasm_bindgen(getter, js_name = tileCounts)]
    pub fn tile_counts(&self) -> Vec<u32> {
        self.tile_counts.clone()
    }

    /// Whether the batch replaces every Gaussian taken before it with the same Gaussians at
    /// a finer rate (a progressive stream's refinement, spec §3.8) instead of adding to them.
    #[wasm_bindgen(getter)]
    pub fn replaces(&self) -> bool {
        self.replaces
    }

    /// SH degree, 0 … 3.
    #[wasm_bindgen(getter, js_name = shDegree)]
    pub fn sh_degree(&self) -> u8 {
        self.gaussians.sh_degree
    }

    /// Means, `x y z` per Gaussian.
    #[wasm_bindgen(getter)]
    pub fn positions(&self) -> Vec<f32> {
        self.gaussians.positions.iter().flatten().copied().collect()
    }

    /// Natural logarithms of the three axis scales per Gaussian.
    #[wasm_bindgen(getter, js_name = logScales)]
    pub fn log_scales(&self) -> Vec<f32> {
        self.gaussians
            .log_scales
            .iter()
            .flatten()
            .copied()
            .collect()
    }

    /// Rotation quaternions `w x y z` per Gaussian.
    #[wasm_bindgen(getter)]
    pub fn rotations(&self) -> Vec<f32> {
        self.gaussians.rotations.iter().flatten().copied().collect()
    }

    /// Opacity logits, one per Gaussian.
    #[wasm_bindgen(getter, js_name = opacityLogits)]
    pub fn opacity_logits(&self) -> Vec<f32> {
        self.gaussians.opacity_logit.clone()
    }

    /// SH band 0, three colour channels per Gaussian (`f_dc_0..2`).
    #[wasm_bindgen(getter, js_name = shDc)]
    pub fn sh_dc(&self) -> Vec<f32> {
        self.gaussians.f_dc.iter().flatten().copied().collect()
    }

    /// The higher SH coefficients, `3·B` per Gaussian channel-major (`f_rest_*`).
    #[wasm_bindgen(getter, js_name = shRest)]
    pub fn sh_rest(&self) -> Vec<f32> {
        self.gaussians.f_rest.clone()
    }
}

/// A viewer needs the Gaussians, not the symbols they came from.
fn options(rate: Option<u8>) -> DecoderBuilder {
    salvq::Decoder::builder().rate(rate).gaussians_only(true)
}

fn to_js(e: impl std::fmt::Display) -> JsError {
    JsError::new(&e.to_string())
}

/// The Gaussians of a decoded stream: an explicit stream's own, or an anchors-profile
/// model's neural Gaussians seen from ring camera 0 (Annex C.1, C.2).
fn gaussians_of(decoded: Scene) -> Result<Gaussians, JsError> {
    match decoded {
        salvq::Scene::Gaussians(d) => Ok(d.gaussians),
        salvq::Scene::Anchors(m) => {
            let positions = neural::anchor_positions(&m);
            Ok(anchor_gaussians(&m, &positions)?.0)
        }
    }
}

/// The neural Gaussians of `m`'s anchors seen from ring camera 0 of the scene whose anchors
/// are at `scene` (Annex C.2: the camera follows from every anchor, also for a part), and
/// how many each anchor gave.
fn anchor_gaussians(m: &SceneModel, scene: &[[f32; 3]]) -> Result<(Gaussians, Vec<u32>), JsError> {
    let camera = Ring::default()
        .camera(&Bounds::of_points(scene), 0, 64, 48)
        .map_err(to_js)?;
    neural::neural_gaussians_counted(m, camera.position).map_err(to_js)
}

/// Every anchor's world position (as `neural::anchor_positions` gives them) and the tile
/// table of an anchors-profile stream, from its `HEAD`, `TILS` and `APOS` alone: what a part
/// decode, which outputs its own tiles' anchors, needs for the whole scene's camera.
fn scene_anchors(bytes: &[u8]) -> salvq::Result<(Vec<[f32; 3]>, TileTable)> {
    let limits = Limits::default();
    let (_, rest) = Signature::parse(bytes)?;
    let mut reader = ChunkReader::new(rest, SIGNATURE_LEN as u64, &limits);
    let mut order = ChunkOrder::new(Profile::Anchors);
    let (mut head, mut tiles) = (None, None);
    while let Some(chunk) = reader.next_chunk()? {
        if order.step(chunk.tag)? == Position::Ancillary {
            continue;
        }
        match (chunk.tag, &head, tiles.take()) {
            (ChunkTag::HEAD, _, _) => head = Some(Preflight::parse(chunk.payload, &limits)?),
            (ChunkTag::TILS, Some(h), _) => {
                let t = TileTable::parse(chunk.payload, h.dims.anchors, h.coord_bits)?;
                tiles = Some(t);
            }
            (ChunkTag::APOS, Some(h), Some(t)) => {
                let voxels = read_apos(chunk.payload, &t, GaussianTables::standard())?;
                let positions = voxels
                    .iter()
                    .map(|v| std::array::from_fn(|a| h.origin[a] + h.voxel_size * v[a] as f32))
                    .collect();
                return Ok((positions, t));
            }
            (_, _, t) => tiles = t,
        }
    }
    // Unreachable after a part decode of the same bytes succeeded: it read all three.
    Err(ChunkOrder::missing(ChunkTag::APOS))
}

/// The tiles `kept` marks, in order, and the Gaussian count `count(t)` of each.
fn tile_list(kept: &[bool], mut count: impl FnMut(usize) -> u32) -> (Vec<u32>, Vec<u32>) {
    (0..kept.len())
        .filter(|&t| kept[t])
        .map(|t| (t as u32, count(t)))
        .unzip()
}

/// A decoded stream as one batch: for an explicit stream, with the tiles `part` kept.
fn batch_of(decoded: Scene, part: Option<TilePart>) -> Result<Batch, JsError> {
    let (tile_indices, tile_counts) = match &decoded {
        salvq::Scene::Gaussians(d) => {
            let kept = d
                .tiles
                .select(d.header.origin, d.layer.voxel_size, None, part);
            tile_list(&kept, |t| d.tiles.count(t))
        }
        salvq::Scene::Anchors(_) => (Vec::new(), Vec::new()),
    };
    Ok(Batch {
        gaussians: gaussians_of(decoded)?,
        tiles: 0,
        tile_indices,
        tile_counts,
        replaces: false,
    })
}

/// Decodes a whole stream at `rate` (default: the lowest coded rate).
#[wasm_bindgen]
pub fn decode(bytes: &[u8], rate: Option<u8>) -> Result<Batch, JsError> {
    batch_of((options(rate)).build().decode(bytes).map_err(to_js)?, None)
}

/// Decodes part `part` (from 0) of `parts` of a stream's tiles at `rate` (spec §10.3.2):
/// `parts` workers, each given the whole stream and its own `part`, decode it together,
/// every tile once. `tileIndices` and `tileCounts` say which tiles a batch holds. For an
/// anchors-profile stream, the part's anchors' neural Gaussians as [`decode`] computes them
/// (the camera follows from every anchor, whose positions the part reads again from `APOS`).
#[wasm_bindgen(js_name = decodePart)]
pub fn decode_part(
    bytes: &[u8],
    rate: Option<u8>,
    part: u32,
    parts: u32,
) -> Result<Batch, JsError> {
    let part = TilePart::new(part, parts).ok_or_else(|| {
        JsError::new(&format!(
            "part {part} of {parts}: a part is from 0 to parts - 1 [§10.3.2]"
        ))
    })?;
    let options = options(rate).part(Some(part));
    match options.build().decode(bytes).map_err(to_js)? {
        salvq::Scene::Anchors(m) => anchors_part(bytes, &m, part),
        explicit => batch_of(explicit, Some(part)),
    }
}

/// [`decode_part`] of an anchors-profile stream, its part decoded into `m`.
fn anchors_part(bytes: &[u8], m: &SceneModel, part: TilePart) -> Result<Batch, JsError> {
    let (scene, tiles) = scene_anchors(bytes).map_err(to_js)?;
    let (gaussians, per_anchor) = anchor_gaussians(m, &scene)?;
    let kept = tiles.select(m.origin, m.voxel_size, None, Some(part));
    // The part's anchors are its tiles', in order: each tile's count sums its anchors'.
    let mut at = 0;
    let (tile_indices, tile_counts) = tile_list(&kept, |t| {
        let n = tiles.range(t).len();
        at += n;
        per_anchor.get(at - n..at).map_or(0, |c| c.iter().sum())
    });
    Ok(Batch {
        gaussians,
        tiles: 0,
        tile_indices,
        tile_counts,
        replaces: false,
    })
}

/// A stream decoded as its bytes arrive: [`Stream::feed`] each piece, [`Stream::take`] the
/// Gaussians of the tiles completed so far, [`Stream::finish`] at the end.
#[wasm_bindgen]
pub struct Stream {
    inner: Option<StreamDecoder>,
    /// Gaussians already handed out by `take`.
    taken: usize,
    tiles_taken: usize,
}

#[wasm_bindgen]
impl Stream {
    /// A decoder for `rate` (default: the lowest coded rate).
    #[wasm_bindgen(constructor)]
    pub fn new(rate: Option<u8>) -> Stream {
        Stream {
            inner: Some(options(rate).build().stream()),
            taken: 0,
            tiles_taken: 0,
        }
    }

    /// Takes the next bytes; an error means the stream is broken whatever follows.
    pub fn feed(&mut self, bytes: &[u8]) -> Result<(), JsError> {
        let inner = self.inner.as_mut().ok_or_else(finished)?;
        inner.feed(bytes).map_err(to_js)
    }

    /// The Gaussians of the tiles completed since the last call (provisional until
    /// [`Stream::finish`] confirms the stream).
    pub fn take(&mut self) -> Result<Batch, JsError> {
        let inner = self.inner.as_mut().ok_or_else(finished)?;
        let new_tiles = &inner.tiles()[self.tiles_taken..];
        // §3.8: a refinement hands out the first layer's tiles again, at a finer rate: every
        // Gaussian, to replace those shown.
        let first_rate = inner.tiles().first().map(|t| t.rate);
        if new_tiles.iter().any(|t| Some(t.rate) != first_rate) {
            let all = inner.gaussians();
            let batch = Batch {
                gaussians: slice(all, 0),
                tiles: new_tiles.len(),
                tile_indices: new_tiles.iter().map(|t| t.index as u32).collect(),
                tile_counts: new_tiles.iter().map(|t| t.gaussians.len() as u32).collect(),
                replaces: true,
            };
            self.tiles_taken = inner.tiles().len();
            self.taken = all.len();
            return Ok(batch);
        }
        let tile_indices = new_tiles.iter().map(|t| t.index as u32).collect();
        let tile_counts = new_tiles.iter().map(|t| t.gaussians.len() as u32).collect();
        let tiles = new_tiles.len();
        self.tiles_taken = inner.tiles().len();
        let all = inner.gaussians();
        let from = self.taken;
        self.taken = all.len();
        Ok(Batch {
            gaussians: slice(all, from),
            tiles,
            tile_indices,
            tile_counts,
            replaces: false,
        })
    }

    /// Bytes received so far.
    pub fn received(&self) -> usize {
        self.inner.as_ref().map_or(0, StreamDecoder::received)
    }

    /// Ends the stream: the Gaussians not yet taken (for an anchors-profile stream, all of
    /// them), or the error the whole-buffer decoder reports for these bytes.
    pub fn finish(&mut self) -> Result<Batch, JsError> {
        let inner = self.inner.take().ok_or_else(finished)?;
        let decoded = inner.finish().map_err(to_js)?;
        // An explicit stream's tiles complete in order: the ones not yet taken are the rest.
        let (tile_indices, tile_counts) = match &decoded {
            salvq::Scene::Gaussians(d) => (self.tiles_taken..d.tiles.len())
                .map(|t| (t as u32, d.tiles.count(t)))
                .unzip(),
            salvq::Scene::Anchors(_) => (Vec::new(), Vec::new()),
        };
        let all = gaussians_of(decoded)?;
        let from = self.taken.min(all.len());
        Ok(Batch {
            gaussians: slice(&all, from),
            tiles: 0,
            tile_indices,
            tile_counts,
            replaces: false,
        })
    }
}

fn finished() -> JsError {
    JsError::new("the stream was finished")
}

/// Gaussians `from..` of `g`.
fn slice(g: &Gaussians, from: usize) -> Gaussians {
    let b = 3 * g.rest_per_channel();
    Gaussians {
        positions: g.positions[from..].to_vec(),
        sh_degree: g.sh_degree,
        f_dc: g.f_dc[from..].to_vec(),
        f_rest: g.f_rest[from * b..].to_vec(),
        opacity_logit: g.opacity_logit[from..].to_vec(),
        log_scales: g.log_scales[from..].to_vec(),
        rotations: g.rotations[from..].to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arrays of `batches` put back in stream order by their tiles, as a page with
    /// several workers does: positions and opacity logits, float bits.
    fn in_stream_order(batches: &[Batch]) -> (Vec<u32>, Vec<u32>) {
        let mut pieces = Vec::new();
        for b in batches {
            let mut at = 0;
            for (&t, &n) in b.tile_indices.iter().zip(&b.tile_counts) {
                pieces.push((t, b, at, n as usize));
                at += n as usize;
            }
            assert_eq!(at, b.count(), "a batch's tiles hold its Gaussians");
        }
        pieces.sort_by_key(|p| p.0);
        let (mut positions, mut opacity) = (Vec::new(), Vec::new());
        for (_, b, at, n) in pieces {
            let p = b.positions();
            positions.extend(p[3 * at..3 * (at + n)].iter().map(|x| x.to_bits()));
            let o = b.opacity_logits();
            opacity.extend(o[at..at + n].iter().map(|x| x.to_bits()));
        }
        (positions, opacity)
    }

    fn check_parts(stream: &[u8], what: &str) {
        let whole = decode(stream, None).unwrap_or_else(|_| panic!("{what} decodes"));
        let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
        let expected = (bits(whole.positions()), bits(whole.opacity_logits()));
        assert!(!expected.1.is_empty(), "{what}");
        for parts in [1, 2, 3] {
            let batches: Vec<Batch> = (0..parts)
                .map(|k| decode_part(stream, None, k, parts).unwrap_or_else(|_| panic!("{what}")))
                .collect();
            if parts > 1 {
                assert!(batches.iter().all(|b| b.count() < whole.count()), "{what}");
            }
            assert_eq!(in_stream_order(&batches), expected, "{what}, {parts} parts");
        }
    }

    #[test]
    fn parts_put_together_are_the_whole_decode() {
        // Anchors: 1 200 anchors in tiles of at most 100; the parts' neural Gaussians use the
        // whole scene's camera.
        let model = salvq_gen::generate(&salvq_gen::GenParams::small(1200, 5));
        let options = salvq_encoder::EncodeOptions {
            tile_anchors: 100,
            ..Default::default()
        };
        let anchors = salvq_encoder::encode_full(&model, &options).unwrap();
        check_parts(&anchors.stream, "anchors");
        // Explicit: 900 Gaussians in tiles of at most 60.
        let explicit = salvq_conformance::explicit_vectors::encode_synthetic(
            &salvq_gen::gaussians::GaussianParams::new(900, 1, 7),
            vec![salvq_encoder::explicit::RatePlan {
                voxel: 0.05,
                refine: [3, 2, 1, 0],
                steps: vec![0.1, 0.25, 0.03, 0.03, 0.04],
                shift: vec![[1, 0, 0, -1]; 4],
            }],
            salvq_encoder::explicit::ExplicitOptions {
                tile_gaussians: 60,
                ..Default::default()
            },
        )
        .unwrap();
        check_parts(&explicit.stream, "explicit");
    }

    #[test]
    fn a_stream_replaces_the_coarse_rate_with_each_refinement() {
        let plan = |f: f64| salvq_encoder::explicit::RatePlan {
            voxel: 0.05 * f,
            refine: [3, 2, 1, 0],
            steps: [0.1, 0.25, 0.03, 0.03, 0.04].map(|s| s * f).to_vec(),
            shift: vec![[1, 0, 0, -1]; 4],
        };
        let e = salvq_conformance::explicit_vectors::encode_synthetic(
            &salvq_gen::gaussians::GaussianParams::new(500, 1, 9),
            vec![plan(1.0), plan(4.0)],
            salvq_encoder::explicit::ExplicitOptions {
                tile_gaussians: 60,
                ..Default::default()
            },
        )
        .unwrap();
        let mut stream = Stream::new(None);
        // What a page shows: batches added, and replaced by a refinement.
        let mut shown: Vec<Batch> = Vec::new();
        let mut replaced = 0;
        for piece in e.stream.chunks(200) {
            stream.feed(piece).unwrap();
            let b = stream.take().unwrap();
            if b.replaces() {
                replaced += 1;
                shown.clear();
            }
            shown.push(b);
        }
        shown.push(stream.finish().unwrap());
        assert_eq!(replaced, 1, "one refinement");
        let whole = decode(&e.stream, None).unwrap();
        let positions: Vec<f32> = shown.iter().flat_map(|b| b.positions()).collect();
        assert!(
            positions == whole.positions(),
            "the finest rate, each Gaussian once"
        );
    }
}
