//! Progressive against layered coding of one real scene (spec §3.8): the default targets'
//! plans coded both ways, each rate's bytes (a layered rate as its extracted single-rate
//! stream, a progressive rate as its prefix), render PSNR at the quality yardstick, bits per
//! Gaussian per group, and every rate checked to decode, extract and cut as the encoder
//! predicted. `cargo run --release -p salvq-bench --example progressive_probe -- scene.ply`
use salvq_encoder::explicit::{
    encode_prepared, rate_plans, ratios, EncodedGaussians, ExplicitOptions, PreparedGaussians,
    RateControl, DEFAULT_PSNR_TARGETS,
};
use salvq_render::compare::RingTarget;

fn main() {
    let path = std::env::args().nth(1).expect("a PLY");
    let g = salvq_render::ply::read_ply(&std::fs::read(&path).unwrap()).unwrap();
    let p = PreparedGaussians::new(&g).unwrap();
    let fit = |nested: bool| {
        let fit = ExplicitOptions {
            rates: RateControl::Psnr(DEFAULT_PSNR_TARGETS.to_vec()),
            progressive: nested,
            ..Default::default()
        };
        rate_plans(&g, &p, &fit, &|_| {}).unwrap()
    };
    let q = RingTarget::new(
        &g,
        ratios::QUALITY_VIEWS,
        ratios::QUALITY_WIDTH,
        ratios::QUALITY_HEIGHT,
    )
    .unwrap();
    let psnr =
        |x: &salvq_bitstream::explicit::Gaussians| -10.0 * q.mse(x).unwrap().max(1e-30).log10();
    let mut lines = Vec::new();
    for progressive in [false, true] {
        let (plans, klt) = fit(progressive);
        let options = ExplicitOptions {
            rates: RateControl::Plans(plans.clone()),
            klt: klt.clone(),
            progressive,
            ..Default::default()
        };
        let e = encode_prepared(&p, &plans, &options).unwrap();
        check_rates(&e);
        let mut prefix = e.shared_bytes + 8 + 12;
        for (rep, bytes, out) in &e.layers {
            prefix += bytes;
            let single = e.shared_bytes + 8 + 12 + bytes;
            lines.push((
                progressive,
                rep.rate,
                if progressive { prefix } else { single },
                psnr(out),
                rep.glay_bytes,
                rep.gatt_bytes,
                rep.apos_bytes,
            ));
        }
        println!(
            "progressive={progressive} whole file {} bytes",
            e.stream.len()
        );
        print_group_bits(&e, g.len() as f64);
    }
    lines.sort_by_key(|l| (l.1, l.0));
    for l in lines {
        println!(
            "rate {} progressive={} bytes {} psnr {:.2} hdr {} sym {} apos {}",
            l.1, l.0, l.2, l.3, l.4, l.5, l.6
        );
    }
}

/// Checks that every rate of `e` decodes as the encoder predicted, from the whole stream
/// and from its extracted single-rate stream, and prints how that stream cut short decodes.
fn check_rates(e: &EncodedGaussians) {
    for (rep, _, out) in &e.layers {
        let d = salvq::Decoder::builder()
            .limits(Default::default())
            .rate(Some(rep.rate))
            .build()
            .decode(&e.stream)
            .and_then(salvq::Scene::try_into_gaussians)
            .unwrap();
        assert!(d.gaussians == *out, "rate {} decodes differently", rep.rate);
        let x = salvq::extract_rate(&e.stream, rep.rate, &Default::default()).unwrap();
        let d2 = salvq::Decoder::builder()
            .limits(Default::default())
            .rate(None)
            .build()
            .decode(&x)
            .and_then(salvq::Scene::try_into_gaussians)
            .unwrap();
        assert!(
            d2.gaussians == *out,
            "extracted rate {} decodes differently",
            rep.rate
        );
        let opts = salvq::Decoder::builder().accept_prefix(true);
        let cut = &x[..x.len() - 12];
        let d3 = opts.build().decode(cut);
        println!(
            "rate {} ok; extracted {} bytes; cut decodes: {:?}",
            rep.rate,
            x.len(),
            d3.as_ref()
                .map(|d| match d {
                    salvq::Scene::Gaussians(g) => (g.rate, g.truncated),
                    _ => (99, false),
                })
                .map_err(|e| e.to_string())
        );
    }
}

/// Prints each rate's bits per Gaussian (`n` of them): position (with the octree's alone)
/// and each attribute group.
fn print_group_bits(e: &EncodedGaussians, n: f64) {
    for (rep, _, _) in &e.layers {
        let gb: Vec<String> = rep
            .group_bits
            .iter()
            .map(|b| format!("{:.1}", b / n))
            .collect();
        println!(
            "  rate {} pos {:.1} (apos {:.1}) groups {}",
            rep.rate,
            (rep.apos_bytes as f64 * 8.0 + rep.refine_bits) / n,
            rep.apos_bytes as f64 * 8.0 / n,
            gb.join(" ")
        );
    }
}
