//! The rate control's error model against renders (Annex A.8.2): for every part and trial
//! step, the ring's rendered error of the part quantized alone and the sensitivity model's
//! `Σ uᵢ |xᵢ − Q(xᵢ)|²`, and their ratio (the part's `κ`). One line per trial.
//! `cargo run --release -p salvq-bench --example sensitivity_check -- SCENE.ply`
use salvq_encoder::explicit::{
    curves, ratios, sensitivity, PreparedGaussians, SizeClasses, TrialSteps,
};
use salvq_render::compare::RingTarget;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, input] = &args[..] else {
        return Err("usage: sensitivity_check SCENE.ply".into());
    };
    let g = salvq_render::ply::read_ply(&std::fs::read(input)?)?;
    let p = PreparedGaussians::new(&g)?;
    let target = RingTarget::new(
        &g,
        ratios::CURVE_VIEWS,
        ratios::CURVE_WIDTH,
        ratios::CURVE_HEIGHT,
    )?;
    let sens = target.sensitivities(&g);
    let classes = SizeClasses::for_variant(&p, Default::default());
    let class_of = classes.classes(&p);
    let curves = curves::measure_curves(
        &g,
        &p,
        None,
        &classes,
        Default::default(),
        curves::Effort::Best,
        &target,
        &|_, _, _| {},
    )?;
    let start = TrialSteps::default_for(&p);
    println!("part\tlog2_step\trendered\tmodel\tratio");
    for (part, curve) in &curves {
        let (base, class) = match *part {
            ratios::Part::Position(c) => (start.position, Some(c)),
            ratios::Part::Scale => (start.groups[0], None),
            ratios::Part::Group(gi, c) => (start.groups[gi], Some(c)),
        };
        let members: Vec<usize> = (0..p.len())
            .filter(|&i| class.is_none_or(|c| class_of[i] == c))
            .collect();
        let u = sensitivity::weights(&p, &sens, *part);
        for &(x, mse, _) in curve {
            let e = sensitivity::predicted_error(&p, *part, &members, &u, base * x.exp2());
            println!(
                "{}\t{x}\t{mse:.3e}\t{e:.3e}\t{:.3}",
                part.describe(&p.kinds),
                mse / e.max(1e-300)
            );
        }
    }
    Ok(())
}
