//! Golden digests (Annex B.10). The statistics report of Annex B Table B-3 is an example:
//! `cargo run --release -p salvq-gen --example statistics`.

use super::*;

/// SHA-256 over every tensor in spec Table 2-1 order (little-endian; floats by their bits).
fn digest(m: &SceneModel) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    let floats = |h: &mut Sha256, v: &[f32]| {
        for x in v {
            h.update(x.to_bits().to_le_bytes());
        }
    };
    floats(&mut h, &m.origin);
    floats(&mut h, &[m.voxel_size]);
    for v in &m.anchors.voxel {
        for c in v {
            h.update(c.to_le_bytes());
        }
    }
    h.update(&m.anchors.mask);
    floats(&mut h, &m.anchors.feat);
    floats(&mut h, &m.anchors.scaling);
    floats(&mut h, &m.anchors.offsets);
    for g in [
        &m.grid.grid_3d,
        &m.grid.grid_xy,
        &m.grid.grid_xz,
        &m.grid.grid_yz,
    ] {
        h.update(g.iter().map(|&v| v as u8).collect::<Vec<u8>>());
    }
    for mlp in [&m.mlp_grid, &m.mlp_opacity, &m.mlp_cov, &m.mlp_color] {
        for t in [&mlp.w0, &mlp.b0, &mlp.w1, &mlp.b1] {
            floats(&mut h, t);
        }
    }
    for q in [&m.quant_feat, &m.quant_scaling, &m.quant_offsets] {
        floats(&mut h, &[q.step]);
        floats(&mut h, &q.gains);
        if let Some(b) = &q.basis {
            for t in [&b.u, &b.s, &b.v] {
                floats(&mut h, t);
            }
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The same bytes on every machine, debug or release: a change here is a change of Annex B
/// (update the annex's digests with it).
#[test]
fn golden_digests() {
    let small = digest(&generate(&GenParams::small(500, 7)));
    let hac = digest(&generate(&GenParams::new(2000, 1)));
    println!("small(500, 7): {small}\nnew(2000, 1): {hac}");
    assert_eq!(small, GOLDEN_SMALL_500_7);
    assert_eq!(hac, GOLDEN_NEW_2000_1);
}
const GOLDEN_SMALL_500_7: &str = "3ebee4c1b84b971fe8bcb2e45f918c716800bf854658821259f62138c49c1c84";
const GOLDEN_NEW_2000_1: &str = "f023161b2ed597539fca512f23705433c5435b47fb82cee34cd84aeeb29d38d7";
