//! Renderable output (spec Annex C): Scaffold-GS neural Gaussians, the preview
//! renderer, its metrics, and the `render` / `export-ply` commands.

#[path = "../../../tests/common/mod.rs"]
mod common;
use common::shared_data;

use std::path::PathBuf;

use salvq_gen::{generate, GenParams};
use salvq_render::camera::{Axis, Bounds, Ring};
use salvq_render::ply::read_ply;
use salvq_render::{metrics, neural, raster, sh, Gaussians, Image};

fn one_gaussian(at: [f32; 3], rgb: [f32; 3]) -> Gaussians {
    Gaussians {
        positions: vec![at],
        sh_degree: 0,
        f_dc: vec![sh::rgb_to_dc(rgb)],
        f_rest: Vec::new(),
        opacity_logit: vec![12.0],
        log_scales: vec![[0.3f32.ln(); 3]],
        rotations: vec![[1.0, 0.0, 0.0, 0.0]],
    }
}

#[test]
fn a_single_gaussian_renders_its_colour_at_the_image_centre() {
    let (rgb, background) = ([0.8, 0.2, 0.4], [0.0, 0.0, 1.0]);
    let g = one_gaussian([0.5, -1.0, 2.0], rgb);
    let bounds = Bounds::of_points(&g.positions);
    for view in 0..4 {
        // Odd sides: the principal point (W − 1)/2, (H − 1)/2 is pixel (32, 24).
        let cam = Ring::default().camera(&bounds, view, 65, 49).unwrap();
        let image = raster::render(&g, &cam, background);
        let centre = image.pixel(32, 24);
        for c in 0..3 {
            // alpha = min(0.99, sigmoid(12)) = 0.99 at the mean.
            let expected = 0.99 * rgb[c] + 0.01 * background[c];
            assert!((centre[c] - expected).abs() < 1e-5, "{centre:?} vs {rgb:?}");
        }
        assert_eq!(image.pixel(0, 0), background);
        assert_eq!(image.pixel(64, 48), background);
    }
}

#[test]
fn images_are_the_same_for_any_thread_count() {
    let Some(bytes) = shared_data("fruit_drops.ply") else {
        return;
    };
    let g = read_ply(&bytes).unwrap();
    let cam = Ring::default()
        .camera(&Bounds::of_points(&g.positions), 1, 80, 60)
        .unwrap();
    let on = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| raster::render(&g, &cam, [0.0; 3]))
    };
    assert!(on(1) == on(3));
}

#[test]
fn psnr_and_ssim_of_an_image_against_itself_are_infinite_and_one() {
    let Some(bytes) = shared_data("fruit_drops.ply") else {
        return;
    };
    let g = read_ply(&bytes).unwrap();
    let cam = Ring::default()
        .camera(&Bounds::of_points(&g.positions), 0, 48, 36)
        .unwrap();
    let image = raster::render(&g, &cam, [0.0; 3]);
    assert_eq!(metrics::psnr(&image, &image).unwrap(), f64::INFINITY);
    assert_eq!(metrics::ssim(&image, &image).unwrap(), 1.0);
    let other = raster::render(&g, &cam, [1.0; 3]);
    let p = metrics::psnr(&image, &other).unwrap();
    let s = metrics::ssim(&image, &other).unwrap();
    assert!(p.is_finite() && p > 0.0 && s < 1.0, "{p} {s}");
    // MSE 0.01 everywhere: 20 dB.
    let (a, b) = (Image::filled(5, 4, [0.0; 3]), Image::filled(5, 4, [0.1; 3]));
    assert!((metrics::psnr(&a, &b).unwrap() - 20.0).abs() < 1e-5);
    assert!(metrics::psnr(&a, &Image::filled(4, 5, [0.0; 3])).is_err());
}

#[test]
fn fruit_drops_renders_a_non_trivial_image() {
    let Some(bytes) = shared_data("fruit_drops.ply") else {
        return;
    };
    let g = read_ply(&bytes).unwrap();
    let cam = Ring::default()
        .camera(&Bounds::of_points(&g.positions), 0, 64, 48)
        .unwrap();
    let background = [0.0, 1.0, 0.0];
    let image = raster::render(&g, &cam, background);
    let differing = (0..48)
        .flat_map(|y| (0..64).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = image.pixel(x, y);
            (0..3).any(|c| (p[c] - background[c]).abs() > 0.05)
        })
        .count();
    assert!(differing > 64 * 48 / 4, "{differing} pixels differ");
    let png = image.to_png().unwrap();
    assert!(png.starts_with(b"\x89PNG"));
}

fn small_model() -> salvq::SceneModel {
    generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(300, 4)
    })
}

