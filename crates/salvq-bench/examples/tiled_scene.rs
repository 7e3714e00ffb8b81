//! A stress scene for encode time and memory: `k` copies of a real scene side by side on a
//! square grid in the x-z plane, each shifted by the scene's extent (1st to 99th percentile
//! of the positions, so stray Gaussians do not space the copies apart) plus a tenth. For
//! scale, never for compression claims: its copies repeat one another exactly.
//! `cargo run --release -p salvq-bench --example tiled_scene -- SCENE.ply K OUT.ply`
use salvq_bitstream::explicit::Gaussians;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, input, copies, output] = &args[..] else {
        return Err("usage: tiled_scene SCENE.ply K OUT.ply".into());
    };
    let copies: usize = copies.parse()?;
    let g = salvq_render::ply::read_ply(&std::fs::read(input)?)?;
    let extent = |axis: usize| {
        let mut v: Vec<f32> = g.positions.iter().map(|p| p[axis]).collect();
        v.sort_by(f32::total_cmp);
        let k = (v.len() - 1) / 100;
        1.1 * (v[v.len() - 1 - k] - v[k])
    };
    let (dx, dz) = (extent(0), extent(2));
    let side = (copies as f64).sqrt().ceil() as usize;
    let mut out = Gaussians::zeroed(g.sh_degree, 0);
    for c in 0..copies {
        let mut copy = g.clone();
        let (ox, oz) = ((c % side) as f32 * dx, (c / side) as f32 * dz);
        for p in &mut copy.positions {
            p[0] += ox;
            p[2] += oz;
        }
        out.append(copy);
    }
    salvq_render::ply::write_ply_file(&out, std::path::Path::new(output))?;
    eprintln!(
        "wrote {output}: {} Gaussians ({copies} copies of {}, SH degree {})",
        out.len(),
        g.len(),
        g.sh_degree
    );
    Ok(())
}
