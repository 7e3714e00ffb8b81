//! The decode_speed bench's anchors-profile scenes: a generated scene encoded with the
//! defaults, decoded natively on 1 and 2 threads and in the wasm package (with the neural
//! Gaussians a viewer draws), against the bare coder on its own symbols.

use std::path::Path;
use std::time::Instant;

use salvq::Decoder;
use salvq::Limits;
use salvq::Scene;
use salvq::Symbols;
use salvq_bench::coder::median;
use salvq_bitstream::container::chunk::{ChunkReader, ChunkTag};
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::container::signature::SIGNATURE_LEN;
use salvq_bitstream::explicit::Gaussians;
use salvq_bitstream::model::SceneModel;
use salvq_bitstream::tiles::TileTable;
use salvq_encoder::{encode_full, EncodeOptions};
use salvq_gen::{generate, GenParams};
use salvq_render::camera::{Bounds, Ring};
use salvq_render::neural;

use super::{
    checked_decode, dump, floor, pinned_pool, round_times, secs, wasm_times, Args, Res, Row,
};

/// What an anchors-profile stream is in salvq-wasm: the neural Gaussians of ring camera 0
/// (Annex C.1, C.2), as `crates/salvq-wasm`'s `decode` computes them.
fn camera0_gaussians(m: &SceneModel) -> Gaussians {
    let bounds = Bounds::of_points(&neural::anchor_positions(m));
    let camera = Ring::default()
        .camera(&bounds, 0, 64, 48)
        .expect("ring camera 0");
    neural::neural_gaussians(m, camera.position).expect("neural Gaussians")
}

/// The tile count of an anchors-profile stream (§10.2, its `TILS` chunk).
fn anchors_tiles(stream: &[u8]) -> Res<usize> {
    let limits = Limits::default();
    let mut r = ChunkReader::new(&stream[SIGNATURE_LEN..], SIGNATURE_LEN as u64, &limits);
    let mut head = None;
    while let Some(c) = r.next_chunk()? {
        match c.tag {
            ChunkTag::HEAD => head = Some(Preflight::parse(c.payload, &limits)?),
            ChunkTag::TILS => {
                let h = head.as_ref().ok_or("TILS before HEAD")?;
                return Ok(TileTable::parse(c.payload, h.dims.anchors, h.coord_bits)?.len());
            }
            _ => {}
        }
    }
    Err("no TILS chunk".into())
}

/// Encodes a generated scene of `n` anchors with the defaults into `path`, unless a cached
/// stream is there and may be reused; returns the encoder's symbol count and its prediction of
/// the decode when it encoded.
fn encode_unless_cached(a: &Args, n: u32, path: &Path) -> Res<(Option<u64>, Option<SceneModel>)> {
    if !(a.fresh || a.smoke || !path.exists()) {
        return Ok((None, None));
    }
    let model = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(n, 1)
    });
    let t = Instant::now();
    let e = encode_full(&model, &EncodeOptions::default())?;
    println!("{n} anchors: encoded in {:.1} s", t.elapsed().as_secs_f64());
    std::fs::write(path, &e.stream)?;
    let encoder_symbols = e.report().groups.iter().map(|g| g.symbols).sum::<u64>();
    Ok((Some(encoder_symbols), Some(e.expected().clone())))
}

/// The symbols the bare coder times, in stream order: features, scalings, then the offsets of
/// the set mask slots; their count is checked against the model's dimensions and, when it
/// encoded, the encoder's.
fn coded_symbols(
    n: u32,
    reference: &SceneModel,
    sy: &Symbols,
    encoder_symbols: Option<u64>,
) -> Vec<i64> {
    let mut symbols: Vec<i64> = sy.feat.clone();
    symbols.extend_from_slice(&sy.scaling);
    for (slot, &m) in reference.anchors.mask.iter().enumerate() {
        if m != 0 {
            symbols.extend_from_slice(&sy.offsets[slot * 3..][..3]);
        }
    }
    let set = reference.anchors.mask.iter().filter(|&&m| m != 0).count();
    let (f, s) = (
        sy.feat.len() / reference.n(),
        sy.scaling.len() / reference.n(),
    );
    assert_eq!(
        symbols.len(),
        reference.n() * (f + s) + 3 * set,
        "{n} anchors: symbol count"
    );
    if let Some(c) = encoder_symbols {
        assert_eq!(
            symbols.len() as u64,
            c,
            "{n} anchors: symbols = the encoder's"
        );
    }
    symbols
}

