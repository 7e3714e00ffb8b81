//! Progressive explicit streams (spec §3.8): every rate decodes to what the encoder
//! predicted, a rate's extraction is the stream's prefix (and the stream of the coarser rates
//! coded alone), and a stream cut anywhere decodes, where the caller accepts it, to its last
//! complete rate.

use salvq::DecodedGaussians;
use salvq::Limits;
use salvq::Scene;
use salvq_conformance::explicit_vectors::encode_synthetic;
use salvq_encoder::explicit::{EncodedGaussians, ExplicitOptions, RatePlan};
use salvq_gen::gaussians::GaussianParams;

/// Three rates whose steps and voxel double per rate (rate 0 the finest).
fn plans() -> Vec<RatePlan> {
    (0..3)
        .map(|k| {
            let f = (k as f64).exp2();
            RatePlan {
                voxel: 0.05 * f,
                refine: [3, 2, 1, 0],
                steps: [0.1, 0.25, 0.03, 0.03, 0.04].map(|s| s * f).to_vec(),
                shift: vec![[1, 0, 0, -1], [2, 1, 0, 0], [1, 0, 0, 0], [2, 1, 0, 0]],
            }
        })
        .collect()
}

fn encode(coded: Option<Vec<u8>>) -> EncodedGaussians {
    encode_synthetic(
        &GaussianParams::new(500, 3, 31),
        plans(),
        ExplicitOptions {
            coded,
            tile_gaussians: 64,
            ..Default::default()
        },
    )
    .unwrap()
}

fn decoded(d: Scene) -> DecodedGaussians {
    match d {
        salvq::Scene::Gaussians(g) => *g,
        salvq::Scene::Anchors(_) => panic!("an explicit stream"),
    }
}

#[test]
fn every_rate_decodes_to_the_encoders_prediction() {
    let e = encode(None);
    assert!(e.header.progressive);
    let rates: Vec<u8> = e.layers.iter().map(|l| l.0.rate).collect();
    assert_eq!(rates, [2, 1, 0], "the coarsest rate first");
    for (report, _, expected) in &e.layers {
        let d = salvq::Decoder::builder()
            .limits(Limits::default())
            .rate(Some(report.rate))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_gaussians)
            .unwrap();
        assert_eq!(d.rate, report.rate);
        assert!(!d.truncated);
        assert!(d.gaussians == *expected, "rate {}", report.rate);
    }
    let finest = salvq::Decoder::builder()
        .limits(Limits::default())
        .rate(None)
        .build()
        .decode(&e.stream)
        .and_then(salvq::Scene::try_into_gaussians)
        .unwrap();
    assert_eq!(finest.rate, 0, "the finest rate by default");
}

