//! Decode throughput of a generated 100 k-anchor scene, and where the
//! time goes: full decode vs the integer prior (grid features, MLP, scale indices) vs entropy
//! decoding with per-symbol tables vs the bare constriction coder with one static model on the
//! same symbols. Run: `cargo bench --bench decode_throughput [-- ANCHORS]`.
//! Times are medians of several runs in one process; compare ratios, not absolute numbers.

use std::collections::HashMap;
use std::time::Instant;

use salvq::Limits;
use salvq_bench::coder as measure;
use salvq_bitstream::attributes::layer_bodies;
use salvq_bitstream::container::chunk::{ChunkReader, ChunkTag};
use salvq_bitstream::container::payload::{read_mlps, read_quan};
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::entropy::{GaussianTables, SymbolReader};
use salvq_bitstream::hyperprior::grid::GridRef;
use salvq_bitstream::hyperprior::prior::{AnchorContext, Group, Prior, BATCH};
use salvq_bitstream::model::{Anchors, Dims, SceneModel};
use salvq_bitstream::tiles::TileTable;
use salvq_encoder::{encode_full, EncodeOptions, Encoded};
use salvq_gen::{generate, GenParams};

fn median_secs(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[runs / 2]
}

fn main() {
    let n: u32 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(100_000);
    let model = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(n, 1)
    });
    let e = encode_full(&model, &EncodeOptions::default()).expect("encodes");
    let stream = &e.stream;
    let symbols_total: u64 = e.report().groups.iter().map(|g| g.symbols).sum();
    print_scene(n, &e, symbols_total);

    // Full decode.
    let runs = 5;
    let t_full = median_secs(runs, || {
        let m = salvq::decode(stream)
            .and_then(salvq::Scene::try_into_anchors)
            .expect("decodes");
        assert_eq!(m.anchors.voxel.len(), n as usize);
    });

    // The pieces, rebuilt from the stream's chunks.
    let chunks = StreamChunks::read(stream);
    let prior = chunks.prior();
    let d = &chunks.head.dims;
    let expected = e.expected();
    let mut ctx = prior.context();
    // The grid as the decoder reads it: with its values' signs where it has 4 channels.
    let signs = prior.grid_signs(&expected.grid);
    let grid = GridRef::new(&expected.grid, signs.as_ref());
    let voxels = &expected.anchors.voxel;
    let t_grid = time_grid_features(&prior, grid, voxels, runs);
    let t_mlp = median_secs(runs, || {
        let mut y = vec![0i32; prior.mlp.cout];
        for &v in voxels {
            prior.eval_into(grid, v, &mut ctx, &mut y);
        }
        std::hint::black_box(&y);
    });
    let (t_mlp_batch, batch_ratios) = time_batched_mlp(&prior, grid, voxels, &mut ctx, runs);
    let (t_prior, ks) = time_scale_indices(&prior, grid, d, &expected.anchors, &mut ctx, runs);
    let tiles = chunks.tiles();
    let masks = &expected.anchors.mask;
    let (t_entropy, symbols) =
        time_entropy_decode(&chunks, &tiles, masks, &ks, symbols_total, runs);
    check_symbols(stream, expected, &tiles, d, &symbols);
    let tables = GaussianTables::standard();
    let bare_ns = measure::bare_coder_decode_ns(&symbols, tables.precision(), runs);
    let t_bare = bare_ns * 1e-9 * symbols.len() as f64;
    let rounds = 9;
    let ratios = full_over_bare_ratios(stream, &symbols, rounds);
    print_timings(&Timings {
        n,
        symbols: symbols.len(),
        runs,
        full: t_full,
        grid: t_grid,
        mlp: t_mlp,
        mlp_batch: t_mlp_batch,
        batch_ratios,
        prior: t_prior,
        entropy: t_entropy,
        bare: t_bare,
        bare_ns,
        ratios,
    });
}

