//! Tests of the generator: validity, determinism, and the realism statistics of Annex B Table B-2.

use std::collections::HashSet;

use super::context::Layout;
use super::stats::{context_outputs, mask_fractions, nn_distances, pca_share, quantile};
use super::*;
use salvq_bitstream::model::morton3;
use salvq_bitstream::model::validate::validate_model;

#[test]
fn small_models_validate() {
    for seed in 0..6 {
        for n in [1, 2, 5, 17, 300] {
            let m = generate(&GenParams::small(n, seed));
            validate_model(&m).unwrap_or_else(|e| panic!("seed {seed} n {n}: {e}"));
            assert!(m.is_canonical());
            assert_eq!(m.n(), n as usize);
            let distinct: HashSet<[u32; 3]> = m.anchors.voxel.iter().copied().collect();
            assert_eq!(distinct.len(), n as usize);
            for a in 0..3 {
                assert_eq!(m.anchors.voxel.iter().map(|v| v[a]).min(), Some(0));
            }
        }
    }
}

#[test]
fn edge_dimensions_validate() {
    let tiny = GenParams {
        feat_dim: 1,
        offsets: 1,
        rates: 1,
        grid_channels: 1,
        res_3d: vec![],
        res_2d: vec![1],
        log2_size_3d: 1,
        log2_size_2d: 1,
        context_hidden: 1,
        scaffold_hidden: 1,
        view_dims: 0,
        feat_basis: true,
        scaling_basis: true,
        ..GenParams::small(1, 0)
    };
    for seed in 0..8 {
        for n in [1, 2, 3, 40] {
            let m = generate(&GenParams {
                anchors: n,
                seed,
                ..tiny.clone()
            });
            validate_model(&m).unwrap_or_else(|e| panic!("seed {seed} n {n}: {e}"));
        }
    }
    let wide = GenParams {
        res_3d: vec![1, 65_535],
        res_2d: vec![],
        log2_size_3d: 3,
        view_dims: 8,
        rates: 64,
        ..GenParams::small(50, 1)
    };
    validate_model(&generate(&wide)).unwrap();
}

#[test]
fn hac_model_validates() {
    let m = generate(&GenParams::new(3000, 9));
    validate_model(&m).unwrap();
    assert!(m.is_canonical());
    let plus = m.grid.grid_3d.iter().filter(|&&v| v == 1).count() as f64;
    let balance = plus / m.grid.grid_3d.len() as f64;
    assert!((balance - 0.5).abs() < 0.01, "fraction of +1: {balance}");
    let mut q = GenParams::small(200, 3);
    q.scaling_basis = true;
    q.view_dims = 0;
    validate_model(&generate(&q)).unwrap();
}

fn run_small(p: &GenParams, threads: usize) -> SceneModel {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| generate(p))
}

#[test]
fn same_bytes_whatever_the_thread_count() {
    let p = GenParams::new(2500, 42);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| generate(&p))
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, generate(&p));
    let small = GenParams::small(2000, 42);
    assert_eq!(run_small(&small, 1), run_small(&small, 3));
    assert_ne!(generate(&small), generate(&GenParams::small(2000, 43)));
}

#[test]
fn geometry_statistics_20k() {
    let g = surfaces::generate(5, 20_000);
    assert_eq!(g.voxels.len(), 20_000);
    assert!(g.voxels.windows(2).all(|w| morton3(w[0]) < morton3(w[1])));
    let nn = nn_distances(&g.voxels);
    let med = quantile(nn.clone(), 0.5);
    assert!((1.0..=2.0).contains(&med), "NN median {med}");
    let p90 = quantile(nn, 0.9);
    assert!((1.4..=4.0).contains(&p90), "NN p90 {p90}");
}