#[test]
fn refinements_are_smaller_than_coding_the_rate_alone() {
    let e = encode(None);
    let layered = encode_synthetic(
        &GaussianParams::new(500, 3, 31),
        plans(),
        ExplicitOptions {
            tile_gaussians: 64,
            progressive: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        e.stream.len() < layered.stream.len(),
        "progressive {} bytes, layered {}",
        e.stream.len(),
        layered.stream.len()
    );
}

#[test]
fn extraction_is_the_prefix_and_the_coarser_rates_coded_alone() {
    let e = encode(None);
    for r in 0..3u8 {
        let extracted = salvq::extract_rate(&e.stream, r, &Limits::default()).unwrap();
        let alone = encode(Some((r..3).collect()));
        assert_eq!(extracted, alone.stream, "rate {r}");
        // After GHED (whose rate_mask changed), a prefix of the stream.
        let ghed_end = salvq_bitstream::container::signature::SIGNATURE_LEN + 8 + 35 + 4;
        let prefix = &extracted[ghed_end..extracted.len() - 12];
        let same = &e.stream[ghed_end..ghed_end + prefix.len()];
        assert!(prefix == same, "rate {r} is a prefix");
        let d = salvq::Decoder::builder()
            .limits(Limits::default())
            .rate(None)
            .build()
            .decode(&extracted)
            .and_then(salvq::Scene::try_into_gaussians)
            .unwrap();
        let expected = &e.layers.iter().find(|l| l.0.rate == r).unwrap().2;
        assert!(d.gaussians == *expected, "rate {r}");
    }
}

#[test]
fn a_cut_stream_decodes_to_its_last_complete_rate() {
    let e = encode(None);
    let accept = salvq::Decoder::builder().accept_prefix(true);
    // Where each rate's last chunk ends.
    let mut ends = Vec::new();
    let mut at = e.stream.len() - 12;
    for (_, bytes, _) in e.layers.iter().rev() {
        ends.push(at);
        at -= bytes;
    }
    ends.reverse();
    let mut last = None;
    for cut in (0..e.stream.len()).step_by(97).chain(ends.iter().copied()) {
        let data = &e.stream[..cut];
        let complete = e.layers.iter().zip(&ends).rfind(|(_, &end)| end <= cut);
        match (accept.build().decode(data), complete) {
            (Ok(d), Some(((report, _, expected), _))) => {
                let d = decoded(d);
                assert!(d.truncated, "cut at {cut}");
                assert_eq!(d.rate, report.rate, "cut at {cut}");
                assert!(d.gaussians == *expected, "cut at {cut}");
                last = Some(d.rate);
            }
            (Err(e), None) => assert!(e.is_truncation() || cut < 40, "cut at {cut}: {e}"),
            (got, want) => panic!(
                "cut at {cut}: {:?}, expected rate {:?}",
                got.map(|d| decoded(d).rate),
                want.map(|w| w.0 .0.rate)
            ),
        }
        // Without consent, every cut is an error.
        assert!((salvq::Decoder::builder()).build().decode(data).is_err());
    }
    assert_eq!(last, Some(0));
}

#[test]
fn info_gives_each_rates_prefix_and_where_it_ends() {
    let e = encode(None);
    let info =
        salvq_encoder::info::explicit::inspect_explicit(&e.stream, &Limits::default()).unwrap();
    assert!(info.progressive);
    let rates: Vec<u8> = info.layers.iter().map(|l| l.rate).collect();
    assert_eq!(rates, [0, 1, 2], "finest first");
    for l in &info.layers {
        let extracted = salvq::extract_rate(&e.stream, l.rate, &Limits::default()).unwrap();
        assert_eq!(
            l.single_rate_bytes as usize,
            extracted.len(),
            "rate {}",
            l.rate
        );
        let d = (salvq::Decoder::builder().accept_prefix(true))
            .build()
            .decode(&e.stream[..l.stream_end as usize])
            .unwrap();
        assert_eq!(
            decoded(d).rate,
            l.rate,
            "a prefix ending at {}",
            l.stream_end
        );
    }
    assert_eq!(info.layers[0].stream_end as usize, e.stream.len() - 12);
    // The refinements pay no octree: the voxels are the first layer's.
    assert!(info.layers[0].octree_bits == 0.0 && info.layers[2].octree_bits > 0.0);
}

#[test]
fn a_stream_shows_the_coarsest_rate_first_then_refines_it_in_place() {
    let e = encode(None);
    let whole = |rate: u8| {
        salvq::Decoder::builder()
            .limits(Limits::default())
            .rate(Some(rate))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_gaussians)
            .unwrap()
            .gaussians
    };
    let mut decoder = salvq::Decoder::builder().build().stream();
    let mut seen: Vec<u8> = Vec::new();
    for piece in e.stream.chunks(300) {
        decoder.feed(piece).unwrap();
        let tiles = decoder.new_tiles();
        if let Some(t) = tiles.last() {
            if seen.last() != Some(&t.rate) {
                seen.push(t.rate);
            }
            if t.rate != 2 {
                // A refinement hands out every tile again, at the refined rate.
                assert!(tiles.iter().all(|x| x.rate == t.rate));
                assert!(*decoder.gaussians() == whole(t.rate), "rate {}", t.rate);
            }
        }
    }
    assert_eq!(seen, [2, 1, 0], "coarse first, then each refinement");
    let tiles = decoder.tiles().len();
    let salvq::Scene::Gaussians(d) = decoder.finish().unwrap() else {
        panic!("an explicit stream");
    };
    assert!(d.gaussians == whole(0));
    assert_eq!(tiles % 3, 0, "each tile once per rate");
}
