//! Real cameras (Annex C.2): the Inria 3DGS `cameras.json` and COLMAP text models, on
//! hand-written fixtures in tests/data (two cameras: `a.png`, the identity pose 4 units
//! behind the origin with a SIMPLE_PINHOLE, and `b.png`, a rotated PINHOLE with fx ≠ fy).

use std::path::{Path, PathBuf};

use salvq_render::camera::Camera;
use salvq_render::camera_file::{
    parse_colmap, parse_inria_json, read_colmap_dir, read_inria_json, NamedCamera,
};
use salvq_render::Error;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn colmap_fixture() -> Vec<NamedCamera> {
    read_colmap_dir(&data("colmap")).unwrap()
}

/// Pixel coordinates of a world point, in [`Camera`]'s convention: pixel (i, j) samples the
/// point (i, j), the principal point is ((W − 1)/2, (H − 1)/2).
fn project(c: &Camera, p: [f32; 3]) -> [f32; 2] {
    let t = c.to_camera(p);
    [
        c.fx * t[0] / t[2] + (c.width as f32 - 1.0) / 2.0,
        c.fy * t[1] / t[2] + (c.height as f32 - 1.0) / 2.0,
    ]
}

#[test]
fn a_colmap_camera_projects_a_point_where_colmap_does() {
    let cameras = colmap_fixture();
    // Sorted by name, as 3DGS sorts them: images.txt lists b.png first.
    let names: Vec<&str> = cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["a.png", "b.png"]);
    let [a, b] = [&cameras[0].camera, &cameras[1].camera];
    assert_eq!((a.width, a.height, a.fx, a.fy), (320, 240, 300.0, 300.0));
    assert_eq!((b.width, b.height, b.fx, b.fy), (640, 480, 500.0, 510.0));
    // a: identity rotation, t = (0, 0, 4): the centre is (0, 0, −4).
    assert_eq!(a.position, [0.0, 0.0, -4.0]);
    // COLMAP: x = (1, 0.5, 0) → (1, 0.5, 4) → u = 300·0.25 + 160 = 235, v = 157.5, with
    // pixel centres at +0.5; here pixel centres are integers: (234.5, 157).
    assert_eq!(project(a, [1.0, 0.5, 0.0]), [234.5, 157.0]);
    // b: R(q) (0.3, −0.2, 1) + t = (0.28, −1.6, 3.96) (numpy), so COLMAP's pixel is
    // (500·0.28/3.96 + 320, 510·(−1.6)/3.96 + 240) = (355.35354, 33.93939).
    let t = b.to_camera([0.3, -0.2, 1.0]);
    for (got, want) in t.iter().zip([0.28, -1.6, 3.96]) {
        assert!((got - want).abs() < 1e-5, "{t:?}");
    }
    let [u, v] = project(b, [0.3, -0.2, 1.0]);
    assert!((u - (355.35354 - 0.5)).abs() < 1e-3, "{u}");
    assert!((v - (33.93939 - 0.5)).abs() < 1e-3, "{v}");
    // The camera centre is at depth 0, the point straight ahead at the principal point.
    assert!(b.to_camera(b.position).iter().all(|v| v.abs() < 1e-6));
}

#[test]
fn inria_json_and_colmap_describe_the_same_cameras() {
    let inria = read_inria_json(&data("cameras.json")).unwrap();
    let colmap = colmap_fixture();
    assert_eq!(inria.len(), 2);
    assert_eq!(inria[1].name, "b");
    for (j, c) in inria.iter().zip(&colmap) {
        let (j, c) = (&j.camera, &c.camera);
        assert_eq!(
            (j.width, j.height, j.fx, j.fy),
            (c.width, c.height, c.fx, c.fy)
        );
        for a in 0..3 {
            assert!((j.position[a] - c.position[a]).abs() < 1e-6, "{j:?} {c:?}");
            for k in 0..3 {
                assert!((j.rotation[a][k] - c.rotation[a][k]).abs() < 1e-6);
            }
        }
    }
    // The JSON rotation is camera-to-world: its first row is the world x axis in camera
    // space, which is the first column of the world-to-camera rotation.
    assert!((inria[1].camera.rotation[1][0] - 0.315_789_47).abs() < 1e-6);
}

fn error_of(r: salvq_render::Result<Vec<NamedCamera>>) -> (u64, &'static str, String) {
    match r.unwrap_err() {
        e @ Error::CameraFileInvalid { .. } => {
            let text = e.to_string();
            let Error::CameraFileInvalid { line, field, .. } = e else {
                unreachable!()
            };
            (line, field, text)
        }
        e => panic!("{e}"),
    }
}

fn colmap(cameras: &str, images: &str) -> salvq_render::Result<Vec<NamedCamera>> {
    parse_colmap(
        cameras,
        Path::new("cameras.txt"),
        images,
        Path::new("images.txt"),
    )
}

const IMAGE: &str = "1 1 0 0 0 0 0 4 1 a.png\n\n";

