//! Time to first tile: an explicit-profile stream of N generated Gaussians fed to
//! `salvq::StreamDecoder` in 64 KiB pieces, as a viewer receives it, against the
//! whole-buffer decode of the same bytes on one thread and on rayon's pool. Prints the bytes
//! and the decode time at which the first tile is handed out, and the whole decode's time.
//! Checks what it measures: the streamed Gaussians equal the whole decode's.
//! Run: `cargo bench --bench first_tile` (N = 1 000 000; `SALVQ_BENCH_GAUSSIANS=N` changes
//! it, CI runs 20 000), or `SALVQ_BENCH_STREAM=scene.salvq cargo bench --bench first_tile` for
//! a stream written by `salvq encode` (its lowest rate).

use std::time::Instant;

use salvq::Scene;
use salvq_conformance::explicit_vectors::encode_synthetic;
use salvq_encoder::explicit::{ExplicitOptions, RatePlan};
use salvq_gen::gaussians::GaussianParams;

const PIECE: usize = 64 << 10;

fn whole(stream: &[u8], threads: Option<usize>) -> (f64, Scene) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let t = Instant::now();
        let d = (salvq::Decoder::builder().threads(threads))
            .build()
            .decode(stream)
            .expect("decodes");
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(d);
    }
    (best, out.expect("three runs"))
}

fn main() {
    let n: usize = std::env::var("SALVQ_BENCH_GAUSSIANS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let given = std::env::var_os("SALVQ_BENCH_STREAM");
    let stream = match given {
        Some(path) => {
            let stream = std::fs::read(&path).expect("SALVQ_BENCH_STREAM: a readable stream");
            println!("{}: {} bytes", path.to_string_lossy(), stream.len());
            stream
        }
        None => generated(n),
    };
    measure(&stream);
}

/// A stream of `n` generated Gaussians, one rate.
fn generated(n: usize) -> Vec<u8> {
    let plan = RatePlan {
        voxel: 0.02,
        refine: [3, 2, 1, 0],
        steps: vec![0.05, 0.2, 0.02, 0.02, 0.03],
        shift: vec![[1, 0, 0, -1]; 4],
    };
    let t = Instant::now();
    let e = encode_synthetic(
        &GaussianParams::new(n, 1, 5),
        vec![plan],
        ExplicitOptions::default(),
    )
    .expect("encodes");
    println!(
        "{n} generated Gaussians (SH 1), one rate: {} bytes, {} tiles, encoded in {:.1} s",
        e.stream.len(),
        e.layers[0].0.tiles,
        t.elapsed().as_secs_f64()
    );
    e.stream
}

fn measure(stream: &[u8]) {
    let (one, reference) = whole(stream, Some(1));
    let (pool, _) = whole(stream, None);
    let salvq::Scene::Gaussians(reference) = reference else {
        panic!("an explicit-profile stream")
    };
    println!(
        "{} Gaussians, {} tiles",
        reference.gaussians.len(),
        reference.tiles.len()
    );

    let mut decoder = salvq::Decoder::builder().build().stream();
    let mut spent = 0.0;
    let mut first = None;
    for piece in stream.chunks(PIECE) {
        let t = Instant::now();
        decoder.feed(piece).expect("a valid stream");
        let tiles = decoder.new_tiles().len();
        spent += t.elapsed().as_secs_f64();
        if first.is_none() && tiles > 0 {
            first = Some((decoder.received(), spent, decoder.gaussians().len()));
        }
    }
    let t = Instant::now();
    let streamed = decoder.finish().expect("a valid stream");
    spent += t.elapsed().as_secs_f64();
    let salvq::Scene::Gaussians(streamed) = streamed else {
        panic!("an explicit-profile stream")
    };
    assert_eq!(
        streamed.gaussians, reference.gaussians,
        "streamed = whole decode"
    );
    let (bytes, secs, count) = first.expect("a tile before the end");
    println!(
        "whole decode: {:.4} s on 1 thread, {:.4} s on {} threads",
        one,
        pool,
        rayon::current_num_threads()
    );
    println!(
        "streamed in {} KiB pieces: first tile after {} of {} bytes ({:.1} %), {:.4} s of decoding, {} Gaussians; \
all tiles {:.3} s of decoding",
        PIECE >> 10,
        bytes,
        stream.len(),
        100.0 * bytes as f64 / stream.len() as f64,
        secs,
        count,
        spent
    );
    println!(
        "time to first tile / whole decode on 1 thread: {:.4}",
        secs / one
    );
}
