//! The explicit-Gaussians profile (spec §3, Annex A.8): round trips of synthetic and real
//! scenes, extraction, thread independence, the encoder's input checks and rate control.

mod common;
use common::shared_data;

use salvq::DecodedGaussians;
use salvq::DecoderBuilder;
use salvq::{Error, Limits};
use salvq_conformance::explicit_vectors::encode_synthetic;
use salvq_encoder::explicit::input::{input_kind, InputKind};
use salvq_encoder::explicit::{
    encode_gaussians, encode_prepared, ExplicitOptions, PreparedGaussians, RateControl, RatePlan,
};
use salvq_gen::gaussians::{generate_gaussians, GaussianParams};
use salvq_render::compare::RingTarget;
use salvq_render::ply::{ply_bytes, read_ply};
use salvq_render::Error as R;

fn plan(voxel: f64, groups: usize) -> RatePlan {
    RatePlan {
        voxel,
        refine: [3, 2, 1, 0],
        steps: [0.1, 0.25, 0.03, 0.03, 0.04][..groups].to_vec(),
        shift: vec![[1, 0, 0, -1]; groups - 1],
    }
}

fn plans(m: usize, groups: usize) -> Vec<RatePlan> {
    (0..m)
        .map(|k| {
            let mut p = plan(0.05 * (k as f64).exp2(), groups);
            p.steps.iter_mut().for_each(|s| *s *= (k as f64).exp2());
            p
        })
        .collect()
}