/// Scaffold-GS's rule, computed independently: (anchor, offset) pairs with mask 1 and
/// tanh(MLP_opacity) > 0.
fn kept_offsets(m: &salvq::SceneModel, camera: [f32; 3]) -> Vec<(usize, usize)> {
    let (f, k, hs) = (
        m.dims.feat_dim as usize,
        m.dims.offsets as usize,
        m.dims.scaffold_hidden as usize,
    );
    let mut kept = Vec::new();
    for (i, v) in m.anchors.voxel.iter().enumerate() {
        let pos: Vec<f64> = (0..3)
            .map(|a| f64::from(m.origin[a] + m.voxel_size * v[a] as f32))
            .collect();
        let d: Vec<f64> = (0..3).map(|a| pos[a] - f64::from(camera[a])).collect();
        let dist = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        let mut x: Vec<f64> = m.anchors.feat[i * f..(i + 1) * f]
            .iter()
            .map(|&v| f64::from(v))
            .collect();
        x.extend(d.iter().map(|v| v / dist));
        let inp = x.len();
        let o = &m.mlp_opacity;
        let hidden: Vec<f64> = (0..hs)
            .map(|j| {
                let s: f64 = (0..inp).map(|c| f64::from(o.w0[j * inp + c]) * x[c]).sum();
                (s + f64::from(o.b0[j])).max(0.0)
            })
            .collect();
        for off in 0..k {
            let s: f64 = (0..hs)
                .map(|j| f64::from(o.w1[off * hs + j]) * hidden[j])
                .sum();
            let opacity = (s + f64::from(o.b1[off])).tanh();
            if m.anchors.mask[i * k + off] == 1 && opacity > 0.0 {
                kept.push((i, off));
            }
        }
    }
    kept
}

#[test]
fn neural_gaussians_follow_scaffold_gs() {
    let m = small_model();
    let camera = [3.0, -2.0, 5.0];
    let g = neural::neural_gaussians(&m, camera).unwrap();
    let kept = kept_offsets(&m, camera);
    let unmasked = m.anchors.mask.iter().filter(|&&b| b == 1).count();
    assert!(
        !kept.is_empty() && kept.len() < unmasked,
        "{} of {unmasked}",
        kept.len()
    );
    assert_eq!(g.len(), kept.len());
    let k = m.dims.offsets as usize;
    for (j, &(i, off)) in kept.iter().enumerate().step_by(7) {
        let anchor = neural::anchor_positions(&m)[i];
        let l = &m.anchors.scaling[i * 6..i * 6 + 6];
        for a in 0..3 {
            let expected = anchor[a] + m.anchors.offsets[(i * k + off) * 3 + a] * l[a];
            assert_eq!(g.positions[j][a], expected);
            // Gaussian scale = l[3..6] · sigmoid(·) ≤ l[3..6].
            assert!(g.log_scales[j][a] <= l[3 + a].ln() + 1e-6);
        }
        let q = g.rotations[j];
        assert!((q.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-5);
        let colour = g.f_dc[j].map(|d| d * sh::C0 + 0.5);
        assert!(colour.iter().all(|c| (0.0..=1.0).contains(c)), "{colour:?}");
        assert!(g.opacity_logit[j].is_finite());
    }
    // S ≠ 6 has no Scaffold-GS reading.
    let mut bad = m.clone();
    bad.dims.scaling_dim = 5;
    assert!(matches!(
        neural::neural_gaussians(&bad, camera),
        Err(neural::NeuralError::Unsupported { value: 5, .. })
    ));
    let mut short = m.clone();
    short.mlp_cov.b1.pop();
    assert!(matches!(
        neural::neural_gaussians(&short, camera),
        Err(neural::NeuralError::Shape(salvq::Error::TensorShape { .. }))
    ));
}

#[test]
fn ring_settings_are_checked() {
    let b = Bounds::of_points(&[[0.0; 3], [1.0; 3]]);
    let ring = Ring::default();
    assert!(ring.camera(&b, 7, 10, 10).is_ok());
    for e in [
        ring.camera(&b, 8, 10, 10),
        ring.camera(&b, 0, 0, 10),
        ring.camera(&b, 0, 10, 20_000),
        Ring {
            elevation_deg: 90.0,
            ..ring
        }
        .camera(&b, 0, 10, 10),
        Ring { views: 0, ..ring }.camera(&b, 0, 10, 10),
    ] {
        assert_eq!(
            salvq_render::Error::from(e.unwrap_err()).class(),
            "RenderSettingInvalid"
        );
    }
    assert_eq!(Axis::parse("-y"), Some(ring.up));
    assert_eq!(Axis::parse("y"), Some(Axis { index: 1, sign: 1 }));
    assert_eq!(Axis::parse("w"), None);
    // The ring looks at the centre: it projects to the principal point.
    let cam = ring.camera(&b, 3, 11, 11).unwrap();
    let t = cam.to_camera([0.5; 3]);
    assert!(t[0].abs() < 1e-5 && t[1].abs() < 1e-5 && t[2] > 0.0);
}

fn salvq_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_salvq"))
}

