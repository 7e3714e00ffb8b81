//! Renderable output (spec Annex C): PLY I/O, Scaffold-GS neural Gaussians, the preview
//! renderer, its metrics, and the `render` / `export-ply` commands.

#[path = "../../../tests/common/mod.rs"]
mod common;
use common::shared_data;

use std::path::PathBuf;

use salvq_gen::{generate, GenParams};
use salvq_render::camera::{Axis, Bounds, Ring};
use salvq_render::ply::{ply_bytes, read_ply, recorded_ring_bounds};
use salvq_render::Error;
use salvq_render::{metrics, neural, raster, sh, Gaussians, Image};

/// `n` Gaussians of SH degree `degree` with awkward binary32 values (negative zero,
/// subnormals, large exponents) so that a round trip has something to lose.
fn awkward_gaussians(n: usize, degree: u8) -> Gaussians {
    let b = salvq::explicit::rest_per_channel(degree);
    let v = |i: usize, j: usize| -> f32 {
        match (i * 31 + j * 7) % 6 {
            0 => -0.0,
            1 => f32::from_bits(1 + (i * 13 + j) as u32), // subnormal
            2 => 1.0e30 * (i as f32 + 1.0),
            _ => (i as f32 * 0.37 - j as f32 * 1.3).sin(),
        }
    };
    Gaussians {
        positions: (0..n).map(|i| [v(i, 0), v(i, 1), v(i, 2)]).collect(),
        sh_degree: degree,
        f_dc: (0..n).map(|i| [v(i, 3), v(i, 4), v(i, 5)]).collect(),
        f_rest: (0..n * 3 * b).map(|i| v(i / 7, i % 7 + 20)).collect(),
        opacity_logit: (0..n).map(|i| v(i, 6)).collect(),
        log_scales: (0..n).map(|i| [v(i, 7), v(i, 8), v(i, 9)]).collect(),
        rotations: (0..n)
            .map(|i| [v(i, 10), v(i, 11), v(i, 12), v(i, 13)])
            .collect(),
    }
}

fn bits(g: &Gaussians) -> Vec<u32> {
    let flat = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut out = flat(&g.positions);
    out.extend(flat(&g.f_dc));
    out.extend(g.f_rest.iter().map(|x| x.to_bits()));
    out.extend(g.opacity_logit.iter().map(|x| x.to_bits()));
    out.extend(flat(&g.log_scales));
    out.extend(g.rotations.iter().flatten().map(|x| x.to_bits()));
    out
}

#[test]
fn ply_write_read_round_trip_is_bit_exact() {
    for degree in 0..=3 {
        let g = awkward_gaussians(37, degree);
        let bytes = ply_bytes(&g).unwrap();
        let back = read_ply(&bytes).unwrap();
        assert_eq!(back.sh_degree, degree);
        assert_eq!(bits(&back), bits(&g), "degree {degree}");
        assert_eq!(ply_bytes(&back).unwrap(), bytes);
    }
    let empty = read_ply(&ply_bytes(&Gaussians::default()).unwrap()).unwrap();
    assert!(empty.is_empty());
}

#[test]
fn ring_bounds_recorded_in_a_ply_header_read_back_exactly() {
    let g = awkward_gaussians(5, 1);
    let b = Bounds {
        min: [-0.0, 1e-30, -3.25],
        max: [0.1, 7.0e20, f32::from_bits(0x3eaa_aaab)],
    };
    let mut bytes = Vec::new();
    salvq_render::ply::write_ply_with(&g, Some(&b), &mut bytes).unwrap();
    assert_eq!(recorded_ring_bounds(&bytes).unwrap(), Some(b));
    assert_eq!(bits(&read_ply(&bytes).unwrap()), bits(&g));
    assert_eq!(recorded_ring_bounds(&ply_bytes(&g).unwrap()).unwrap(), None);
    // min > max on x, a number missing, one not finite: header line 3 is named.
    let text = String::from_utf8_lossy(&ply_bytes(&g).unwrap()).into_owned();
    for bad in ["5 0 0 1 1 1", "0 0 0 1 1", "0 0 0 1 1 inf"] {
        let line = format!("format binary_little_endian 1.0\ncomment salvq ring_bounds {bad}");
        let broken = text.replacen("format binary_little_endian 1.0", &line, 1);
        let e = recorded_ring_bounds(broken.as_bytes()).unwrap_err();
        assert!(matches!(e, Error::PlyHeaderInvalid { line: 3, .. }), "{e}");
    }
}