/// Prints the scene and, per attribute group, its coded size against the ideal bits.
fn print_scene(n: u32, e: &Encoded, symbols_total: u64) {
    println!(
        "scene: {n} anchors, {symbols_total} attribute symbols, stream {} bytes",
        e.stream.len()
    );
    for g in &e.report().groups {
        println!(
            "  {:<8} coded {:>9} B, ideal(int) {:>11.0} B, ideal(float) {:>11.0} B: coded/int {:.5}, int/float {:.5}",
            g.group,
            g.coded_bytes,
            g.ideal_bits_integer / 8.0,
            g.ideal_bits_float / 8.0,
            g.coded_bytes as f64 * 8.0 / g.ideal_bits_integer,
            g.ideal_bits_integer / g.ideal_bits_float
        );
    }
    let (coded, int, flt) = e.report().groups.iter().fold((0f64, 0f64, 0f64), |a, g| {
        (
            a.0 + g.coded_bytes as f64 * 8.0,
            a.1 + g.ideal_bits_integer,
            a.2 + g.ideal_bits_float,
        )
    });
    println!(
        "  all      coded/int {:.5}, int/float {:.5}",
        coded / int,
        int / flt
    );
}

/// The stream's chunk payloads and its `HEAD`, as a decoder reads them.
struct StreamChunks<'a> {
    payloads: HashMap<ChunkTag, &'a [u8]>,
    head: Preflight,
}

impl<'a> StreamChunks<'a> {
    fn read(stream: &'a [u8]) -> Self {
        let mut r = ChunkReader::new(&stream[12..], 12, &Limits::default());
        let mut payloads = HashMap::new();
        while let Some(c) = r.next_chunk().expect("valid") {
            payloads.insert(c.tag, c.payload);
        }
        let head = Preflight::parse(payloads[&ChunkTag::HEAD], &Limits::default()).expect("head");
        StreamChunks { payloads, head }
    }

    /// The integer prior of rate 0, from `MLPS` and `QUAN`.
    fn prior(&self) -> Prior {
        let d = &self.head.dims;
        let (int_mlp, _) = read_mlps(self.payloads[&ChunkTag::MLPS], d).expect("mlps");
        let quant = read_quan(self.payloads[&ChunkTag::QUAN], d).expect("quan");
        Prior::new(
            d,
            self.head.coord_bits,
            int_mlp,
            [&quant[0], &quant[1], &quant[2]],
            0,
        )
    }

    /// The anchor tiles, from `TILS`.
    fn tiles(&self) -> TileTable {
        let (head, tils) = (&self.head, self.payloads[&ChunkTag::TILS]);
        TileTable::parse(tils, head.dims.anchors, head.coord_bits).expect("TILS")
    }
}

/// Median time of the grid features alone, every anchor.
fn time_grid_features(prior: &Prior, grid: GridRef<'_>, voxels: &[[u32; 3]], runs: usize) -> f64 {
    median_secs(runs, || {
        let mut x = vec![0i16; prior.layout.features()];
        for &v in voxels {
            prior.features(grid, v, &mut x);
        }
        std::hint::black_box(&x);
    })
}

/// The context MLP one anchor at a time and BATCH at a time (as the full decode runs it),
/// back to back in each round; both must give the same outputs. Returns the batched
/// median time and the sorted per-round ratios batched / one at a time.
fn time_batched_mlp(
    prior: &Prior,
    grid: GridRef<'_>,
    voxels: &[[u32; 3]],
    ctx: &mut AnchorContext,
    runs: usize,
) -> (f64, Vec<f64>) {
    let cout = prior.mlp.cout;
    let (mut ys_one, mut ys_batch) = (
        vec![0i32; voxels.len() * cout],
        vec![0i32; voxels.len() * cout],
    );
    let mut eval_one = |ys: &mut [i32]| {
        for (&v, y) in voxels.iter().zip(ys.chunks_exact_mut(cout)) {
            prior.eval_into(grid, v, ctx, y);
        }
    };
    let mut batch_ctx = prior.context();
    let mut eval_batch = |ys: &mut [i32]| {
        let batches = voxels.chunks(BATCH).zip(ys.chunks_mut(BATCH * cout));
        for (v, y) in batches {
            match v.first_chunk::<BATCH>() {
                Some(v) => prior.eval_batch_into(grid, v, &mut batch_ctx, y),
                None => {
                    for (&va, ya) in v.iter().zip(y.chunks_exact_mut(cout)) {
                        prior.eval_into(grid, va, &mut batch_ctx, ya);
                    }
                }
            }
        }
    };
    let mut batch_ratios: Vec<f64> = (0..runs)
        .map(|_| {
            let one = median_secs(1, || eval_one(&mut ys_one));
            let batch = median_secs(1, || eval_batch(&mut ys_batch));
            batch / one
        })
        .collect();
    batch_ratios.sort_by(f64::total_cmp);
    assert!(
        ys_one == ys_batch,
        "the context MLP's outputs differ between one anchor and {BATCH} at a time"
    );
    let t_mlp_batch = median_secs(runs, || eval_batch(&mut ys_batch));
    (t_mlp_batch, batch_ratios)
}