#[test]
fn distorted_and_malformed_colmap_cameras_are_rejected_naming_the_line() {
    let header = "# comment\n\n";
    let cases = [
        ("1 SIMPLE_RADIAL 64 48 50 32 24 0.1", "PARAMS", "distortion"),
        (
            "1 OPENCV 64 48 50 50 32 24 0 0 0.01 0",
            "PARAMS",
            "distortion",
        ),
        (
            "1 OPENCV_FISHEYE 64 48 50 50 32 24 0 0 0 0",
            "MODEL",
            "pinhole",
        ),
        ("1 PANORAMA 64 48 50", "MODEL", "unknown"),
        ("1 PINHOLE 64 48 50 50 32", "PARAMS", "4 parameters"),
        ("1 PINHOLE 64 0 50 50 32 24", "HEIGHT", "1 …"),
        ("1 PINHOLE 64 48 -50 50 32 24", "PARAMS (fx)", "positive"),
        ("x PINHOLE 64 48 50 50 32 24", "CAMERA_ID", "not a number"),
    ];
    for (line, field, words) in cases {
        let (at, f, text) = error_of(colmap(&format!("{header}{line}\n"), IMAGE));
        assert_eq!((at, f), (3, field), "{text}");
        assert!(
            text.contains(words) && text.contains("cameras.txt, line 3"),
            "{text}"
        );
    }
    // Zero distortion is a pinhole.
    let c = colmap("1 SIMPLE_RADIAL 64 48 50 32 24 0\n", IMAGE).unwrap();
    assert_eq!((c[0].camera.fx, c[0].camera.fy), (50.0, 50.0));
    let pinhole = "1 PINHOLE 64 48 50 50 32 24\n";
    for (images, line, field) in [
        ("# c\n1 1 0 0 0 0 0 4 2 a.png\n\n", 2, "CAMERA_ID"),
        ("1 0 0 0 0 0 0 4 1 a.png\n\n", 1, "QW QX QY QZ TX TY TZ"),
        ("1 1 0 0 0 0 0 4 1 a.png\n\n2 1 0 0\n", 3, "QZ"),
        ("1 1 0 0 0 0 0 4 1\n", 1, "NAME"),
        ("# only comments\n", 0, "images"),
    ] {
        let (at, f, text) = error_of(colmap(pinhole, images));
        assert_eq!((at, f), (line, field), "{text}");
        assert!(text.contains("images.txt"), "{text}");
    }
    // The points line after an image is skipped even when it looks like an image line.
    let c = colmap(
        pinhole,
        "1 1 0 0 0 0 0 4 1 a.png\n2 0 0 0 0 0 0 4 9 b.png\n",
    )
    .unwrap();
    assert_eq!(c.len(), 1);
}

#[test]
fn malformed_cameras_json_is_rejected_naming_the_line_and_field() {
    let good = std::fs::read_to_string(data("cameras.json")).unwrap();
    let json = |text: &str| parse_inria_json(text, Path::new("cameras.json"));
    assert_eq!(
        json(&good).unwrap(),
        read_inria_json(&data("cameras.json")).unwrap()
    );
    // Each edit breaks one field of camera 1; the error names the line of the field's value.
    let camera_1 = good.find("\"id\": 1").unwrap();
    let line_at = |at: usize| 1 + good[..at].matches('\n').count() as u64;
    let line_of = |needle: &str| line_at(camera_1 + good[camera_1..].find(needle).unwrap());
    let cases = [
        ("\"fx\": 500.0", "\"fx\": -500.0", "fx", "\"fx\""),
        ("\"width\": 640", "\"width\": 64.5", "width", "\"width\""),
        ("\"fy\": 510.0", "\"fy\": \"510\"", "fy", "\"fy\""),
        ("0.7263157894736842", "0.9", "rotation", "\"rotation\""),
        ("-1.8157894736842104", "1e999", "position", "\"position\""),
    ];
    for (from, to, field, key) in cases {
        let (at, f, text) = error_of(json(&good.replacen(from, to, 1)));
        assert_eq!((at, f), (line_of(key), field), "{text}");
        assert!(text.contains("camera 1:"), "{text}");
    }
    // A reflection is not a rotation.
    let mirrored = good.replacen("[\n    -0.5263157894736842", "[\n    0.5263157894736842", 1);
    let mirrored = mirrored.replacen("-0.3157894736842105,", "0.3157894736842105,", 1);
    let mirrored = mirrored.replacen("0.7894736842105264", "-0.7894736842105264", 1);
    assert_eq!(error_of(json(&mirrored)).1, "rotation");
    let (at, f, _) = error_of(json(&good.replacen("\"fy\": 510.0", "\"fz\": 510.0", 1)));
    assert_eq!((at, f), (line_of("\"id\": 1") - 1, "fy"));
    // JSON syntax: serde's line.
    let (at, _, text) = error_of(json(&good.replacen("\"id\": 1,", "\"id\": 1", 1)));
    assert_eq!(at, line_of("\"id\": 1") + 1, "{text}");
    assert_eq!(error_of(json("[]")).0, 0);
    assert_eq!(error_of(json("{}")).1, "JSON");
    // 3DGS writes the list on one line: the camera's index tells them apart.
    let one_line: String = good.split_whitespace().collect();
    let text = error_of(json(&one_line.replacen("\"fx\":500.0", "\"fx\":0", 1))).2;
    assert!(text.contains("line 1, field fx: camera 1: 0:"), "{text}");
}

#[test]
fn a_resized_camera_keeps_its_field_of_view() {
    let b = &colmap_fixture()[1].camera;
    let half = b.resized(320, 240).unwrap();
    assert_eq!((half.fx, half.fy), (250.0, 255.0));
    assert_eq!(half.tan_half_fov(), b.tan_half_fov());
    assert_eq!(half.rotation, b.rotation);
    assert!(b.resized(0, 10).is_err());
}