#[test]
fn a_real_inria_ply_is_written_back_byte_for_byte() {
    // fruit_drops.ply is in the Inria layout with zero normals, exactly what write_ply writes.
    let Some(original) = shared_data("fruit_drops.ply") else {
        return;
    };
    let g = read_ply(&original).unwrap();
    assert_eq!((g.len(), g.sh_degree), (4721, 3));
    assert!(ply_bytes(&g).unwrap() == original);
}

/// A PLY file whose header is `header` (lines) followed by `body`.
fn ply_file(header: &[&str], body: &[u8]) -> Vec<u8> {
    let mut b = header.join("\n").into_bytes();
    b.push(b'\n');
    b.extend_from_slice(body);
    b
}

#[test]
fn properties_are_found_by_name_in_any_order_and_type() {
    // A skipped element first; the vertex element in shuffled order with double, uchar and
    // extra properties, big-endian.
    let header = [
        "ply",
        "format binary_big_endian 1.0",
        "comment made by hand",
        "element camera 2",
        "property float fx",
        "property ushort id",
        "element vertex 1",
        "property double rot_3",
        "property uchar red",
        "property float opacity",
        "property double z",
        "property float y",
        "property float x",
        "property uchar f_dc_2",
        "property float f_dc_1",
        "property float f_dc_0",
        "property float scale_2",
        "property float scale_1",
        "property float scale_0",
        "property float rot_2",
        "property float rot_1",
        "property float rot_0",
        "element face 1",
        "property list uchar int vertex_indices",
        "end_header",
    ];
    let mut body = vec![0u8; 2 * 6]; // the camera element
    body.extend(0.25f64.to_be_bytes()); // rot_3
    body.push(200); // red (ignored)
    body.extend(2.5f32.to_be_bytes()); // opacity
    body.extend((-3.0f64).to_be_bytes()); // z
    body.extend(2.0f32.to_be_bytes()); // y
    body.extend(1.0f32.to_be_bytes()); // x
    body.push(7); // f_dc_2
    for v in [0.5f32, 0.25, -1.0, -2.0, -3.0, 0.0, 0.0, 1.0] {
        body.extend(v.to_be_bytes()); // f_dc_1, f_dc_0, scale_2..0, rot_2..0
    }
    body.extend([3, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 2]); // the face element (not read)
    let g = read_ply(&ply_file(&header, &body)).unwrap();
    assert_eq!(g.positions, vec![[1.0, 2.0, -3.0]]);
    assert_eq!(g.f_dc, vec![[0.25, 0.5, 7.0]]);
    assert_eq!(g.opacity_logit, vec![2.5]);
    assert_eq!(g.log_scales, vec![[-3.0, -2.0, -1.0]]);
    assert_eq!(g.rotations, vec![[1.0, 0.0, 0.0, 0.25]]);
    assert_eq!((g.sh_degree, g.f_rest.len()), (0, 0));
}

fn header_with(count: &str, drop: &str, extra: &str) -> String {
    let mut h = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n");
    for p in [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
        "rot_0", "rot_1", "rot_2", "rot_3",
    ] {
        if p != drop {
            h.push_str(&format!("property float {p}\n"));
        }
    }
    h.push_str(extra);
    h.push_str("end_header\n");
    h
}