#[test]
fn attribute_statistics() {
    let m = generate(&GenParams::new(5000, 5));
    let (active, dead) = mask_fractions(&m);
    assert!((0.5..=0.7).contains(&active), "active offsets {active}");
    assert!((0.004..=0.02).contains(&dead), "all-zero masks {dead}");
    // Scaling: ln(scaling / voxel) around N(-0.3, 1.2), as the Octree-GS anchors.
    let v = f64::from(m.voxel_size);
    let ls: Vec<f64> = m
        .anchors
        .scaling
        .iter()
        .map(|&s| (f64::from(s) / v).ln())
        .collect();
    let (p10, p50, p90) = (
        quantile(ls.clone(), 0.1),
        quantile(ls.clone(), 0.5),
        quantile(ls, 0.9),
    );
    assert!(
        (-0.8..=0.2).contains(&p50) && p10 < -1.0 && p90 > 0.8,
        "{p10} {p50} {p90}"
    );
    // Offsets mostly within +-3.
    let k = usize::from(m.dims.offsets);
    let act: Vec<f32> = m
        .anchors
        .offsets
        .iter()
        .enumerate()
        .filter(|(i, _)| m.anchors.mask[i / 3] == 1 && i / (3 * k) < m.n())
        .map(|(_, &o)| o)
        .collect();
    let inside = act.iter().filter(|o| o.abs() <= 3.0).count() as f64 / act.len() as f64;
    assert!(inside > 0.99, "offsets within 3: {inside}");
    // Correlated features: the top 5 of 50 principal components carry most of the variance.
    let share = pca_share(&m, 5);
    assert!(share > 0.5, "top-5 PCA share {share}");
}

#[test]
fn the_prior_predicts_the_data() {
    let m = generate(&GenParams::new(4000, 11));
    let out = context_outputs(&m);
    let lay = Layout::new(&m.dims);
    let f = lay.f;
    let mut corr_sum = 0.0;
    let mut z2 = 0.0;
    for d in 0..f {
        let xs: Vec<f64> = out.iter().map(|o| o[lay.mean_feat() + d]).collect();
        let ys: Vec<f64> = m.anchors.feat.chunks(f).map(|r| f64::from(r[d])).collect();
        let n = xs.len() as f64;
        let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
        let cov: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
        let vx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
        let vy: f64 = ys.iter().map(|y| (y - my) * (y - my)).sum();
        corr_sum += cov / (vx * vy).sqrt();
        // Standardised residuals (feat - mean) / scale have unit variance.
        z2 += out
            .iter()
            .zip(&ys)
            .map(|(o, y)| ((y - o[lay.mean_feat() + d]) / o[lay.scale_feat() + d]).powi(2))
            .sum::<f64>()
            / n;
    }
    let corr = corr_sum / f as f64;
    let z2 = z2 / f as f64;
    assert!(corr > 0.5, "mean correlation {corr}");
    assert!(
        (0.9..1.1).contains(&z2),
        "standardised residual variance {z2}"
    );
    // Every predicted scale is positive.
    for o in &out {
        assert!((lay.scale_feat()..lay.mean_offsets())
            .all(|i| i < lay.mean_scaling() || i >= lay.scale_scaling() || o[i] > 0.0));
        assert!((lay.scale_feat()..lay.mean_scaling()).all(|i| o[i] > 0.0));
        assert!((lay.mean_scaling()..lay.mean_offsets()).all(|i| o[i] > 0.0));
        assert!((lay.scale_offsets()..lay.q_adj()).all(|i| o[i] > 0.0));
    }
}

#[test]
fn quantizers_are_as_documented() {
    let m = generate(&GenParams::new(100, 1));
    assert_eq!(
        (
            m.quant_feat.step,
            m.quant_scaling.step,
            m.quant_offsets.step
        ),
        (1.0, (0.1 * f64::from(m.voxel_size)) as f32, 0.2)
    );
    for q in [&m.quant_feat, &m.quant_scaling, &m.quant_offsets] {
        assert_eq!(q.gains[0], 1.0);
        assert!(q
            .gains
            .windows(2)
            .all(|w| w[1] > w[0] * 1.4 && w[1] < w[0] * 1.6));
    }
    let b = m.quant_feat.basis.as_ref().unwrap();
    let cond = b.s[0] / b.s[b.s.len() - 1];
    let geo = b.s.iter().map(|&s| f64::from(s).ln()).sum::<f64>() / b.s.len() as f64;
    assert!(
        (2.0..5.0).contains(&cond) && geo.abs() < 1e-5,
        "{cond} {geo}"
    );
}