/// Median time of the whole prior (grid, MLP, scale indices), and the scale indices of
/// each group (features, scalings, the offsets whose mask is set) in anchor order.
fn time_scale_indices(
    prior: &Prior,
    grid: GridRef<'_>,
    d: &Dims,
    anchors: &Anchors,
    ctx: &mut AnchorContext,
    runs: usize,
) -> (f64, [Vec<u8>; 3]) {
    let (f, s, k) = (
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        usize::from(d.offsets),
    );
    let mut ks: [Vec<u8>; 3] = [vec![], vec![], vec![]];
    let t_prior = median_secs(runs, || {
        for v in ks.iter_mut() {
            v.clear();
        }
        let mut y = vec![0i32; prior.mlp.cout];
        for (i, &v) in anchors.voxel.iter().enumerate() {
            prior.eval_into(grid, v, ctx, &mut y);
            for (g, width) in [(Group::Feature, f), (Group::Scaling, s)] {
                let step = prior.step(&y, g);
                for j in 0..width {
                    ks[g as usize].push(prior.scale_index(&y, g, j, &step));
                }
            }
            let step = prior.step(&y, Group::Offsets);
            for j in 0..3 * k {
                if anchors.mask[i * k + j / 3] != 0 {
                    ks[2].push(prior.scale_index(&y, Group::Offsets, j, &step));
                }
            }
        }
    });
    (t_prior, ks)
}

/// Median time of entropy decoding with per-symbol tables under the scale indices `ks`,
/// and the symbols decoded.
fn time_entropy_decode(
    chunks: &StreamChunks,
    tiles: &TileTable,
    masks: &[u8],
    ks: &[Vec<u8>; 3],
    symbols_total: u64,
    runs: usize,
) -> (f64, Vec<i64>) {
    let d = &chunks.head.dims;
    let (f, s, k) = (
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        usize::from(d.offsets),
    );
    let tables = GaussianTables::standard();
    let tags = [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF];
    // §10.2: each chunk holds one body per tile; a tile's symbols are its anchors', group by
    // group (offsets only where the mask is set).
    let payloads = tags.map(|t| chunks.payloads[&t]);
    let bodies = layer_bodies(payloads, tiles.len()).expect("tile framing");
    let counts = |t: usize| {
        let r = tiles.range(t);
        let set = masks[r.start * k..r.end * k]
            .iter()
            .filter(|&&m| m != 0)
            .count();
        [r.len() * f, r.len() * s, 3 * set]
    };
    let mut symbols: Vec<i64> = Vec::with_capacity(symbols_total as usize);
    let t_entropy = median_secs(runs, || {
        symbols.clear();
        let mut at = [0usize; 3];
        for (t, b) in bodies.iter().enumerate() {
            let c = counts(t);
            for g in 0..3 {
                let mut reader = SymbolReader::new(tags[g], b[g], tables).expect("reader");
                for &ki in &ks[g][at[g]..at[g] + c[g]] {
                    symbols.push(reader.symbol(ki).expect("symbol"));
                }
                reader.finish().expect("finish");
                at[g] += c[g];
            }
        }
    });
    (t_entropy, symbols)
}

