//! Render speed of the CPU preview renderer (spec Annex C.4) on the real scenes in
//! `../shared/data` and on a decoded generated scene: milliseconds per render, and per
//! megapixel per 100 k Gaussians, with 1 thread and with all of rayon's threads.
//!
//! `cargo bench --bench render_speed [-- --width W --height H --runs R --out DIR]`;
//! `--out DIR` also writes each scene's ring views 0 … 7 as PNG files (512 × 384).

use std::path::{Path, PathBuf};
use std::time::Instant;

use salvq_gen::{generate, GenParams};
use salvq_render::camera::Ring;
use salvq_render::raster;
use salvq_render::scene::Scene;

struct Options {
    width: u32,
    height: u32,
    runs: usize,
    out: Option<PathBuf>,
}

fn options() -> Options {
    let mut o = Options {
        width: 1024,
        height: 768,
        runs: 3,
        out: None,
    };
    let args: Vec<String> = std::env::args().collect();
    let mut i = 1;
    while i < args.len() {
        let next = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--width" => o.width = next.parse().expect("--width N"),
            "--height" => o.height = next.parse().expect("--height N"),
            "--runs" => o.runs = next.parse().expect("--runs N"),
            "--out" => o.out = Some(PathBuf::from(next)),
            _ => {
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    o
}

/// The median of `runs` timings of `f`, in milliseconds.
fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn scenes(data: &Path) -> Vec<(String, Scene)> {
    let mut out = Vec::new();
    for name in ["fruit_drops", "donut", "guitar", "playbot"] {
        let path = data.join(format!("{name}.ply"));
        match std::fs::read(&path) {
            Ok(bytes) => out.push((
                format!("{name}.ply"),
                Scene::from_bytes(&bytes, None).expect("a valid PLY file"),
            )),
            Err(_) => eprintln!("skipped {}: not found", path.display()),
        }
    }
    // A generated HAC-size scene, through the encoder and the decoder.
    let model = generate(&GenParams {
        feat_basis: false,
        ..GenParams::new(20_000, 1)
    });
    let stream = salvq_encoder::encode(&model).expect("the generated model encodes");
    let decoded = Scene::from_bytes(&stream, None).expect("the stream decodes");
    out.push(("generated 20k anchors (decoded)".into(), decoded));
    out
}

fn main() {
    let o = options();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let ring = Ring::default();
    let all = rayon::current_num_threads();
    println!(
        "render_speed: ring view 0 of {}, {}x{} ({:.3} MP), median of {} runs",
        ring.views,
        o.width,
        o.height,
        f64::from(o.width * o.height) / 1e6,
        o.runs
    );
    println!(
        "{:<34} {:>9} {:>9} {:>8} {:>10} {:>10} {:>14}",
        "scene", "gaussians", "drawn", "threads", "gen ms", "raster ms", "ms/MP/100k G"
    );
    for (name, scene) in scenes(&data) {
        let bounds = scene.bounds();
        let camera = ring
            .camera(&bounds, 0, o.width, o.height)
            .expect("valid ring");
        for threads in [1, all] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            pool.install(|| {
                let gen_ms = median_ms(o.runs, || {
                    std::hint::black_box(scene.gaussians(camera.position).expect("valid"));
                });
                let g = scene.gaussians(camera.position).expect("valid");
                let mut stats = Default::default();
                let raster_ms = median_ms(o.runs, || {
                    stats = raster::render_with_stats(&g, &camera, [0.0; 3]).1;
                });
                let per = raster_ms
                    / (f64::from(o.width * o.height) / 1e6)
                    / (g.len().max(1) as f64 / 1e5);
                let gen = match scene {
                    Scene::Model(_) => format!("{gen_ms:.1}"),
                    Scene::Gaussians { .. } => "-".into(),
                };
                println!(
                    "{:<34} {:>9} {:>9} {:>8} {:>10} {:>10.1} {:>14.2}",
                    name,
                    g.len(),
                    stats.splats,
                    threads,
                    gen,
                    raster_ms,
                    per
                );
            });
        }
        if let Some(dir) = &o.out {
            std::fs::create_dir_all(dir).expect("output folder");
            let stem: String = name.split(['.', ' ']).next().unwrap_or("scene").to_string();
            for view in 0..ring.views {
                let cam = ring.camera(&bounds, view, 512, 384).expect("valid ring");
                let g = scene.gaussians(cam.position).expect("valid");
                let image = raster::render(&g, &cam, [0.0; 3]);
                let path = dir.join(format!("{stem}_view{view}.png"));
                image.write_png(&path).expect("PNG written");
            }
        }
    }
}