#[test]
fn malformed_ply_files_give_typed_errors() {
    // Room for 2 vertices of up to 24 properties.
    let body = vec![0u8; 2 * 24 * 4];
    let file = |h: String| {
        let mut b = h.into_bytes();
        b.extend_from_slice(&body);
        b
    };
    let class = |bytes: &[u8]| read_ply(bytes).unwrap_err().class();
    assert!(read_ply(&file(header_with("2", "", ""))).is_ok());
    assert_eq!(class(b""), "PlyHeaderInvalid");
    assert_eq!(class(b"plx\nend_header\n"), "PlyHeaderInvalid");
    assert_eq!(
        class(&file(
            header_with("2", "", "").replace("ply\n", "ply\nfoo bar\n")
        )),
        "PlyHeaderInvalid"
    );
    let ascii = header_with("2", "", "").replace("binary_little_endian", "ascii");
    assert_eq!(class(&file(ascii)), "PlyHeaderInvalid");
    let no_end = header_with("2", "", "").replace("end_header", "end_headr");
    assert_eq!(class(&file(no_end)), "PlyHeaderInvalid");
    let bad_type = header_with("2", "", "property quad w\n");
    assert_eq!(class(&file(bad_type)), "PlyHeaderInvalid");
    let twice = header_with("2", "", "property float x\n");
    assert_eq!(class(&file(twice)), "PlyHeaderInvalid");
    let list = header_with("2", "", "property list uchar int idx\n");
    assert_eq!(class(&file(list)), "PlyHeaderInvalid");
    let negative = header_with("-2", "", "");
    assert_eq!(class(&file(negative)), "PlyHeaderInvalid");
    assert!(matches!(
        read_ply(&file(header_with("2", "rot_3", ""))).unwrap_err(),
        Error::PlyPropertyMissing { property: "rot_3" }
    ));
    let five_rest: String = (0..5)
        .map(|i| format!("property float f_rest_{i}\n"))
        .collect();
    assert!(matches!(
        read_ply(&file(header_with("2", "", &five_rest))).unwrap_err(),
        Error::PlyShCoefficients { count: 5 }
    ));
    let gap: String = (1..10)
        .map(|i| format!("property float f_rest_{i}\n"))
        .collect();
    assert_eq!(
        class(&file(header_with("2", "", &gap))),
        "PlyShCoefficients"
    );
    // Counts beyond the file: checked before anything is allocated.
    for count in ["4", "18446744073709551615", "4611686018427387904"] {
        let e = read_ply(&file(header_with(count, "", ""))).unwrap_err();
        assert!(matches!(e, Error::PlyTruncated { stride: 56, .. }), "{e}");
        assert!(e.to_string().ends_with("[§C.3]"), "{e}");
    }
    // An infinite opacity logit (alpha exactly 0 or 1, as splat-transform writes 8-bit
    // alphas) is accepted; a NaN one is not.
    let opacity_at = header_with("2", "", "").len() + 6 * 4;
    let mut inf = file(header_with("2", "", ""));
    inf[opacity_at..opacity_at + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    assert_eq!(read_ply(&inf).unwrap().opacity_logit[0], f32::INFINITY);
    inf[opacity_at..opacity_at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(read_ply(&inf).unwrap_err().class(), "PlyValueNotFinite");
    let mut nan = file(header_with("2", "", ""));
    let at = nan.len() - body.len() + 2 * 14 * 4 - 4;
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(
        read_ply(&nan).unwrap_err(),
        Error::PlyValueNotFinite { vertex: 1, property } if property == "rot_3"
    ));
}

#[test]
fn every_truncation_and_byte_flip_of_a_ply_file_is_an_error_or_a_value_never_a_panic() {
    let bytes = ply_bytes(&awkward_gaussians(3, 1)).unwrap();
    for len in 0..bytes.len() {
        assert!(read_ply(&bytes[..len]).is_err(), "truncated at {len}");
    }
    let header_len = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    for i in 0..header_len + 8 {
        for flip in [0x01u8, 0x20, 0x80] {
            let mut b = bytes.clone();
            b[i] ^= flip;
            let _ = read_ply(&b);
        }
    }
}

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
        Err(Error::NeuralGaussiansUnsupported { value: 5, .. })
    ));
    let mut short = m.clone();
    short.mlp_cov.b1.pop();
    assert!(matches!(
        neural::neural_gaussians(&short, camera),
        Err(Error::Stream(salvq::Error::TensorShape { .. }))
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
        assert_eq!(e.unwrap_err().class(), "RenderSettingInvalid");
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
    let decoded = salvq::decode(&std::fs::read(&stream_path).unwrap()).unwrap();
    for (input, model) in [(&model_path, &m), (&stream_path, &decoded)] {
        let ply = dir.path().join("out.ply");
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