/// `count` synthetic Gaussians of SH degree `sh` (seed `seed`), one rate, in tiles of at most
/// `tile` Gaussians.
fn tiled(count: usize, sh: u8, seed: u64, tile: u32) -> salvq_encoder::explicit::EncodedGaussians {
    encode_synthetic(
        &GaussianParams::new(count, sh, seed),
        plans(1, 5),
        ExplicitOptions {
            tile_gaussians: tile,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The Gaussians of a stream that must be explicit and must decode.
fn gaussians_of(stream: &[u8], o: &DecoderBuilder) -> DecodedGaussians {
    match o.build().decode(stream).unwrap() {
        salvq::Scene::Gaussians(d) => *d,
        salvq::Scene::Anchors(_) => panic!("an explicit stream"),
    }
}

fn decode(stream: &[u8], rate: u8) -> DecodedGaussians {
    salvq::Decoder::builder()
        .limits(Limits::default())
        .rate(Some(rate))
        .build()
        .decode(stream)
        .and_then(salvq::Scene::try_into_gaussians)
        .expect("the stream decodes")
}

#[test]
fn every_rate_decodes_to_the_encoders_prediction() {
    for (degree, n, tiles) in [(0u8, 300usize, 64u32), (1, 50, 16_384), (3, 200, 40)] {
        let groups = if degree == 0 { 4 } else { 5 };
        let e = encode_synthetic(
            &GaussianParams::new(n, degree, 11),
            plans(3, groups),
            ExplicitOptions {
                tile_gaussians: tiles,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(salvq_bitstream::container::is_explicit(&e.stream));
        for (report, _, expected) in &e.layers {
            let d = decode(&e.stream, report.rate);
            assert_eq!(
                &d.gaussians, expected,
                "degree {degree}, rate {}",
                report.rate
            );
            assert_eq!(d.gaussians.len(), n);
        }
    }
}

#[test]
fn coarser_rates_are_smaller_and_further_from_the_input() {
    let params = GaussianParams::new(400, 2, 4);
    let g = generate_gaussians(&params);
    let p = PreparedGaussians::new(&g).unwrap();
    let rate_plans = plans(3, 5);
    let layered = ExplicitOptions {
        progressive: false,
        ..Default::default()
    };
    let e = encode_synthetic(&params, rate_plans.clone(), layered).unwrap();
    let sizes: Vec<usize> = e.layers.iter().map(|l| l.1).collect();
    assert!(sizes[0] > sizes[1] && sizes[1] > sizes[2], "{sizes:?}");
    // Scene Gaussians are in each layer's Morton order: compare through it.
    let origin = p.min.map(|v| v as f32);
    let errors: Vec<f64> = e
        .layers
        .iter()
        .zip(&rate_plans)
        .map(|(l, plan)| {
            let order = salvq_encoder::explicit::grid::grid(&p, origin, plan.voxel).order;
            order
                .iter()
                .enumerate()
                .map(|(k, &i)| {
                    (0..3)
                        .map(|c| f64::from(l.2.f_dc[k][c] - g.f_dc[i][c]).powi(2))
                        .sum::<f64>()
                })
                .sum()
        })
        .collect();
    assert!(errors[0] < errors[1] && errors[1] < errors[2], "{errors:?}");
}

#[test]
fn positions_and_attributes_stay_within_their_steps() {
    let params = GaussianParams::new(300, 1, 8);
    let g = generate_gaussians(&params);
    let p = plans(1, 5);
    let e = encode_synthetic(&params, p.clone(), ExplicitOptions::default()).unwrap();
    let d = &e.layers[0].2;
    // Scene order is the stream's: match Gaussians by their (unique) scales' nearness.
    let voxel = p[0].voxel;
    for q in &d.positions {
        let near = g
            .positions
            .iter()
            .map(|o| {
                (0..3)
                    .map(|a| (f64::from(o[a]) - f64::from(q[a])).abs())
                    .fold(0.0, f64::max)
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            near <= voxel * 0.5 + 1e-6,
            "a position moved by {near}, voxel {voxel}"
        );
    }
}

#[test]
fn extract_equals_encoding_the_rate_alone() {
    let params = GaussianParams::new(150, 3, 21);
    let layered = ExplicitOptions {
        progressive: false,
        ..Default::default()
    };
    let all = encode_synthetic(&params, plans(3, 5), layered.clone()).unwrap();
    for r in 0..3u8 {
        let alone = encode_synthetic(
            &params,
            plans(3, 5),
            ExplicitOptions {
                coded: Some(vec![r]),
                ..layered.clone()
            },
        )
        .unwrap();
        let extracted = salvq::extract_rate(&all.stream, r, &Limits::default()).unwrap();
        assert_eq!(extracted, alone.stream, "rate {r}");
    }
}

#[test]
fn one_and_two_threads_decode_the_same() {
    let params = GaussianParams::new(600, 1, 3);
    let e = encode_synthetic(
        &params,
        plans(1, 5),
        ExplicitOptions {
            tile_gaussians: 50,
            ..Default::default()
        },
    )
    .unwrap();
    let with = |threads| {
        let o = salvq::Decoder::builder().threads(threads);
        gaussians_of(&e.stream, &o).gaussians
    };
    assert!(e.layers[0].0.tiles > 4);
    assert_eq!(with(1), with(2));
}

/// Tiles are decoded largest first, but errors are still reported by tile order (§10.3): in
/// `APOS` and in `GATT` (decoded with it), with every later tile broken too, tile 1's fault
/// is the one reported.
#[test]
fn the_lowest_tile_error_is_reported_whichever_tile_runs_first() {
    use salvq_bitstream::container::chunk::ChunkTag;
    use salvq_bitstream::error::AnsFault;
    let e = tiled(900, 1, 6, 100);
    let nt = e.layers[0].0.tiles;
    assert!(nt > 4, "{nt} tiles");
    for tag in [ChunkTag::APOS, ChunkTag::GATT] {
        // Tiles 2.. get a state the encoder never ends on; tile 1 gets a zero top word.
        let later = common::edit_payload(&e.stream, tag, |p| {
            for &at in &common::tile_body_starts(p, nt)[2..] {
                p[at..at + 8].copy_from_slice(&[0xA5; 8]);
            }
        });
        let both = common::edit_payload(&later, tag, |p| {
            let at = common::tile_body_starts(p, nt)[1];
            p[at..at + 4].copy_from_slice(&[0; 4]);
        });
        let zero_top = Error::AnsStreamInvalid {
            tag,
            fault: AnsFault::ZeroTopWord,
        };
        for threads in [1, 2, 4] {
            let o = salvq::Decoder::builder().threads(threads);
            let other = o.build().decode(&later).map(|_| ()).unwrap_err();
            assert_ne!(
                other, zero_top,
                "{tag}: tiles 2.. alone must fail otherwise"
            );
            let first = o.build().decode(&both).map(|_| ()).unwrap_err();
            assert_eq!(first, zero_top, "{tag}, {threads} threads");
        }
    }
}

#[test]
fn gaussians_only_decodes_the_same_gaussians_without_the_symbols() {
    let e = tiled(700, 1, 4, 64);
    assert!(e.layers[0].0.tiles > 4);
    let region = salvq::RegionBox::from_array([-3.0, -3.0, -3.0, 0.0, 0.0, 3.0]).unwrap();
    for threads in [1, 2] {
        for region in [None, Some(region)] {
            let o = salvq::Decoder::builder().threads(threads).region(region);
            let decode = |o: &DecoderBuilder| gaussians_of(&e.stream, o);
            let (full, only) = (decode(&o), decode(&o.clone().gaussians_only(true)));
            let what = format!("{threads} threads, region {region:?}");
            assert!(!full.gaussians.is_empty(), "{what}");
            assert_eq!(only.gaussians, full.gaussians, "{what}");
            assert_eq!(only.voxels, full.voxels, "{what}");
            assert_eq!(
                full.symbols.size_class.len(),
                full.gaussians.len(),
                "{what}"
            );
            assert_eq!(only.symbols, Default::default(), "{what}");
        }
    }
}

#[test]
fn a_region_decodes_only_the_tiles_it_meets() {
    let params = GaussianParams::new(800, 0, 5);
    let e = encode_synthetic(
        &params,
        plans(1, 4),
        ExplicitOptions {
            tile_gaussians: 64,
            ..Default::default()
        },
    )
    .unwrap();
    let all = decode(&e.stream, 0).gaussians;
    let o = salvq::Decoder::builder().region(Some(
        salvq::RegionBox::from_array([-3.0, -3.0, -3.0, 0.0, 0.0, 3.0]).unwrap(),
    ));
    let salvq::Scene::Gaussians(part) = o.build().decode(&e.stream).unwrap() else {
        panic!("an explicit stream")
    };
    let part = part.gaussians;
    assert!(
        !part.is_empty() && part.len() < all.len(),
        "{} of {}",
        part.len(),
        all.len()
    );
    // Every Gaussian in the box is kept (tiles are a superset of the box).
    let inside = |p: &[f32; 3]| p[0] <= 0.0 && p[1] <= 0.0;
    let want = all.positions.iter().filter(|p| inside(p)).count();
    let got = part.positions.iter().filter(|p| inside(p)).count();
    assert_eq!(got, want);
}

#[test]
fn the_parts_of_a_stream_are_its_tiles_once_each() {
    // §10.3.2, with and without a region: every kept tile in exactly one part, each part's
    // Gaussians those of its tiles in the full decode, the same whole or as bytes arrive.
    let e = tiled(900, 1, 7, 60);
    let full = gaussians_of(&e.stream, &salvq::Decoder::builder());
    let nt = full.tiles.len();
    assert!(nt > 6, "{nt} tiles");
    let region = salvq::RegionBox::from_array([-3.0, -3.0, -3.0, 0.0, 0.0, 3.0]).unwrap();
    for region in [None, Some(region)] {
        let kept = full
            .tiles
            .select(full.header.origin, full.layer.voxel_size, region, None);
        assert!(kept.iter().filter(|&&k| k).count() > 3, "{region:?}");
        for count in [2, 3] {
            let mut owner = vec![None; nt];
            for index in 0..count {
                let part = salvq::TilePart::new(index, count);
                let o = salvq::Decoder::builder()
                    .threads(2)
                    .region(region)
                    .part(part)
                    .gaussians_only(true);
                let d = gaussians_of(&e.stream, &o);
                let mine =
                    full.tiles
                        .select(full.header.origin, full.layer.voxel_size, region, part);
                let rows: Vec<usize> = (0..nt)
                    .filter(|&t| mine[t])
                    .inspect(|&t| {
                        assert!(kept[t] && owner[t].is_none(), "tile {t}");
                        owner[t] = Some(index);
                    })
                    .flat_map(|t| full.tiles.range(t))
                    .collect();
                let what = format!("part {index} of {count}, region {region:?}");
                assert_eq!(d.gaussians.len(), rows.len(), "{what}");
                for (j, &i) in rows.iter().enumerate() {
                    assert_eq!(d.gaussians.positions[j], full.gaussians.positions[i]);
                    assert_eq!(d.gaussians.f_dc[j], full.gaussians.f_dc[i]);
                    assert_eq!(d.gaussians.rotations[j], full.gaussians.rotations[i]);
                }
                // The streaming decoder keeps the same tiles.
                let mut stream = (o.clone()).build().stream();
                for piece in e.stream.chunks(999) {
                    stream.feed(piece).unwrap();
                }
                let salvq::Scene::Gaussians(streamed) = stream.finish().unwrap() else {
                    panic!("an explicit stream")
                };
                assert_eq!(streamed.gaussians, d.gaussians, "{what}, streamed");
            }
            for t in 0..nt {
                assert_eq!(owner[t].is_some(), kept[t], "tile {t}, {count} parts");
            }
        }
    }
}

/// §10.3.2: an explicit-profile part decodes its own tiles' geometry only, so a broken
/// `APOS` body of another part's tile is not its error (a full decode reports it).
#[test]
fn a_part_reads_only_its_own_tiles_geometry() {
    use salvq_bitstream::container::chunk::ChunkTag;
    let e = tiled(900, 1, 6, 100);
    let full = gaussians_of(&e.stream, &salvq::Decoder::builder());
    let nt = full.tiles.len();
    let parts = [0, 1].map(|k| salvq::TilePart::new(k, 2));
    let owned_by = |part| {
        full.tiles
            .select(full.header.origin, full.layer.voxel_size, None, part)
    };
    // A tile of part 1, its body's first words overwritten (a state the encoder never ends on).
    let broken_tile = (0..nt).find(|&t| owned_by(parts[1])[t]).unwrap();
    let broken = common::edit_payload(&e.stream, ChunkTag::APOS, |p| {
        let at = common::tile_body_starts(p, nt)[broken_tile];
        p[at..at + 8].copy_from_slice(&[0xA5; 8]);
    });
    for threads in [1, 2] {
        let o = salvq::Decoder::builder().threads(threads);
        let whole = o.build().decode(&broken).map(|_| ()).unwrap_err();
        assert!(whole.to_string().starts_with("APOS"), "{whole}");
        // Part 0 decodes: the broken tile is part 1's.
        let mine = gaussians_of(&broken, &o.clone().part(parts[0]));
        let rows = (0..nt).filter(|&t| owned_by(parts[0])[t]);
        assert_eq!(
            mine.gaussians.len(),
            rows.map(|t| full.tiles.range(t).len()).sum::<usize>()
        );
        let theirs = (o.part(parts[1]))
            .build()
            .decode(&broken)
            .map(|_| ())
            .unwrap_err();
        assert_eq!(theirs, whole, "{threads} threads");
    }
}

#[test]
fn the_anchors_decoder_names_the_other_profile() {
    let e = encode_synthetic(
        &GaussianParams::new(10, 0, 1),
        plans(1, 4),
        ExplicitOptions::default(),
    )
    .unwrap();
    let err = salvq::decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap_err();
    assert!(
        matches!(err, Error::ChunkOrder { found, .. } if found.as_str() == "GHED"),
        "{err}"
    );
}

#[test]
fn the_encoder_names_inputs_it_does_not_read() {
    let cases: [(&[u8], &str); 5] = [
        (&[0x1f, 0x8b, 8, 0], "gzip"),
        (b"NGSP\x02\0\0\0", "SPZ"),
        (b"PK\x03\x04....", "zip"),
        (b"{\"means\": {}}", "JSON"),
        (
            b"ply\nformat binary_little_endian 1.0\nelement chunk 10\n",
            "compressed PLY",
        ),
    ];
    for (bytes, what) in cases {
        let err = input_kind(bytes).unwrap_err();
        let text = err.to_string();
        assert!(
            matches!(err, salvq_encoder::Error::UnsupportedInput { .. }),
            "{what}: {err}"
        );
        assert!(
            text.contains(what) && text.contains("splat-transform"),
            "{text}"
        );
    }
    assert_eq!(
        input_kind(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n").unwrap(),
        InputKind::Ply
    );
    assert_eq!(
        input_kind(b"\x02\0\0\0\0\0\0\0{}").unwrap(),
        InputKind::Model
    );
}

#[test]
fn a_nan_is_named_by_property_and_gaussian() {
    let mut g = generate_gaussians(&GaussianParams::new(20, 1, 2));
    g.f_rest[7 * 9 + 4] = f32::NAN;
    let err = PreparedGaussians::new(&g).unwrap_err();
    assert!(
        matches!(&err, salvq_encoder::Error::Files(R::PlyValueNotFinite { vertex: 7, property }) if property == "f_rest_4"),
        "{err}"
    );
    // Through the PLY reader as well, with the vertex's index.
    let mut g = generate_gaussians(&GaussianParams::new(20, 0, 2));
    g.log_scales[13][2] = f32::INFINITY;
    let err = read_ply(&ply_bytes(&g).unwrap()).unwrap_err();
    assert!(
        matches!(&err, R::PlyValueNotFinite { vertex: 13, property } if property == "scale_2"),
        "{err}"
    );
}

#[test]
fn degenerate_scenes_encode_or_fail_with_a_typed_error() {
    // No Gaussians at all.
    let empty = salvq_render::Gaussians::default();
    assert!(matches!(
        PreparedGaussians::new(&empty),
        Err(salvq_encoder::Error::UnsupportedInput { .. })
    ));
    // One Gaussian; every Gaussian at one point (zero-size box).
    for params in [
        GaussianParams::new(1, 3, 1),
        GaussianParams {
            one_point: true,
            ..GaussianParams::new(64, 0, 1)
        },
    ] {
        let groups = if params.sh_degree == 0 { 4 } else { 5 };
        let e = encode_synthetic(&params, plans(2, groups), ExplicitOptions::default()).unwrap();
        for (r, _, expected) in &e.layers {
            assert_eq!(&decode(&e.stream, r.rate).gaussians, expected);
        }
    }
}

#[test]
fn truncated_and_malformed_ply_files_are_typed_errors() {
    let g = generate_gaussians(&GaussianParams::new(10, 1, 4));
    let bytes = ply_bytes(&g).unwrap();
    for cut in [3usize, 20, 200, bytes.len() - 1] {
        let err = read_ply(&bytes[..cut]).unwrap_err();
        assert!(
            matches!(err, R::PlyHeaderInvalid { .. } | R::PlyTruncated { .. }),
            "cut at {cut}: {err}"
        );
    }
}

/// The rate control on a real scene (fruit_drops, as trained): every rate lands within
/// 0.5 dB of its render-PSNR target at the yardstick (8 ring views at 512 × 384, Annex
/// A.8.2), and finer rates cost more. It renders a few hundred
/// images: CI runs it in release (`cargo test --release --test explicit`).
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "renders hundreds of images; run with --release"
)]
fn rates_meet_their_psnr_targets_on_a_real_scene() {
    let Some(bytes) = shared_data("fruit_drops.ply") else {
        return;
    };
    let g = read_ply(&bytes).unwrap();
    let targets = vec![50.0, 40.0];
    let e = encode_gaussians(
        &g,
        &ExplicitOptions {
            rates: RateControl::Psnr(targets.clone()),
            ..Default::default()
        },
        &|_| {},
    )
    .unwrap();
    use salvq_encoder::explicit::ratios::{QUALITY_HEIGHT, QUALITY_VIEWS, QUALITY_WIDTH};
    let target = RingTarget::new(&g, QUALITY_VIEWS, QUALITY_WIDTH, QUALITY_HEIGHT).unwrap();
    // Layers come in stream order (a progressive stream's coarsest first): by their rate.
    let mut bytes = [0usize; 2];
    for ((report, _, expected), read) in e.layers.iter().zip(e.rate_stream_bytes()) {
        let want = targets[usize::from(report.rate)];
        let got = target.psnr(expected).unwrap();
        assert!(
            (got - want).abs() < 0.5,
            "rate {}: {got:.2} dB for {want} dB",
            report.rate
        );
        bytes[usize::from(report.rate)] = read;
    }
    assert!(bytes[0] > bytes[1], "{bytes:?}");
    // And the stream decodes to what the encoder predicted.
    for (report, _, expected) in &e.layers {
        assert_eq!(&decode(&e.stream, report.rate).gaussians, expected);
    }
}

#[test]
fn three_points_round_trip_through_the_plans() {
    let Some(bytes) = shared_data("three_points.ply") else {
        return;
    };
    let g = read_ply(&bytes).unwrap();
    let p = PreparedGaussians::new(&g).unwrap();
    let e = encode_prepared(&p, &plans(2, 5), &ExplicitOptions::default()).unwrap();
    for (report, _, expected) in &e.layers {
        assert_eq!(&decode(&e.stream, report.rate).gaussians, expected);
    }
}

/// `salvq info` counts, per group, the values coded at a wide scale, at the widest, and those
/// sent with an escape (§6.3.6, §6.4): a group quantized far finer than the widest table's σ
/// is coded at wide scales and no longer escapes; a group quantized coarser than its spread
/// needs none.
#[test]
fn info_names_the_groups_that_need_wide_scales() {
    use salvq_encoder::info::explicit::inspect_explicit;
    let mut plan = plan(0.05, 5);
    // Scales at a step of 0.005 in log units: a spread of some hundred steps, past the
    // widest table's σ (29.3 steps), where 0.13 escaped a value in ten or more.
    plan.steps = vec![0.005, 100.0, 0.03, 0.03, 0.04];
    let e = encode_synthetic(
        &GaussianParams::new(200, 1, 5),
        vec![plan],
        ExplicitOptions::default(),
    )
    .unwrap();
    let info = inspect_explicit(&e.stream, &Limits::default()).unwrap();
    let saturation = &info.layers[0].saturation;
    let group = |name: &str| {
        saturation
            .iter()
            .find(|g| g.group == name)
            .unwrap_or_else(|| panic!("{name} in {saturation:?}"))
    };
    let (scale, opacity) = (group("scale"), group("opacity"));
    assert!(scale.wide_scale > 0.9, "{scale:?}");
    assert!(scale.escaped < 0.02, "{scale:?}");
    assert_eq!(scale.widest_scale, 0.0, "{scale:?}");
    assert_eq!(
        (opacity.wide_scale, opacity.widest_scale, opacity.escaped),
        (0.0, 0.0, 0.0)
    );
    let line = format!(
        "scale {:.1} % / {:.1} % / {:.1} %",
        100.0 * scale.wide_scale,
        100.0 * scale.widest_scale,
        100.0 * scale.escaped
    );
    assert!(info.to_text().contains(&line), "{}", info.to_text());
}
