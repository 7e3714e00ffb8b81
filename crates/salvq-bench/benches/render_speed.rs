//! Render speed of the CPU preview renderer (spec Annex C.4) on the real scenes in
//! `../shared/data` and on a decoded generated scene: milliseconds per render, and per
//! megapixel per 100 k Gaussians, with 1 thread and with all of rayon's threads.
//!
//! `cargo bench --bench render_speed [-- --width W --height H --runs R --out DIR]`;
//! `--out DIR` also writes each scene's ring views 0 … 7 as PNG files (512 × 384).
//!
//! Checks what it measures (a failure panics, so the bench exits non-zero): each scene's
//! Gaussians and image are the same on 1 thread as on all of rayon's (at least 2: the
//! renderer's tiles run in parallel and the image must not depend on the thread count), and
//! every image draws splats and has pixels other than the background. Smoke mode (CI, a few
//! seconds): `cargo bench --bench render_speed -- --width 160 --height 120 --runs 1`.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use salvq_gen::{generate, GenParams};
use salvq_render::camera::Ring;
use salvq_render::raster;
use salvq_render::scene::Scene;
use salvq_render::{Gaussians, Image};

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
    // At least 2, so that the 1-thread image is compared with a parallel one.
    let all = rayon::current_num_threads().max(2);
    let mut checked = 0;
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
        let mut rendered: Vec<(usize, Image, Option<Gaussians>)> = Vec::new();
        for threads in [1, all] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let out = pool.install(|| {
                let gen_ms = median_ms(o.runs, || {
                    std::hint::black_box(scene.gaussians(camera.position).expect("valid"));
                });
                let g = scene.gaussians(camera.position).expect("valid");
                let mut stats = Default::default();
                let mut image = Image::filled(0, 0, [0.0; 3]);
                let raster_ms = median_ms(o.runs, || {
                    (image, stats) = raster::render_with_stats(&g, &camera, [0.0; 3]);
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
                // A model's Gaussians are generated per camera (on rayon's threads too); a
                // PLY's are the file's.
                let generated = match g {
                    Cow::Owned(g) => Some(g),
                    Cow::Borrowed(_) => None,
                };
                (stats.splats, image, generated)
            });
            rendered.push(out);
        }
        let [(splats, image, gaussians), (_, image_n, gaussians_n)] =
            <[_; 2]>::try_from(rendered).unwrap_or_else(|_| unreachable!("two thread counts"));
        assert!(
            gaussians == gaussians_n,
            "{name}: the Gaussians differ between 1 and {all} threads"
        );
        assert!(
            image == image_n,
            "{name}: the image differs between 1 and {all} threads"
        );
        let drawn = image.rgb.chunks_exact(3).filter(|p| p != &[0.0; 3]).count();
        assert!(
            splats > 0 && drawn > 0,
            "{name}: {splats} splats drawn, {drawn} pixels other than the background"
        );
        checked += 1;
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
    println!(
        "checked: {checked} scenes: Gaussians and images on 1 thread = on {all}; each image \
         draws splats and has pixels other than the background"
    );
}
