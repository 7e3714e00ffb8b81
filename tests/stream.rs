//! Decoding as bytes arrive (`salvq::stream`): whatever the pieces, the result and the error
//! are the whole-buffer decoder's, and an explicit-profile stream hands out its tiles before
//! it is complete.

mod common;
use common::repo_root;

use salvq::Result;
use salvq::{DecoderBuilder, Scene};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_conformance::explicit_vectors::encode_synthetic;
use salvq_encoder::explicit::{ExplicitOptions, RatePlan};
use salvq_gen::gaussians::GaussianParams;

/// Feeds `stream` in pieces of `piece` bytes (stopping at the first error) and finishes.
fn streamed(stream: &[u8], piece: usize, options: &DecoderBuilder) -> Result<Scene> {
    let mut d = options.build().stream();
    for p in stream.chunks(piece.max(1)) {
        if d.feed(p).is_err() {
            break;
        }
    }
    d.finish()
}

fn vectors() -> Vec<(String, Vec<u8>)> {
    let dir = repo_root().join("conformance/vectors");
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .expect("conformance/vectors")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "salvq"))
        .map(|p| {
            let name = p
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            (name, std::fs::read(&p).expect("a vector"))
        })
        .collect();
    out.sort();
    out
}

#[test]
fn every_vector_streams_to_the_whole_buffer_result() {
    let vectors = vectors();
    assert!(vectors.len() > 100, "{} vectors", vectors.len());
    let mut explicit = 0;
    for (name, bytes) in &vectors {
        let rates = [None, Some(0), Some(1), Some(3)];
        for rate in rates {
            let options = salvq::Decoder::builder().rate(rate);
            let whole = options.build().decode(bytes);
            explicit += usize::from(matches!(whole, Ok(salvq::Scene::Gaussians(_))));
            for piece in [1, 7, 100, 4096, bytes.len()] {
                let got = streamed(bytes, piece, &options);
                assert_eq!(got, whole, "{name}, rate {rate:?}, pieces of {piece} bytes");
            }
        }
    }
    assert!(explicit > 0, "no explicit-profile vector decoded");
}

#[test]
fn truncated_streams_report_what_the_whole_buffer_decoder_reports() {
    let explicit: Vec<_> = vectors()
        .into_iter()
        .filter(|(n, _)| n.starts_with("g-"))
        .collect();
    assert!(explicit.len() >= 10, "{} g-* vectors", explicit.len());
    for (name, bytes) in &explicit {
        for cut in [
            0,
            5,
            12,
            20,
            bytes.len() / 2,
            bytes.len() - 5,
            bytes.len() - 1,
        ] {
            let part = &bytes[..cut.min(bytes.len())];
            let options = salvq::Decoder::builder();
            assert_eq!(
                streamed(part, 3, &options),
                options.build().decode(part),
                "{name} cut at {cut}"
            );
        }
    }
}

fn tiled_stream(tile_gaussians: u32) -> Vec<u8> {
    let plan = RatePlan {
        voxel: 0.05,
        refine: [3, 2, 1, 0],
        steps: vec![0.1, 0.25, 0.03, 0.03, 0.04],
        shift: vec![[1, 0, 0, -1]; 4],
    };
    encode_synthetic(
        &GaussianParams::new(3000, 1, 9),
        vec![plan],
        ExplicitOptions {
            tile_gaussians,
            ..Default::default()
        },
    )
    .expect("encodes")
    .stream
}

#[test]
fn tiles_arrive_before_the_stream_ends_and_add_up_to_the_whole() {
    let stream = tiled_stream(200);
    let mut d = salvq::Decoder::builder().build().stream();
    let mut first_tile_at = None;
    let mut handed_out = Vec::new();
    for (i, piece) in stream.chunks(64).enumerate() {
        d.feed(piece).expect("a valid stream");
        let new = d.new_tiles();
        if first_tile_at.is_none() && !new.is_empty() {
            first_tile_at = Some((i + 1) * 64);
        }
        handed_out.extend(new);
    }
    let first = first_tile_at.expect("tiles were handed out");
    assert!(first < stream.len(), "first tile only at the end");
    let drawn = d.gaussians().clone();
    let Ok(salvq::Scene::Gaussians(whole)) = d.finish() else {
        panic!("an explicit stream")
    };
    assert!(handed_out.len() > 4, "{} tiles", handed_out.len());
    assert_eq!(
        drawn, whole.gaussians,
        "the tiles as handed out are the decode"
    );
    let covered: usize = handed_out.iter().map(|t| t.gaussians.len()).sum();
    assert_eq!(covered, whole.gaussians.len());
}

#[test]
fn a_corrupt_tile_is_reported_as_the_whole_buffer_decoder_reports_it() {
    let stream = tiled_stream(300);
    // Flip a byte near the end (inside GATT), with and without fixing the chunk's CRC.
    let at = stream.len() - 40;
    let mut bad = stream.clone();
    bad[at] ^= 0x5a;
    let options = salvq::Decoder::builder();
    let whole = options.build().decode(&bad);
    assert!(whole.is_err());
    for piece in [1, 50, 1000] {
        assert_eq!(streamed(&bad, piece, &options), whole, "pieces of {piece}");
    }
    // With the CRC recomputed, the tile's own fault is reported, once the chunk is complete,
    // for corruptions in several tiles' bodies.
    let mut faults = 0;
    for back in [30usize, 200, 700, 1500] {
        let Some(edited) =
            salvq_encoder::writers::surgery::edit_payload(&stream, ChunkTag::GATT, |p| {
                let at = p.len().saturating_sub(back);
                p[at] ^= 0xa5;
            })
        else {
            panic!("a GATT chunk")
        };
        let whole = options.build().decode(&edited);
        faults += usize::from(whole.is_err());
        for piece in [1, 50, 1000] {
            assert_eq!(
                streamed(&edited, piece, &options),
                whole,
                "{back} from the end, pieces of {piece}"
            );
        }
    }
    assert!(
        faults > 0,
        "no corruption was detected: the test tests nothing"
    );
}
