//! The hyperprior's integer grid interpolation (spec §5.2) against the encoder's binary64
//! reference (Annex B.4.2) on a generated scene.

use salvq_bitstream::hyperprior::grid::GridLayout;
use salvq_encoder::float_grid::Interp;
use salvq_gen::{generate, GenParams};

#[test]
fn integer_features_match_float_interpolation() {
    let m = generate(&GenParams::new(200, 2));
    let layout = GridLayout::new(&m.dims, m.coord_bits());
    let interp = Interp::new(&m.dims, m.coord_bits());
    let mut int = vec![0i16; layout.features()];
    let mut flt = vec![0f64; layout.features()];
    let mut worst = 0f64;
    for &v in &m.anchors.voxel {
        layout.interpolate(&m.grid, v, &mut int);
        interp.features(&m.grid, v, &mut flt);
        for (a, b) in int.iter().zip(&flt) {
            worst = worst.max((f64::from(*a) / 256.0 - b).abs());
        }
    }
    // 10-bit weights and 8-bit output: within a few units of 2^-8.
    assert!(worst < 4.0 / 256.0, "worst {worst}");
}
