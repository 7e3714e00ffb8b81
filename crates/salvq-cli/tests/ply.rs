//! The 3DGS PLY file (spec Annex C.3): written and read back bit for bit, properties found by
//! name in any order and type, malformed files as typed errors, never a panic.

#[path = "../../../tests/common/mod.rs"]
mod common;
use common::shared_data;

use salvq_render::camera::Bounds;
use salvq_render::ply::{ply_bytes, read_ply, recorded_ring_bounds};
use salvq_render::Error;
use salvq_render::Gaussians;

/// `n` Gaussians of SH degree `degree` with awkward binary32 values (negative zero,
/// subnormals, large exponents) so that a round trip has something to lose.
fn awkward_gaussians(n: usize, degree: u8) -> Gaussians {
    let b = salvq_bitstream::explicit::rest_per_channel(degree);
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
