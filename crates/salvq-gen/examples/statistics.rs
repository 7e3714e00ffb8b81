//! Prints the realism statistics of Annex B Table B-3 and the generation time, for
//! `GenParams::new(N, seed)` at N = 100,000 and 1,000,000 (the statistics at 100,000 only):
//!
//! `cargo run --release -p salvq-gen --example statistics`
//!
//! `SALVQ_GEN_N` and `SALVQ_GEN_SEED` choose the scene; `SALVQ_GEN_DUMP=path` writes the
//! voxels (u32 LE).

use salvq_gen::context::Layout;
use salvq_gen::stats::{context_outputs, mask_fractions, nn_distances, pca_share, quantile};
use salvq_gen::{generate, GenParams};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

fn main() {
    let seed = env("SALVQ_GEN_SEED").unwrap_or(1);
    for n in env::<u32>("SALVQ_GEN_N").map_or(vec![100_000, 1_000_000], |n| vec![n]) {
        let t = std::time::Instant::now();
        let m = generate(&GenParams::new(n, seed));
        let dt = t.elapsed();
        println!(
            "N = {n}, seed {seed}: {dt:.2?}; voxel {} coord_bits {}",
            m.voxel_size,
            m.coord_bits()
        );
        if let Some(path) = env::<String>("SALVQ_GEN_DUMP") {
            let bytes: Vec<u8> = m
                .anchors
                .voxel
                .iter()
                .flat_map(|v| v.iter().flat_map(|c| c.to_le_bytes()))
                .collect();
            std::fs::write(path, bytes).unwrap();
        }
        if n > 200_000 {
            continue;
        }
        let nn = nn_distances(&m.anchors.voxel);
        let frac = |lo: f64, hi: f64| {
            nn.iter().filter(|&&d| d > lo && d <= hi).count() as f64 / nn.len() as f64
        };
        println!(
            "  NN voxels p10/median/p90 {:.3} {:.3} {:.3}; =1 {:.3} sqrt2 {:.3} sqrt3 {:.3} 2 {:.3} 2-4 {:.3} >4 {:.3}",
            quantile(nn.clone(), 0.1), quantile(nn.clone(), 0.5), quantile(nn.clone(), 0.9),
            frac(0.5, 1.2), frac(1.2, 1.6), frac(1.6, 1.9), frac(1.9, 2.1), frac(2.1, 4.0), frac(4.0, f64::INFINITY)
        );
        let (active, dead) = mask_fractions(&m);
        let k = usize::from(m.dims.offsets);
        let full = m
            .anchors
            .mask
            .chunks(k)
            .filter(|c| c.iter().all(|&b| b == 1))
            .count() as f64
            / m.n() as f64;
        println!("  masks: active offsets {active:.3}, all-zero anchors {dead:.4}, all-one anchors {full:.3}");
        let v = f64::from(m.voxel_size);
        let ls: Vec<f64> = m
            .anchors
            .scaling
            .iter()
            .map(|&s| (f64::from(s) / v).ln())
            .collect();
        println!(
            "  ln(scaling/voxel) p10/median/p90 {:.3} {:.3} {:.3}",
            quantile(ls.clone(), 0.1),
            quantile(ls.clone(), 0.5),
            quantile(ls, 0.9)
        );
        let act: Vec<f64> = m
            .anchors
            .offsets
            .iter()
            .enumerate()
            .filter(|(i, _)| m.anchors.mask[i / 3] == 1)
            .map(|(_, &o)| f64::from(o))
            .collect();
        let sd = (act.iter().map(|o| o * o).sum::<f64>() / act.len() as f64).sqrt();
        let inside = act.iter().filter(|o| o.abs() <= 3.0).count() as f64 / act.len() as f64;
        println!("  offsets (active): rms {sd:.3}, within +-3 {inside:.4}");
        let out = context_outputs(&m);
        let lay = Layout::new(&m.dims);
        let f = lay.f;
        let sig: Vec<f64> = out
            .iter()
            .flat_map(|o| o[lay.scale_feat()..lay.scale_feat() + f].to_vec())
            .collect();
        let bits = sig
            .iter()
            .map(|s| {
                (s * (2.0 * std::f64::consts::PI * std::f64::consts::E).sqrt())
                    .log2()
                    .max(0.0)
            })
            .sum::<f64>()
            / sig.len() as f64;
        let fsd = (0..f)
            .map(|d| {
                let col: Vec<f64> = m.anchors.feat.chunks(f).map(|r| f64::from(r[d])).collect();
                let mu = col.iter().sum::<f64>() / col.len() as f64;
                (col.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / col.len() as f64).sqrt()
            })
            .sum::<f64>()
            / f as f64;
        println!(
            "  features: mean std per dim {fsd:.3}; predicted sigma p10/median/p90 {:.3} {:.3} {:.3}; ~{bits:.2} bits/dim at step 1; PCA top-5 share {:.3}",
            quantile(sig.clone(), 0.1), quantile(sig.clone(), 0.5), quantile(sig, 0.9), pca_share(&m, 5)
        );
    }
}