/// One generated scene's row (anchors profile, `n` anchors): its stream decoded in process and
/// in the wasm package, each timed and checked, against the bare coder on its symbols.
pub(crate) fn anchors_scene(a: &Args, n: u32, cache: &Path, pkg: Option<&Path>) -> Res<Row> {
    let path = cache.join(format!("anchors_{n}.salvq"));
    let (encoder_symbols, expected) = encode_unless_cached(a, n, &path)?;
    let stream = std::fs::read(&path)?;
    let one_opts = salvq::Decoder::builder().threads(1);
    let (reference, sy) = one_opts.build().decode_with_symbols(&stream)?;
    if let Some(expected) = &expected {
        assert!(
            reference == *expected,
            "{n} anchors: the decode is the encoder's prediction"
        );
    }
    let symbols = coded_symbols(n, &reference, &sy, encoder_symbols);
    let mut row = Row {
        profile: "anchors",
        scene: format!("generated {n}"),
        size: n as usize,
        symbols: symbols.len(),
        bytes: stream.len() as u64,
        tiles: anchors_tiles(&stream)?,
        ..Row::default()
    };
    (row.floor, row.floor_outside) = floor(&symbols, a.rounds);
    let d1 = Decoder::builder().threads(1).build();
    let d2 = Decoder::builder().threads(2).build();
    let d2p = pinned_pool(2).map(|p| Decoder::builder().thread_pool(p).build());
    let pool1 = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (mut t1, mut t2, mut t2b, mut ratio, mut tw) = (vec![], vec![], vec![], vec![], vec![]);
    let mut t2p = vec![];
    let mut neural = None;
    drop((d1.decode(&stream), d2.decode(&stream)));
    drop(d2p.as_ref().map(|d| d.decode(&stream)));
    let same = |got: &salvq::Result<Scene>| {
        let Ok(salvq::Scene::Anchors(m)) = got else {
            return false;
        };
        **m == reference
    };
    let decode = |d: &Decoder, what: &str| {
        checked_decode(d, &stream, same, &format!("{n} anchors: the {what}"))
    };
    for _ in 0..a.rounds {
        let (s1, s2, again, pinned) = round_times(&d1, &d2, d2p.as_ref(), decode);
        t2p.extend(pinned);
        t1.push(s1);
        t2.push(s2);
        t2b.push(again);
        ratio.push(s2 / s1);
        if pkg.is_some() {
            tw.push(secs(|| {
                pool1.install(|| {
                    let Ok(salvq::Scene::Anchors(m)) = d1.decode(&stream) else {
                        panic!("decodes")
                    };
                    neural = Some(camera0_gaussians(&m));
                });
            }));
        }
    }
    row.one = median(&mut t1);
    row.two = median(&mut t2);
    row.two_again = median(&mut t2b);
    row.two_pinned = (!t2p.is_empty()).then(|| median(&mut t2p));
    row.two_over_one = median(&mut ratio);
    if let (Some(pkg), Some(g)) = (pkg, &neural) {
        row.wasm_native = median(&mut tw);
        let expected = dump(g);
        row.wasm = Some(wasm_times(pkg, &path, a.rounds, &expected, &row.scene, 0)?);
        let on = |workers| wasm_times(pkg, &path, a.rounds, &expected, &row.scene, workers);
        row.wasm_workers = Some([on(1)?.0, on(2)?.0]);
    }
    println!(
        "{n} anchors: {} B; 1 thread {:.4} s, 2 threads {:.4} s",
        row.bytes, row.one, row.two
    );
    Ok(row)
}