#[test]
fn export_ply_writes_one_gaussian_per_kept_offset_and_render_writes_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let m = small_model();
    let model_path = dir.path().join("m.safetensors");
    let stream_path = dir.path().join("m.salvq");
    salvq_render::interchange::write_model(&m, &model_path).unwrap();
    std::fs::write(&stream_path, salvq_encoder::encode(&m).unwrap()).unwrap();
    let decoded = salvq::decode(&std::fs::read(&stream_path).unwrap())
        .and_then(salvq::Scene::try_into_anchors)
        .unwrap();
    for (i, (input, model)) in [(&model_path, &m), (&stream_path, &decoded)]
        .into_iter()
        .enumerate()
    {
        let ply = dir.path().join(format!("out{i}.ply"));
        let status = std::process::Command::new(salvq_bin())
            .args(["export-ply", input.to_str().unwrap(), "-o"])
            .arg(&ply)
            .args(["--view", "2"])
            .status()
            .unwrap();
        assert!(status.success());
        let g = read_ply(&std::fs::read(&ply).unwrap()).unwrap();
        let bounds = Bounds::of_points(&neural::anchor_positions(model));
        let camera = Ring::default().camera(&bounds, 2, 512, 384).unwrap();
        assert_eq!(g.len(), kept_offsets(model, camera.position).len());
        assert_eq!(g, neural::neural_gaussians(model, camera.position).unwrap());
    }
    let png = dir.path().join("view.png");
    let out = std::process::Command::new(salvq_bin())
        .args(["render", stream_path.to_str().unwrap(), "-o"])
        .arg(&png)
        .args(["--view", "1", "--width", "40", "--height", "30"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    // A bad view index is a usage of the ring the command reports, leaving no file.
    let bad = dir.path().join("bad.png");
    let out = std::process::Command::new(salvq_bin())
        .args(["render", stream_path.to_str().unwrap(), "-o"])
        .arg(&bad)
        .args(["--view", "9"])
        .output()
        .unwrap();
    assert!(!out.status.success() && !bad.exists());
    assert!(String::from_utf8_lossy(&out.stderr).contains("RenderSettingInvalid"));
}

/// A PNG file that `salvq render` wrote, as an image of values in [0, 1].
fn read_png(path: &std::path::Path) -> Image {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    Image {
        width: info.width,
        height: info.height,
        rgb: buf[..info.buffer_size()]
            .iter()
            .map(|&v| f32::from(v) / 255.0)
            .collect(),
    }
}

fn salvq_ok(args: &[&std::ffi::OsStr]) {
    let out = std::process::Command::new(salvq_bin())
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn view_0_of_a_stream_and_of_its_exported_ply_are_the_same_image() {
    // The PLY records the ring bounds of the anchors it came from (Annex C.2 step 1, C.3),
    // so both renders use the same camera. Before, the PLY's ring was placed around its
    // Gaussian means: view 0 of the two was 25 dB apart.
    let dir = tempfile::tempdir().unwrap();
    let stream = dir.path().join("m.salvq");
    std::fs::write(&stream, salvq_encoder::encode(&small_model()).unwrap()).unwrap();
    let ply = dir.path().join("m.ply");
    salvq_ok(&[
        "export-ply".as_ref(),
        stream.as_ref(),
        "-o".as_ref(),
        ply.as_ref(),
    ]);
    let render = |input: &std::path::Path, name: &str| {
        let png = dir.path().join(name);
        let size = ["--width", "96", "--height", "72"].map(std::ffi::OsStr::new);
        salvq_ok(
            &[
                &[
                    "render".as_ref(),
                    input.as_ref(),
                    "-o".as_ref(),
                    png.as_ref(),
                ],
                &size[..],
            ]
            .concat(),
        );
        read_png(&png)
    };
    let (from_stream, from_ply) = (render(&stream, "s.png"), render(&ply, "p.png"));
    let psnr = metrics::psnr(&from_stream, &from_ply).unwrap();
    assert!(
        psnr > 50.0,
        "view 0 of the stream and of its PLY: {psnr:.1} dB apart"
    );
    // Not a blank image agreeing with a blank image.
    assert!(from_stream.rgb.iter().filter(|&&v| v > 0.05).count() > 96 * 72 / 20);
}