/// What the bench measures is the stream's: the symbols fed to the bare coder are the ones
/// the decoder reads (§11.1's symbol tensors, in the same tile and group order).
fn check_symbols(
    stream: &[u8],
    expected: &SceneModel,
    tiles: &TileTable,
    d: &Dims,
    symbols: &[i64],
) {
    let (f, s, k) = (
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        usize::from(d.offsets),
    );
    let masks = &expected.anchors.mask;
    let (decoded, sy) = salvq::Decoder::default()
        .decode_with_symbols(stream)
        .expect("decodes");
    assert_eq!(
        &decoded, expected,
        "the decode timed is the encoder's prediction"
    );
    let mut stream_symbols = Vec::with_capacity(symbols.len());
    for t in 0..tiles.len() {
        let r = tiles.range(t);
        stream_symbols.extend_from_slice(&sy.feat[r.start * f..r.end * f]);
        stream_symbols.extend_from_slice(&sy.scaling[r.start * s..r.end * s]);
        for i in r {
            for slot in 0..k {
                if masks[i * k + slot] != 0 {
                    stream_symbols.extend_from_slice(&sy.offsets[(i * k + slot) * 3..][..3]);
                }
            }
        }
    }
    assert_eq!(
        symbols, stream_symbols,
        "the bare coder's symbols are the stream's"
    );
    println!(
        "checked: the decode equals the encoder's prediction; {} symbols equal the stream's",
        symbols.len()
    );
}

/// The machine is noisy: the ratio full decode / bare coder is taken within each round
/// (full decode, then the bare coder, back to back); returns the rounds' ratios, sorted.
fn full_over_bare_ratios(stream: &[u8], symbols: &[i64], rounds: usize) -> Vec<f64> {
    let precision = GaussianTables::standard().precision();
    let mut ratios: Vec<f64> = (0..rounds)
        .map(|_| {
            let full = median_secs(1, || {
                std::hint::black_box(
                    salvq::decode(stream)
                        .and_then(salvq::Scene::try_into_anchors)
                        .expect("decodes"),
                );
            });
            let bare =
                measure::bare_coder_decode_ns(symbols, precision, 1) * 1e-9 * symbols.len() as f64;
            full / bare
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    ratios
}

/// What was measured, seconds unless named otherwise.
struct Timings {
    /// Anchors in the scene.
    n: u32,
    /// Attribute symbols decoded.
    symbols: usize,
    /// Runs each median is taken over.
    runs: usize,
    full: f64,
    grid: f64,
    mlp: f64,
    mlp_batch: f64,
    /// Per round, batched / one anchor at a time, sorted.
    batch_ratios: Vec<f64>,
    prior: f64,
    entropy: f64,
    bare: f64,
    /// The bare coder's nanoseconds per symbol.
    bare_ns: f64,
    /// Per round, full decode / bare coder, sorted.
    ratios: Vec<f64>,
}

fn print_timings(t: &Timings) {
    let (runs, rounds) = (t.runs, t.ratios.len());
    let per = |secs: f64| secs * 1e9 / t.symbols as f64;
    println!("\ndecode, medians of {runs} runs:");
    println!(
        "  full decode            {:>8.3} s  {:>7.1} ns/symbol  {:>10.0} anchors/s  {:>11.0} symbols/s",
        t.full,
        per(t.full),
        f64::from(t.n) / t.full,
        t.symbols as f64 / t.full
    );
    println!(
        "  grid features only     {:>8.3} s  {:>7.1} ns/symbol",
        t.grid,
        per(t.grid)
    );
    println!(
        "  grid + MLP             {:>8.3} s  {:>7.1} ns/symbol",
        t.mlp,
        per(t.mlp)
    );
    println!(
        "  grid + MLP, {BATCH} at once  {:>8.3} s  {:>7.1} ns/symbol  (per-round median / one at a time: {:.3}, min {:.3}, max {:.3}; outputs checked equal)",
        t.mlp_batch,
        per(t.mlp_batch),
        t.batch_ratios[runs / 2],
        t.batch_ratios[0],
        t.batch_ratios[runs - 1]
    );
    println!(
        "  prior (grid+MLP+index) {:>8.3} s  {:>7.1} ns/symbol",
        t.prior,
        per(t.prior)
    );
    println!(
        "  entropy decode, tables {:>8.3} s  {:>7.1} ns/symbol",
        t.entropy,
        per(t.entropy)
    );
    println!(
        "  bare coder, one model  {:>8.3} s  {:>7.1} ns/symbol",
        t.bare, t.bare_ns
    );
    println!(
        "ratio full decode / bare coder = {:.2} (medians above); per-round median {:.2} \
         (min {:.2}, max {:.2}, {rounds} rounds; goal <= 3.0); prior / full = {:.2}",
        t.full / t.bare,
        t.ratios[rounds / 2],
        t.ratios[0],
        t.ratios[rounds - 1],
        t.prior / t.full
    );
}
