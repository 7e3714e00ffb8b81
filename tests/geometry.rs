//! Anchor geometry (spec §8): the octree codes any set of voxels losslessly, shared voxels
//! included; edge cases of depth and count; on a generated scene the adaptive contexts beat
//! the order-0 entropy of the occupancy bytes.

use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::geometry::decode;
use salvq_bitstream::model::morton3;
use salvq_encoder::encode_full;
use salvq_encoder::writers::encode_geometry as encode;
use salvq_gen::rng::Stream;
use salvq_gen::{generate, GenParams};

fn round_trip(mut voxels: Vec<[u32; 3]>, depth: u8) -> usize {
    voxels.sort_by_key(|v| morton3(*v));
    let tables = GaussianTables::standard();
    let body = encode(&voxels, depth, tables).unwrap();
    let back = decode(&body, depth, voxels.len() as u32, tables).unwrap();
    assert_eq!(back, voxels, "depth {depth}");
    body.len()
}

#[test]
fn edge_cases_round_trip() {
    round_trip(vec![[0, 0, 0]], 1);
    round_trip(vec![[1, 1, 1]], 1);
    // Every voxel of a 2³ and a 4³ cube.
    let full = |side: u32| -> Vec<[u32; 3]> {
        (0..side * side * side)
            .map(|i| [i % side, i / side % side, i / side / side])
            .collect()
    };
    round_trip(full(2), 1);
    round_trip(full(4), 2);
    // The corners of the largest cube (depth 21), and one anchor there.
    let m = (1 << 21) - 1;
    round_trip(vec![[0, 0, 0], [m, 0, 0], [0, m, m], [m, m, m]], 21);
    round_trip(vec![[m, m, m]], 21);
}

#[test]
fn random_sets_with_shared_voxels_round_trip() {
    let mut s = Stream::new(3, 99, 0);
    for trial in 0..30 {
        let depth = 1 + s.below(12) as u8;
        let side = 1u64 << depth;
        let n = 1 + s.below(400) as usize;
        let mut voxels = Vec::with_capacity(n);
        while voxels.len() < n {
            let v = [s.below(side), s.below(side), s.below(side)].map(|c| c as u32);
            // Up to 5 anchors in one voxel.
            for _ in 0..1 + s.below(5) {
                voxels.push(v);
            }
        }
        voxels.truncate(n);
        round_trip(voxels, depth);
        let _ = trial;
    }
}

#[test]
fn models_with_shared_voxels_decode_exactly() {
    let mut m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(300, 4)
    });
    // Put anchors 10..20 into anchor 10's voxel, and 50, 51 into anchor 49's.
    for i in 11..20 {
        m.anchors.voxel[i] = m.anchors.voxel[10];
    }
    m.anchors.voxel[50] = m.anchors.voxel[49];
    m.anchors.voxel[51] = m.anchors.voxel[49];
    let e = encode_full(&m, &Default::default()).unwrap();
    let d = salvq::decode(&e.stream)
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    assert_eq!(&d, e.expected());
    assert_eq!(d.anchors.voxel, m.to_canonical_order().anchors.voxel);
}

#[test]
fn contexts_beat_order_zero_on_a_generated_scene() {
    let m = generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(20_000, 2)
    });
    let depth = m.coord_bits();
    let bytes = round_trip(m.anchors.voxel.clone(), depth);
    let coded = bytes as f64 * 8.0;
    let order0 = salvq_encoder::writers::geometry::order0_occupancy_bits(&m.anchors.voxel, depth);
    assert!(
        coded < 0.95 * order0,
        "coded {:.2} vs order-0 {:.2} bits/anchor",
        coded / 2e4,
        order0 / 2e4
    );
}
